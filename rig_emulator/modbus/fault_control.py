"""Fault injection in the Modbus server: the gate, the command block and the truth block.

:class:`ServerFaults` joins a :class:`~rig_emulator.faults.FaultEngine` to a
:class:`~rig_emulator.modbus.server.BenchServer`:

- its :meth:`gate` goes on the Modbus server's gates (after the TLS authorisation gate), so
  communication faults act on every transport (TCP, TLS, RTU) before a request touches a
  datastore; ``disconnect`` calls the server's ``close_all_connections``;
- the engine is the emulator's reading hook, so instrument faults change the readings only;
- :meth:`values` adds the command block and the active fault count to the published
  values (the emulator adds the truth, ``true_NAME``); a dropout is a NaN, which a float
  register serves as NaN and an integer register as its type's invalid code (the codec);
- :meth:`write` handles a client's write of the command block
  (:mod:`rig_emulator.faults.wire`).
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from pymodbus.constants import ExcCodes

from rig_emulator.emulator import Emulator
from rig_emulator.faults import (
    Entry,
    FaultEngine,
    FaultError,
    FaultJournal,
    ReadingRange,
    check_spikes,
    check_units,
)
from rig_emulator.faults.wire import (
    BLOCK_SIGNALS,
    COMMAND_CLEAR,
    COMMAND_SET,
    fault_dict_to_spec,
    spec_from_block,
)
from rig_emulator.registers import RegisterMap, emulator_units, instrument_units, reading_range
from rig_emulator.signals import MEASURED

#: Command signals of the fault block (written by clients, never plant commands).
FAULT_COMMANDS = BLOCK_SIGNALS

try:  # the shared gate interface of rig_emulator/modbus/handler.py
    from rig_emulator.modbus.handler import GateDecision
except ImportError:  # pragma: no cover - a handler without gates: no communication faults
    GateDecision = None  # type: ignore[assignment,misc]


def reading_ranges(register_map: RegisterMap) -> dict[str, ReadingRange]:
    """Per measured signal published as an integer: the lowest and highest reading every
    register of it serves, its invalid code left out, the narrowest register and its step
    (a reading's resolution)."""
    out: dict[str, ReadingRange] = {}
    for device in register_map.devices:
        for point in device.points:
            if point.signal not in MEASURED:
                continue
            lo, hi = reading_range(point)
            if not math.isfinite(lo):
                continue
            where = f"unit {device.unit_id} {point.name}, {point.datatype} x {point.scale:g}"
            here = ReadingRange(lo, hi, where, abs(point.scale))
            known = out.get(point.signal)
            if known is not None:  # what every register serves: the intersection, named
                # by the narrower (a narrower second register was kept alone: a uint16's
                # 0 at its low end let a spike of -100 through, a re-probe)
                named = known if known.hi - known.lo <= hi - lo else here
                here = ReadingRange(
                    max(lo, known.lo), min(hi, known.hi), named.register, named.step
                )
            out[point.signal] = here
    return out


class ServerFaults:
    """The faults of one server (see the module docstring)."""

    def __init__(
        self,
        emulator: Emulator,
        register_map: RegisterMap,
        entries: Iterable[Entry] = (),
        journal_path: str | Path | None = None,
        epoch_id: int | None = None,
    ) -> None:
        """``epoch_id``: the server's (:attr:`BenchServer.epoch_id`), on every journal line
        (a report tells a restarted server's plant from the first one's by it)."""
        self.emulator = emulator
        # begun by the server once it serves (begin_journal): a failed start keeps the old
        journal = (
            FaultJournal(journal_path, begin=False, epoch_id=epoch_id)
            if journal_path is not None
            else None
        )
        self.engine = FaultEngine([], journal, plant=emulator.plant)
        #: the map's own units (simulation control, truth): never faulted
        self.own_units = emulator_units(register_map)
        self.engine.never_faulted = self.own_units
        instruments = instrument_units(register_map)
        self.engine.instrument_units = tuple(sorted(instruments))
        # (the truth unit publishes every signal: the instruments' readings only)
        published = {p.signal for d in register_map.devices if d.unit_id in instruments
                     for p in d.points}  # fmt: skip
        self.engine.signals = tuple(s for s in MEASURED if s in published)
        profile_faults = getattr(emulator.profile, "faults", ()) or ()
        self.engine.add_initial(profile_faults, "profile")
        self.engine.add_initial(entries, "file")
        emulator.reading_hook = self.engine.apply
        self.block: dict[str, float] = dict.fromkeys(BLOCK_SIGNALS, 0.0)
        #: the block's fields written since the last set: a set takes only a block whose
        #: every field was written for it (:meth:`write`)
        self._fields_written: set[str] = set()
        self._ranges = reading_ranges(register_map)
        self.engine.reading_ranges = self._ranges
        self.engine.reading_floors = emulator.profile.reading_floors
        #: the units a communication fault may name (the bench's; 0: all of them)
        self.units = frozenset(d.unit_id for d in register_map.devices)

    # ------------------------------------------------------------------ wiring
    def attach(self, modbus_server: Any) -> bool:
        """Put the gate on ``modbus_server.gates`` and let ``disconnect`` close its
        connections; False if that server has no gates (communication faults then act not)."""
        gates = getattr(modbus_server, "gates", None)
        close = getattr(modbus_server, "close_all_connections", None)
        if close is not None:

            def disconnect(reason: str) -> int:
                """Close every connection once the request being answered is answered
                (a disconnect starts while a lockstep advance is published: its reply
                still goes out); returns how many connections are open now."""
                open_now = len(getattr(modbus_server, "handlers", ()))
                try:
                    asyncio.get_running_loop().call_soon(close, reason)
                except RuntimeError:  # no loop running: close at once
                    return close(reason)
                return open_now

            self.engine.on_disconnect = disconnect
        if gates is None or GateDecision is None:
            return False
        gates.append(self.gate)
        return True

    def gate(self, info: Any) -> Any:
        """The fault-injection gate: a decision for a request to a faulty unit, else None; a
        unit the bench does not have is never faulty (it gets 0B, as without faults, even
        under a fault on every unit, 0)."""
        if info.unit_id not in self.units:
            return None
        decision = self.engine.decide(info.unit_id)
        if decision is None:
            return None
        return GateDecision(  # type: ignore[misc]
            delay_s=decision.delay_s, drop=decision.drop, exception_code=decision.exception_code
        )

    def begin_journal(self) -> None:
        """The server serves on every port asked for: the journal file begins (replacing
        an earlier one there)."""
        if self.engine.journal is not None:
            self.engine.journal.begin()

    def close(self) -> None:
        if self.engine.journal is not None:
            self.engine.journal.close()

    @property
    def journal_lines_lost(self) -> int:
        """Journal lines that could not be written (a full disk): ``serve`` exits 1."""
        journal = self.engine.journal
        return journal.lines_lost if journal is not None else 0

    # ------------------------------------------------------------------ values
    def values(self, out: dict[str, float]) -> None:
        """Add the block and the count to ``out``."""
        out.update(self.block)
        out["active_fault_count"] = float(len(self.engine.active))

    def truth(self, signal: str) -> float:
        """The plant's true value of a measured signal."""
        plant = self.emulator.plant()
        if signal not in plant:
            raise ValueError(f"'{signal}' is not a measured signal ({', '.join(MEASURED)})")
        return float(plant[signal])

    # ------------------------------------------------------------------ commands
    def parse(self, fault: Mapping[str, Any] | Entry) -> Entry:
        """A fault given as a dict (as in ``FAULTS.yaml``) or a parsed entry, checked
        against this bench's units; :class:`FaultError` names what is wrong."""
        entry = fault if not isinstance(fault, Mapping) else fault_dict_to_spec(fault)
        check_units([entry], self.units, "fault", self.own_units)
        check_spikes([entry], self._ranges, "fault")
        return entry

    def inject(self, fault: Mapping[str, Any] | Entry, source: str = "python") -> None:
        """Set a fault given as a dict (as in ``FAULTS.yaml``) or a parsed entry."""
        self.engine.add(self.parse(fault), source)

    def write(self, new: Mapping[str, float]) -> ExcCodes | None:
        """A client's write to the command block: applied whole, or refused with 03 and
        nothing changed. A set takes a block every field of which was written since the
        last set, in this write or before it (the whole block in one FC16, or the fields
        first and the command last, as a map with the command apart from its fields needs):
        a set alone armed whatever the last set had left there, a second offset on top of
        the first (a stranger's probe)."""
        block = {**self.block, **new}
        command = int(block["fault_command"])
        fields = set(BLOCK_SIGNALS) - {"fault_command"}
        written = self._fields_written | (set(new) & fields)
        if command == COMMAND_SET and not fields <= written:
            return ExcCodes.ILLEGAL_VALUE
        try:
            spec = spec_from_block(block) if command == COMMAND_SET else None
            if spec is not None:
                check_units([spec], self.units, "fault", self.own_units)
                check_spikes([spec], self._ranges, "fault")
        except FaultError:
            return ExcCodes.ILLEGAL_VALUE
        if command not in (0, COMMAND_SET, COMMAND_CLEAR):
            return ExcCodes.ILLEGAL_VALUE
        block["fault_command"] = 0.0
        self.block = block
        self._fields_written = written
        if spec is not None:
            self.engine.add(spec, "modbus")
            self._fields_written = set()  # the next set needs a block written for it
        elif command == COMMAND_CLEAR:
            self.engine.clear()
        return None
