"""Response models of the report routes (api/routes/reports.py, docs/report.md)."""

from __future__ import annotations

from pydantic import BaseModel, Field


class ReportInfo(BaseModel):
    """A commissioning report in the store (its metadata; the document is at ``url``)."""

    id: str = Field(description="printed in the report's footer and title")
    drive_key: str = Field(description="vendor-product-serial (1018h), else profile@bus")
    plant_tag: str | None = Field(description="the drive's plant tag when the report was made")
    session: str = Field(description="the session the drive was read through")
    time: str = Field(description="when it was made (ISO 8601, UTC)")
    by: str = Field(description="the user who made it")
    sha256: str = Field(
        description="SHA-256 of the report's data as canonical JSON (printed in the report)"
    )
    html_sha256: str = Field(description="SHA-256 of the HTML document as the store keeps it")
    pdf_sha256: str | None = Field(description="SHA-256 of its PDF (None: not printed yet)")
    url: str = Field(description="the HTML document (GET)")
    pdf_url: str = Field(description="the PDF (GET; printed on the first request)")
