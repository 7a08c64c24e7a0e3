"""Health and profile routes."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, Query, Request, Response

from servodesk import __version__
from servodesk.api.deps import StateDep
from servodesk.api.downloads import content_disposition
from servodesk.api.schemas import ERROR_RESPONSES, HealthOut
from servodesk.api.schemas_profiles import (
    ErrorInfo,
    GroupInfo,
    ImportedProfile,
    NetworkInfo,
    NetworkLedInfo,
    NetworkObjectInfo,
    NetworkRuleInfo,
    ObjectInfo,
    ProfileDetail,
    ProfileSummary,
    QuirkInfo,
)
from servodesk.api.uploads import openapi_file_body, read_file
from servodesk.domain.profile import DeviceProfile, NetworkSpec, ObjectSpec
from servodesk.domain.profile_loader import check_profile, save_profile
from servodesk.errors import ConflictError, ValidationError
from servodesk.services.session import error_info

router = APIRouter(tags=["system"], responses=ERROR_RESPONSES)


@router.get("/health", operation_id="health")
async def health(state: StateDep) -> HealthOut:
    return HealthOut(
        status="ok",
        version=__version__,
        simulation=state.sim is not None,
        links=state.manager.links.available(),
    )


def summary(p: DeviceProfile) -> ProfileSummary:
    return ProfileSummary(
        id=p.id,
        name=p.name,
        vendor=p.vendor,
        fieldbus=p.fieldbus,
        description=p.description,
        objects=len(p.objects),
        variables=len(p.variables),
        errors=len(p.errors),
        modes=list(p.modes),
        homing_methods=list(p.homing_methods),
    )


def object_info(s: ObjectSpec) -> ObjectInfo:
    default = s.default
    return ObjectInfo(
        index=s.index,
        subindex=s.subindex,
        address=str(s.address),
        name=s.name,
        name_local=s.name_local,
        data_type=s.data_type.name,
        access=s.access.value,
        pdo_mapping=s.pdo_mapping.value,
        default=default,
        min=s.min,
        max=s.max,
        unit=s.unit,
        scale=s.scale,
        raw_unit=s.raw_unit,
        group=s.group,
        persist=s.persist,
        process=s.process,
        description=s.description,
        section=s.section,
        values={str(k): v for k, v in s.values.items()} if s.values else None,
        pnu=s.pnu,
        symbol=s.symbol,
    )


@router.get("/profiles", operation_id="list_profiles")
async def list_profiles(state: StateDep) -> list[ProfileSummary]:
    return [summary(p) for p in state.catalog.all()]


_EXPORTS = {
    "eds": ("text/plain; charset=utf-8", "eds"),
    "dcf": ("text/plain; charset=utf-8", "dcf"),
    "esi": ("application/xml", "xml"),
}


@router.get(
    "/profiles/{profile_id}/export",
    operation_id="export_profile",
    response_class=Response,
    responses={200: {"content": {"text/plain": {}, "application/xml": {}}}},
)
async def export_profile(
    profile_id: str,
    state: StateDep,
    format: Literal["eds", "dcf", "esi"] = Query("eds", description="eds, dcf or esi"),
    node_id: int = Query(1, ge=1, le=127, description="node id written into a DCF"),
) -> Response:
    from servodesk import devdesc

    p = state.catalog.get(profile_id)
    if format == "eds":
        text = devdesc.export_eds(p)
    elif format == "dcf":
        text = devdesc.export_dcf(p, node_id, {})
    else:
        text = devdesc.export_esi(p)
    media, suffix = _EXPORTS[format]
    return Response(
        text,
        media_type=media,
        headers={"content-disposition": content_disposition(f"{p.id}.{suffix}")},
    )


@router.post(
    "/profiles/import",
    status_code=201,
    operation_id="import_profile",
    openapi_extra=openapi_file_body(),
)
async def import_profile(
    request: Request,
    state: StateDep,
    filename: str = Query(min_length=5, max_length=255, description="e.g. drive.eds"),
    profile_id: str | None = Query(
        None, pattern=r"^[a-z0-9][a-z0-9-]*$", max_length=64, description="default: from the name"
    ),
    device: int | None = Query(
        None, ge=1, le=10000, description="ESI with several devices: which one (default 1)"
    ),
) -> ImportedProfile:
    """Import an EDS, DCF, ESI, XDD or XPD file (multipart/form-data field ``file``) as a new
    profile; ``warnings`` lists what the file holds that the profile does not."""
    from servodesk import devdesc

    body = await read_file(request)  # At most 16 MiB (api/uploads.py).
    text = body.decode("utf-8", errors="replace").lstrip("\ufeff")
    result = devdesc.read_text(text, filename, profile_id, device=device)
    p = result.profile
    if p.id in state.catalog.ids():
        raise ConflictError(f"a profile {p.id!r} exists already", hint="choose another profile_id")
    problems = check_profile(p)
    if problems:
        raise ValidationError(
            f"the imported profile is inconsistent: {problems[0]}"
            + (f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""),
            hint="fix the file and import it again",
        )
    save_profile(p, state.settings.user_profile_dir)
    state.catalog.refresh()
    state.audit.record("config.profile_imported", details={"profile": p.id, "filename": filename})
    return ImportedProfile(
        **summary(state.catalog.get(p.id)).model_dump(), warnings=list(result.warnings)
    )


@router.get("/profiles/{profile_id}", operation_id="get_profile")
async def get_profile(profile_id: str, state: StateDep) -> ProfileDetail:
    return profile_detail(state.catalog.get(profile_id))


def network_info(n: NetworkSpec) -> NetworkInfo:
    """The profile's ``network:`` section, its objects named as ``object_list`` names them."""
    return NetworkInfo(
        summary=n.summary,
        section=n.section,
        objects=[
            NetworkObjectInfo(address=str(o.address), note=o.note, section=o.section)
            for o in n.objects
        ],
        addressing=[NetworkRuleInfo(**r.model_dump()) for r in n.addressing],
        leds=[NetworkLedInfo(**led.model_dump()) for led in n.leds],
    )


def profile_detail(p: DeviceProfile) -> ProfileDetail:
    """A profile with all its objects, errors, quirks and network section (GET /profiles/{id})."""
    return ProfileDetail(
        **summary(p).model_dump(),
        groups=[GroupInfo(**g.model_dump()) for g in p.groups],
        object_list=[object_info(s) for s in p.variables.values()],
        error_list=[ErrorInfo(**error_info(e)) for e in p.errors],
        quirks=[QuirkInfo(**q.model_dump()) for q in p.quirks],
        network=network_info(p.network) if p.network is not None else None,
    )
