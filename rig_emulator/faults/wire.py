"""The fault command block of the simulation control unit (unit 100), as numbers.

Holding registers (documented in ``register_maps/wieselburg_bench.yaml`` and the README):

    address  point             type     meaning
    10       fault_kind        uint16   KIND_CODES: 1 delay ... 9 offset
    11       fault_target      uint16   unit ID (communication; 0 = every instrument unit)
                                        or the signal's index in SIGNAL_CODES (instrument)
    12-13    fault_parameter   float32  delay_ms, exception code, rate_per_h or value
    14-15    fault_duration_s  float32  for_s; 0 = until cleared (a spike: one second)
    16-19    fault_at_s        float64  at_s in simulated seconds; 0 = now
    20       fault_command     uint16   write 1: set the fault the block describes;
                                        2: clear every fault

Input register 19 (``active_fault_count``) counts the active faults. Write the block in
one FC16 request (kind to command, 11 registers) or the fields first and the command last.
A block that does not describe a valid fault gets exception 03 and changes nothing; so does
a set whose fields were not all written since the last set (the command alone would arm the
last fault again).

The truth unit (101, read-only): input registers 0 onwards hold the plant's true value of
every measured signal as float64, in :data:`SIGNAL_CODES` order (4 registers each, signal
``true_NAME``), whatever the faults do to the readings.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rig_emulator.faults.spec import (
    COMM_KINDS,
    KINDS,
    PARAMETER,
    FaultError,
    FaultSpec,
    check_parameter,
    fault_from_mapping,
)
from rig_emulator.signals import MEASURED

KIND_CODES: dict[str, int] = {kind: i + 1 for i, kind in enumerate(KINDS)}
SIGNAL_CODES: dict[str, int] = {name: i for i, name in enumerate(MEASURED)}
BLOCK_SIGNALS = (
    "fault_kind",
    "fault_target",
    "fault_parameter",
    "fault_duration_s",
    "fault_at_s",
    "fault_command",
)
COMMAND_SET = 1
COMMAND_CLEAR = 2


def block_values(spec: FaultSpec) -> dict[str, float]:
    """The block's signal values that describe ``spec`` (command: set)."""
    return {
        "fault_kind": float(KIND_CODES[spec.kind]),
        "fault_target": float(spec.unit if spec.is_comm else SIGNAL_CODES[str(spec.signal)]),
        "fault_parameter": float(spec.parameter or 0.0),
        "fault_duration_s": float(spec.for_s or 0.0),
        "fault_at_s": float(spec.at_s or 0.0),
        "fault_command": float(COMMAND_SET),
    }


def spec_from_block(block: Mapping[str, float]) -> FaultSpec:
    """The fault a block describes (:class:`FaultError` if it describes none)."""
    code = int(block["fault_kind"])
    kinds = {v: k for k, v in KIND_CODES.items()}
    if code not in kinds:
        raise FaultError(f"fault_kind: {code} is not a kind code (1..{len(kinds)})")
    kind = kinds[code]
    data: dict[str, Any] = {"kind": kind}
    target = int(block["fault_target"])
    if kind in COMM_KINDS:
        data["unit"] = target
    else:
        if not 0 <= target < len(MEASURED):
            raise FaultError(
                f"fault_target: {target} is not a signal index (0..{len(MEASURED) - 1})"
            )
        data["signal"] = MEASURED[target]
    name = PARAMETER[kind]
    if name is not None:
        value = block["fault_parameter"]
        if name == "code":
            value = int(value) if float(value).is_integer() else value
        check_parameter(f"fault_parameter ({name})", kind, value)
        data[name] = value
    if block["fault_duration_s"] > 0:
        data["for_s"] = float(block["fault_duration_s"])
    if block["fault_at_s"] > 0:
        data["at_s"] = float(block["fault_at_s"])
    spec = fault_from_mapping(data, "fault block")
    assert isinstance(spec, FaultSpec)
    return spec


def fault_dict_to_spec(fault: Mapping[str, Any]) -> FaultSpec:
    """A fault given as a dict (``{"kind": "no_reply", "unit": 2, "for_s": 30}``)."""
    spec = fault_from_mapping(dict(fault), "fault")
    if not isinstance(spec, FaultSpec):
        raise FaultError(
            "fault.kind: random faults come from a fault file or a profile (serve --faults,"
            " the marker's faults=), not one at a time"
        )
    return spec
