"""The quirk vocabulary: every quirk id a profile may name, the shape of its value, and the
modules that act on it (issue 51 item 5).

A quirk is a documented deviation of one family from the standard (``quirks:`` in
``profiles/<id>/profile.yaml``, docs/profiles.md). Shared code reads a quirk by id and acts on
it: ``sm_watchdog_fault`` makes the EtherCAT twin fault when its SyncManager watchdog fires,
``no_fault_reset_bit7`` changes how an alarm is reset. Before this registry an id was a bare
string on both sides, so a typo in a profile (``sm_watchdog_fualt``) or in code switched a
safety-relevant quirk off without a word. Now:

- the profile loader refuses a quirk id that is not here, naming the closest one, and a value
  of the wrong shape (:func:`check_quirks`, called by ``check_profile`` and at load);
- :meth:`DeviceProfile.quirk` refuses an id that is not here (a typo in code fails the first
  test that reaches it), and tests/profiles/test_quirk_registry.py checks every literal id the
  code reads is here and every reader named here still reads it.

``read_by`` empty means the quirk is device knowledge for the engineer (shown on the profile
page with its manual section) that no code acts on yet: 40 of the 106 ids are read by code.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from dataclasses import dataclass
from enum import Flag, auto
from typing import Any


class Shape(Flag):
    """The JSON shapes a quirk's value may take (YAML scalars, lists, mappings)."""

    MAP = auto()
    LIST = auto()
    INT = auto()
    NUM = auto()  # int or float
    BOOL = auto()
    STR = auto()
    NONE = auto()  # "the family has none" (CTMM04x keeps no alarm history)


MAP, LIST, INT, NUM, BOOL, STR, NONE = (
    Shape.MAP,
    Shape.LIST,
    Shape.INT,
    Shape.NUM,
    Shape.BOOL,
    Shape.STR,
    Shape.NONE,
)


@dataclass(frozen=True)
class QuirkSpec:
    shape: Shape
    #: Modules (dotted, below ``servodesk``) that act on the quirk; empty: documentation only.
    read_by: tuple[str, ...]


def _shape_of(value: Any) -> Shape:
    if value is None:
        return NONE
    if isinstance(value, bool):  # before int: a bool is an int in Python
        return BOOL
    if isinstance(value, int):
        return INT | NUM
    if isinstance(value, float):
        return NUM
    if isinstance(value, str):
        return STR
    if isinstance(value, list):
        return LIST
    if isinstance(value, Mapping):
        return MAP
    return Shape(0)


Q = QuirkSpec

#: id -> shape and readers. Keep sorted; a new quirk is added here and in docs/profiles.md.
QUIRKS: Mapping[str, QuirkSpec] = {
    "acyclic_max_bytes": Q(INT, ()),
    "alarm_code_format": Q(STR, ()),
    "alarm_history": Q(MAP | NONE, ("services.alarms", "sim.faults")),
    "auto_set_objects": Q(LIST, ("domain.paramset",)),
    "axes": Q(MAP, ()),
    "axis_object_offset": Q(INT, ()),
    "bootup_emcy": Q(LIST, ()),
    "byte_order": Q(STR, ("services.pdo", "sim.pdo")),
    "clear_alarm_history": Q(MAP, ("services.alarms", "sim.faults", "domain.paramset")),
    "command_objects": Q(LIST, ("domain.paramset",)),
    "controlword_interpolation_bits": Q(MAP, ()),
    "controlword_min_interval_ms": Q(INT, ("services.session", "sim.engine")),
    "controlword_requires_mastership": Q(MAP, ()),
    "csp_align_target_before_enable": Q(BOOL, ()),
    "current_alarm": Q(MAP, ("services.alarms", "sim.faults")),
    "cycle_times_ms": Q(LIST, ()),
    "dc_cycle_time_ns": Q(MAP, ("domain.profile",)),
    "dcp": Q(
        MAP,
        (
            "services.simulation",
            "sim.profinet_device",
            "links.profinet_dcp",
            "domain.profile_loader",
        ),
    ),
    "degree_relative_move_forbidden": Q(BOOL, ()),
    "device_name_not_for_identification": Q(STR, ()),
    "device_reset": Q(MAP, ("domain.paramset",)),
    "device_type": Q(INT, ()),
    "device_type_nonstandard": Q(INT, ()),
    "drive_state_object": Q(STR, ()),
    "ecat_comm_error_recovery": Q(LIST, ()),
    "enable_clears_set_points": Q(BOOL, ()),
    "esm_leave_op_faults_when_enabled": Q(BOOL, ()),
    "fault_reset": Q(STR, ("services.alarms", "sim.engine", "domain.cia402")),
    "fault_reset_hold_ms": Q(INT, ("services.alarms",)),
    "firmware_min_objects": Q(MAP, ()),
    "heartbeat_overrides_guarding": Q(BOOL, ()),
    "homing_cancel_clears_status": Q(BOOL, ("sim.engine",)),
    "homing_method_equivalent": Q(MAP, ("services.homing", "sim.engine")),
    "homing_requires_z_phase": Q(BOOL, ()),
    "homing_without_enable": Q(LIST, ("services.homing", "sim.engine")),
    "idle_forces_switch_on_disabled": Q(BOOL, ()),
    "im0": Q(MAP, ("sim.profinet_device",)),
    "indexer_homing_methods": Q(LIST, ()),
    "ip_address_from_dip_switch": Q(MAP, ()),
    "magic_1ea5": Q(INT, ()),
    "master_heartbeat": Q(MAP, ()),
    "mode_change_at_standstill": Q(BOOL, ("services.motion.start",)),
    "mode_change_refused": Q(MAP, ("services.motion.start",)),
    "mode_display_zero_unless_enabled": Q(BOOL, ()),
    "mode_selection": Q(LIST, ()),
    "mode_switch_requires_zero_speed": Q(MAP, ()),
    "modulo_position": Q(BOOL, ()),
    "nmt_station_wide": Q(BOOL, ()),
    "no_fault_reset_bit7": Q(BOOL, ("services.alarms", "sim.engine")),
    "no_quick_stop": Q(BOOL, ()),
    "no_switch_on_enable_shortcut": Q(BOOL, ()),
    "no_tuning_gains": Q(BOOL, ("services.tuning.capabilities",)),
    "node_id_and_bitrate": Q(MAP, ()),
    "objects_not_usable": Q(LIST, ("services.viewer", "services.motion.limits", "domain.paramset")),
    "one_touch_tuning": Q(MAP, ("services.tuning.capabilities", "sim.engine", "sim.onetouch")),
    "parameter_activation": Q(MAP, ("sim.profinet_device", "domain.paramset")),
    "parameter_error_format": Q(STR, ()),
    "parameters_volatile_until_stored": Q(BOOL, ()),
    "pdo_assign_max_per_sm": Q(INT, ()),
    "pdo_comm_param_no_sub4": Q(BOOL, ()),
    "pdo_mapping_fixed": Q(BOOL, ()),
    "pdo_mapping_requires_state": Q(STR, ()),
    "pdo_min_interval_ms": Q(NUM, ()),
    "pdo_no_duplicate_entries": Q(BOOL, ("sim.engine",)),
    "pdo_param_change_requires_invalid": Q(BOOL, ()),
    "pdo_remap_sequence": Q(LIST, ()),
    "pdo_state_abort": Q(INT, ("sim.engine",)),
    "pdo_unknown_object_abort": Q(INT, ("sim.engine",)),
    "pnu_equals_index": Q(BOOL, ()),
    "pnu_subindex_offset": Q(INT, ()),
    "polarity_values": Q(LIST, ()),
    "pp_set_point_buffer": Q(INT | MAP, ("services.motion.commands",)),
    "pv_starts_on_enable": Q(BOOL, ()),
    "quick_stop_ends_switch_on_disabled": Q(BOOL, ()),
    "quick_stop_statusword": Q(INT, ("sim.engine",)),
    "ramp_rate_registers": Q(MAP, ("services.homing", "sim.engine")),
    "reset_to_factory": Q(MAP, ()),
    "restore_defaults": Q(MAP, ("services.session", "sim.engine", "domain.paramset")),
    "restore_refused_in_operation_enabled": Q(BOOL, ()),
    "restore_requires_reset": Q(BOOL, ()),
    "rotary_switch_ip": Q(MAP, ()),
    "rpdo_dlc_mismatch_emcy": Q(INT, ("sim.pdo",)),
    "rxpdo_overrides_sdo": Q(BOOL, ()),
    "safety_state": Q(MAP, ()),
    "sdo_abort_nonstandard": Q(BOOL, ()),
    "sim_fault_codes": Q(MAP, ("sim.faults",)),
    "slmp_axis_multidrop": Q(BOOL, ()),
    "sm_watchdog_fault": Q(STR, ("sim.ethercat_slave",)),
    "speed_multiplier": Q(MAP, ("services.homing",)),
    "state_skip_allowed": Q(BOOL, ()),
    "statusword_bit15_interpolating": Q(INT, ()),
    "statusword_manufacturer_bits": Q(MAP, ()),
    "store_effective_after_reset": Q(BOOL, ()),
    "store_parameters": Q(MAP, ("services.session", "sim.engine", "domain.paramset")),
    "store_parameters_busy_ms": Q(INT, ()),
    "store_parameters_duration_s": Q(INT, ("services.session",)),
    "store_refused_in_states": Q(LIST, ()),
    "telegram1_speed_scaling": Q(MAP, ()),
    "telegram_state_machine": Q(MAP, ()),
    "telegrams": Q(LIST, ()),
    "touch_probe_exclusive": Q(BOOL, ()),
    "tpdo_event_source": Q(STR, ("sim.pdo",)),
    "tuning_gains": Q(MAP, ("services.tuning.capabilities",)),
    "unit_change_sequence": Q(LIST, ("domain.restore_plan",)),
    "user_units_factor_group": Q(MAP, ("services.tuning.capabilities",)),
    "warning_ack_bit": Q(INT, ()),
}


class UnknownQuirk(KeyError):
    """Code asked for a quirk id the registry does not know (a typo, or a quirk not added)."""


def spec(quirk_id: str) -> QuirkSpec:
    """The registry entry of ``quirk_id``; :class:`UnknownQuirk` naming the closest id."""
    try:
        return QUIRKS[quirk_id]
    except KeyError:
        raise UnknownQuirk(
            f"quirk {quirk_id!r} is not in domain/quirks.py{_closest(quirk_id)}"
        ) from None


def _closest(quirk_id: str) -> str:
    near = difflib.get_close_matches(quirk_id, QUIRKS, n=1)
    return f" (did you mean {near[0]!r}?)" if near else ""


def check_quirks(quirks: list[tuple[str, Any]]) -> list[str]:
    """Problems of a profile's ``(id, value)`` quirks: unknown ids, values of the wrong shape,
    an id given twice (the loader would use the first and ignore the rest)."""
    problems: list[str] = []
    seen: set[str] = set()
    for quirk_id, value in quirks:
        if quirk_id in seen:
            problems.append(f"quirk {quirk_id!r}: given more than once")
        seen.add(quirk_id)
        entry = QUIRKS.get(quirk_id)
        if entry is None:
            problems.append(
                f"quirk {quirk_id!r}: unknown id{_closest(quirk_id)}; the ids servodesk knows "
                "are listed in docs/profiles.md (quirk vocabulary)"
            )
            continue
        if not _shape_of(value) & entry.shape:
            want = " or ".join(str(s.name).lower() for s in Shape if s in entry.shape)
            problems.append(
                f"quirk {quirk_id!r}: value {value!r} has the wrong shape (expected {want})"
            )
    return problems
