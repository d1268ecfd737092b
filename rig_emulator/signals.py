"""The catalog of signals the emulator publishes and accepts.

Every register-map point names one of these signals. *Measured* signals come from the plant
through an instrument (see :mod:`rig_emulator.instruments`); *commands* are written by the
test controller and checked against their range; *status* signals describe the emulator
itself (simulated time, speed, tick lateness) and are published as they are.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Signal:
    """A named quantity of the bench.

    Attributes:
        name: identifier used by register maps and profiles (unit in the name).
        unit: unit of the value.
        kind: ``measured``, ``command`` or ``status``.
        description: what it is, for the generated map reference.
        minimum, maximum: accepted range of a command (inclusive).
    """

    name: str
    unit: str
    kind: str
    description: str
    minimum: float = float("-inf")
    maximum: float = float("inf")

    @property
    def switch(self) -> bool:
        """An on/off signal (unit ``0/1``): a coil or a discrete input may carry it."""
        return self.unit == "0/1"

    @property
    def whole(self) -> bool:
        """A command that takes whole numbers only: a switch, a mode or a code (a scaled
        register let 0.5 through to the burner's switch: a stranger's probe)."""
        return self.kind == "command" and (self.switch or self.name in WHOLE_COMMANDS)


_MEASURED = (
    ("water_flow_kg_h", "kg/h", "water mass flow through the boiler (inductive meter)"),
    ("water_in_temp_C", "C", "return (inlet) water temperature (Pt100)"),
    ("water_out_temp_C", "C", "forward (outlet) water temperature, sensor in the exit pipe"),
    ("boiler_water_temp_C", "C", "water temperature inside the boiler body"),
    ("room_temp_C", "C", "room air temperature"),
    ("ambient_pressure_hPa", "hPa", "air pressure"),
    ("relative_humidity_pct", "%", "room air relative humidity"),
    ("flue_gas_O2_pct", "vol-%", "O2 in the dry flue gas (paramagnetic)"),
    ("flue_gas_CO2_pct", "vol-%", "CO2 in the dry flue gas (NDIR)"),
    ("flue_gas_CO_ppm", "ppm", "CO in the dry flue gas (NDIR)"),
    ("flue_gas_NOx_ppm", "ppm", "NOx in the dry flue gas (NDIR)"),
    ("flue_gas_SO2_ppm", "ppm", "SO2 in the dry flue gas (NDIR)"),
    ("flue_gas_OGC_ppm", "ppm C1", "organic gaseous carbon (flame-ionisation detector)"),
    ("flue_gas_temp_C", "C", "flue-gas temperature (Pt100 class B, 4-wire)"),
    ("flue_gas_velocity_m_s", "m/s", "flue-gas velocity (vortex meter)"),
    ("chimney_draught_Pa", "Pa", "chimney draught (micro-manometer, negative)"),
    ("balance_mass_kg", "kg", "reading of the balance the boiler stands on"),
    ("electric_power_W", "W", "electric power drawn by the boiler"),
)
_STATUS = (
    (
        "analyser_status",
        "-",
        "analyser status word: bit 0 measuring, bit 1 CO over range, bit 2 a reading invalid",
    ),
    ("balance_stable", "0/1", "balance reading unchanged for 5 s"),
    ("electric_energy_Wh", "Wh", "electric energy counter since the start"),
    ("boiler_on", "0/1", "burner firing, as the boiler controller reports it"),
    ("boiler_mode", "-", "controller mode: 0 off, 1 start-up, 2 modulating, 3 cut-out"),
    ("firing_power_kW", "kW", "firing power of the burner (net basis)"),
    ("sim_time_s", "s", "simulated time since the start or the last reset"),
    ("tick_lateness_ms", "ms", "lateness of the last real-time tick against its deadline"),
    ("lockstep_counter", "-", "number of completed lockstep advances (wraps at 65536)"),
    ("epoch_id", "-", "random 32-bit identifier of this start of the emulator (a new plant)"),
    ("boiler_id", "-", "32-bit hash of the boiler parameters and the bench configuration"),
    ("profile_id", "-", "32-bit hash of the profile (instruments and effects)"),
    ("seed", "-", "seed of the instrument errors and noise (modulo 2^32)"),
    ("achieved_speed", "-", "simulated s per wall s of the last real-time tick (0 in lockstep)"),
    (
        "tick_overrun_ms",
        "ms",
        "simulation the last tick could not do in its budget or lost to a stall, dropped",
    ),
    ("active_fault_count", "-", "number of active faults (fault injection)"),
    (
        "map_id",
        "-",
        "32-bit hash of the register map served (units, points, types, scales, write ranges)",
    ),
)
_COMMANDS = (
    ("water_flow_setpoint_kg_h", "kg/h", "flow setpoint of the bench pump/valve", 0.0, 2000.0),
    ("return_setpoint_C", "C", "return temperature setpoint of the conditioning", 10.0, 90.0),
    ("pump_on", "0/1", "circulation pump on", 0.0, 1.0),
    ("return_heating", "0/1", "external heating of the return allowed (preheat)", 0.0, 1.0),
    ("boiler_command", "0/1", "boiler switched on by the bench", 0.0, 1.0),
    ("boiler_set_temp_C", "C", "outlet set temperature of the boiler controller", 40.0, 80.0),
    ("speed_factor", "-", "simulated seconds per wall second in real-time mode", 0.01, 100000.0),
    ("clock_mode", "-", "0 real time (paced), 1 lockstep", 0.0, 1.0),
    (
        "lockstep_advance_s",
        "s",
        "write N: advance the simulation by N s, reply when done",
        1.0,
        86400.0,
    ),
    ("reset", "-", "write 1: back to the initial state (same seed)", 0.0, 1.0),
    # the fault command block of the simulation control (rig_emulator/faults/wire.py)
    ("fault_kind", "-", "fault kind code: 1 delay .. 9 offset (see the README)", 0.0, 9.0),
    ("fault_target", "-", "unit ID, or signal index for instrument faults", 0.0, 65535.0),
    ("fault_parameter", "-", "delay_ms, exception code, rate_per_h or value", -1e9, 1e9),
    ("fault_duration_s", "s", "for_s of the fault; 0 until cleared", 0.0, 1e9),
    ("fault_at_s", "s", "at_s of the fault in simulated seconds; 0 now", 0.0, 1e9),
    ("fault_command", "-", "write 1: set the fault of the block; 2: clear all faults", 0.0, 2.0),
)

#: Commands besides the switches that are codes or counts, never fractions.
WHOLE_COMMANDS = frozenset({"clock_mode", "reset", "fault_kind", "fault_target", "fault_command"})

SIGNALS: dict[str, Signal] = {}
for _name, _unit, _text in _MEASURED:
    SIGNALS[_name] = Signal(_name, _unit, "measured", _text)
for _name, _unit, _text in _STATUS:
    SIGNALS[_name] = Signal(_name, _unit, "status", _text)
for _name, _unit, _text, _lo, _hi in _COMMANDS:
    SIGNALS[_name] = Signal(_name, _unit, "command", _text, _lo, _hi)

MEASURED: tuple[str, ...] = tuple(n for n, s in SIGNALS.items() if s.kind == "measured")
#: The plant's true value of each measured signal (fault injection's truth block).
for _name in MEASURED:
    SIGNALS["true_" + _name] = Signal(
        "true_" + _name, SIGNALS[_name].unit, "status", f"true plant value: {_name}"
    )
COMMANDS: tuple[str, ...] = tuple(n for n, s in SIGNALS.items() if s.kind == "command")
#: The commands that act on the plant (the bench's and the boiler's): the rest drive the
#: emulator itself (its clock and its faults)
PLANT_COMMANDS: tuple[str, ...] = (
    "water_flow_setpoint_kg_h",
    "return_setpoint_C",
    "pump_on",
    "return_heating",
    "boiler_command",
    "boiler_set_temp_C",
)
