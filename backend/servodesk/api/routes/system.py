"""Health and profile routes."""

from __future__ import annotations

from fastapi import APIRouter

from servodesk import __version__
from servodesk.api.deps import StateDep
from servodesk.api.schemas import (
    ERROR_RESPONSES,
    ErrorInfo,
    GroupInfo,
    HealthOut,
    ObjectInfo,
    ProfileDetail,
    ProfileSummary,
    QuirkInfo,
)
from servodesk.domain.profile import DeviceProfile, ObjectSpec
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


@router.get("/profiles/{profile_id}", operation_id="get_profile")
async def get_profile(profile_id: str, state: StateDep) -> ProfileDetail:
    p = state.catalog.get(profile_id)
    return ProfileDetail(
        **summary(p).model_dump(),
        groups=[GroupInfo(**g.model_dump()) for g in p.groups],
        object_list=[object_info(s) for s in p.variables.values()],
        error_list=[ErrorInfo(**error_info(e)) for e in p.errors],
        quirks=[QuirkInfo(**q.model_dump()) for q in p.quirks],
    )
