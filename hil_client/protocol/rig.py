"""The abstract rig the protocol runner talks to.

A rig takes setpoints and commands, advances (or waits for) time, and reads its instruments.
The same runner drives the in-process rig and the Modbus rig.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

#: Readings beyond CONTRACT section 3 a bench may lack (the other analyser gases, the FID):
#: a rig without them returns NaN, and the log's fields stay empty.
OPTIONAL_READINGS: tuple[str, ...] = ("flue_gas_NOx_ppm", "flue_gas_SO2_ppm", "flue_gas_OGC_ppm")

#: Instrument readings every rig returns, by name (lab-log columns, CONTRACT section 3).
READING_KEYS: tuple[str, ...] = (
    "water_flow_kg_h",
    "water_in_temp_C",
    "water_out_temp_C",
    "boiler_water_temp_C",
    "flue_gas_temp_C",
    "flue_gas_O2_pct",
    "flue_gas_CO2_pct",
    "flue_gas_CO_ppm",
    "flue_gas_velocity_m_s",
    "chimney_draught_Pa",
    "balance_mass_kg",
    "room_temp_C",
    "ambient_pressure_hPa",
    "relative_humidity_pct",
    "electric_power_W",
    "boiler_on",
    *OPTIONAL_READINGS,
)


@dataclass(slots=True)
class RigCommand:
    """What the test controller writes to the bench each step."""

    flow_setpoint_kg_h: float
    return_setpoint_C: float
    pump_on: bool
    boiler_on: bool
    return_heating: bool = False


@dataclass(frozen=True, slots=True)
class StepTiming:
    """Where the wall time went between two reads of a real-time bench's clock: the one the
    last row has and the one before. A hole in the rows lies between two such reads, and
    the wait that made it may have come in the step before the hole's (a unit's late reply
    after the clock was read: a 4-s delay fault was blamed on a server stall that never
    was, a stranger's probe), so the reads of the clock bound it, not the steps."""

    #: between the two reads of the clock [s]
    wall_s: float = 0.0
    #: waited on purpose for the clock to reach the next acquisition [s]
    paced_s: float = 0.0
    #: waited on the replies of the bench's own clock (its simulation control) [s]
    server_s: float = 0.0
    #: waited on the replies of each instrument, by unit ID [s]
    units_s: Mapping[int, float] = field(default_factory=dict)
    #: the client process stood still, wherever it was (a heartbeat's late wake-ups:
    #: :mod:`hil_client.rigs.holdups`) [s]
    held_s: float = 0.0

    @property
    def client_s(self) -> float:
        """The client itself was held up (paused, swapped out, overloaded) [s]: the rest of
        the wall time, or what its heartbeat saw where more: a client stopped while it
        waited on a reply finds the reply there when it goes on, and the stop looked like
        that wait (a stranger's probe: one SIGSTOPped in a socket wait about one time in
        four)."""
        rest = self.wall_s - self.paced_s - self.server_s - sum(self.units_s.values())
        return max(rest, self.held_s, 0.0)

    @property
    def waits_s(self) -> tuple[float, dict[int, float]]:
        """(the server's, each unit's) waits with the hold-up the heartbeat saw inside
        them taken out of the longest, where the stop must have fallen [s]."""
        rest = self.wall_s - self.paced_s - self.server_s - sum(self.units_s.values())
        inside = max(self.held_s - max(rest, 0.0), 0.0)
        server, units = self.server_s, dict(self.units_s)
        longest = max(units, key=units.__getitem__, default=None)
        if longest is not None and units[longest] > server:
            units[longest] = max(units[longest] - inside, 0.0)
        else:
            server = max(server - inside, 0.0)
        return server, units


class RigError(RuntimeError):
    """The rig cannot be reached or answered wrongly."""


class Rig(Protocol):
    """What the protocol runner needs from a bench."""

    def apply(self, command: RigCommand) -> None:
        """Write setpoints and commands."""

    def advance(self, dt_s: float) -> float:
        """Let ``dt_s`` seconds of simulated time pass; returns the time that passed [s]."""

    def read(self) -> Mapping[str, float]:
        """Read every instrument: a value for each of :data:`READING_KEYS` (NaN if missing)."""

    # Optional: ``read_values() -> Sequence[float]``, the same readings in READING_KEYS
    # order without the mapping (the runner uses it when a rig has it). A rig over a wire
    # may also have (the runner logs and checks them when it does):
    # - ``written_flow_setpoint_kg_h: float``: the flow setpoint the bench holds from the
    #   rig's writes, as the point's encoding carries it (NaN before one was taken); the
    #   log's ``water_flow_setpoint_kg_h``;
    # - ``refusal: str | None``: a plant command the bench refused as an illegal value
    #   (not a transient fault): the method cannot be carried out, the run stops;
    # - ``step_timing: StepTiming``: where the wall time went between the reads of the
    #   bench's clock the last two rows have (who was held up in a hole of the rows);
    # - ``gaps``: breaks and outages (CONTRACT section 7); an entry with ``speed_after`` is
    #   the bench's clock changing speed (another client), which loses no row.

    def close(self) -> None:
        """Release the rig."""


#: Columns of the lab log (CONTRACT section 3), in file order: the step's own, the
#: readings, the flow setpoint spliced in before ``boiler_on``, and the rig's epoch.
LOG_COLUMNS: tuple[str, ...] = (
    "time_s",
    "phase",
    "sequence",
    *READING_KEYS[: READING_KEYS.index("boiler_on")],
    "water_flow_setpoint_kg_h",
    *READING_KEYS[READING_KEYS.index("boiler_on") :],
    "rig_epoch",
)
