"""The in-process rig: steps the emulator directly (no network). A profile's instrument
faults (``faults:``, CONTRACT section 5) act on its readings as a server's would; its
communication faults have no wire to act on (:func:`wire_only_faults` names them)."""

from __future__ import annotations

from hil_client.protocol.rig import READING_KEYS, RigCommand
from rig_emulator.bench import BenchConfig
from rig_emulator.emulator import Emulator
from rig_emulator.faults import COMM_KINDS, Entry, FaultEngine
from rig_emulator.instruments import Profile
from rig_emulator.signals import MEASURED


def wire_only_faults(entries: tuple[Entry, ...]) -> list[str]:
    """The kinds among ``entries`` that act only on a wire (a random source's included)."""
    kinds = [k for e in entries for k in (e.kinds if e.kind == "random" else (e.kind,))]
    return sorted({k for k in kinds if k in COMM_KINDS})


# every reading the runner asks for is a measured signal of the emulator, or boiler_on
assert set(READING_KEYS) <= {*MEASURED, "boiler_on"}


class LocalRig:
    """An :class:`~rig_emulator.emulator.Emulator` behind the rig interface.

    An in-process plant never breaks: its ``epoch`` stays 0 and it has no ``gaps``
    (CONTRACT section 7; declared so the runner's per-row look-ups find them at once).
    """

    epoch = 0
    restart_phase = False

    def __init__(
        self,
        params,
        profile: Profile,
        seed: int = 0,
        config: BenchConfig | None = None,
    ) -> None:
        self.emulator = Emulator(params, profile, seed, config)
        self._stepped = False
        self._last: tuple | None = None
        self.gaps: list = []
        self._emulator_advance = self.emulator.advance
        self._reading_by_name = self.emulator.reading_by_name
        self._reading_values = self.emulator.reading_values_getter(READING_KEYS)
        #: the profile's faults, evaluated at each reading (None: it has none)
        self.faults: FaultEngine | None = None
        if profile.faults:
            self.faults = FaultEngine([])
            self.faults.add_initial(profile.faults, "profile")
            # floored as a server's faults are: no offset reads below what the instrument
            # can show (the profile's reading_min)
            self.faults.reading_floors = profile.reading_floors

    def apply(self, command: RigCommand) -> None:
        key = (
            command.flow_setpoint_kg_h,
            command.return_setpoint_C,
            command.pump_on,
            command.boiler_on,
            command.return_heating,
        )
        if key == self._last:
            return
        self._last = key
        self.emulator.set_commands(
            {
                "water_flow_setpoint_kg_h": command.flow_setpoint_kg_h,
                "return_setpoint_C": command.return_setpoint_C,
                "pump_on": float(command.pump_on),
                "boiler_command": float(command.boiler_on),
                "return_heating": float(command.return_heating),
            }
        )

    def advance(self, dt_s: float) -> float:
        self._emulator_advance(dt_s)
        self._stepped = True
        return dt_s

    def read(self) -> dict[str, float]:
        if not self._stepped:
            raise RuntimeError("read() before the first advance()")
        out = self._reading_by_name()
        if self.faults is not None:
            self.faults.apply(out, self.emulator.sim_time_s)
        out["boiler_on"] = self.emulator.boiler_on
        return out

    def read_values(self) -> tuple[float, ...]:
        """:meth:`read` in READING_KEYS order, without the mapping (the runner's path)."""
        if not self._stepped:
            raise RuntimeError("read() before the first advance()")
        if self.faults is not None:
            out = self.read()
            return tuple(out[name] for name in READING_KEYS)
        return self._reading_values()

    def close(self) -> None:
        pass
