"""The in-process rig: steps the emulator's bench directly (no network)."""

from __future__ import annotations

from rig_emulator.bench import Bench, BenchConfig, BenchOutputs
from rig_emulator.model import MODULATING, STARTUP
from rig_emulator.model.params import BoilerParams

from hil_client.protocol.rig import RigCommand

PROFILES = ("clean",)


class LocalRig:
    """A :class:`~rig_emulator.bench.Bench` behind the rig interface.

    Profile ``clean``: the ideal model read by perfect instruments.
    """

    def __init__(
        self, params: BoilerParams, profile: str = "clean", seed: int = 0,
        config: BenchConfig | None = None,
    ) -> None:
        if profile not in PROFILES:
            raise ValueError(f"unknown profile '{profile}' (available: {', '.join(PROFILES)})")
        self.bench = Bench(params, config)
        self.seed = seed
        self.last: BenchOutputs | None = None

    def apply(self, command: RigCommand) -> None:
        inp = self.bench.inputs
        inp.flow_setpoint_kg_h = command.flow_setpoint_kg_h
        inp.return_setpoint_C = command.return_setpoint_C
        inp.pump_on = command.pump_on
        inp.boiler_on = command.boiler_on
        inp.return_heating = command.return_heating

    def advance(self, dt_s: float) -> None:
        self.last = self.bench.step(dt_s)

    def read(self) -> dict[str, float]:
        o = self.last
        if o is None:
            raise RuntimeError("read() before the first advance()")
        b = o.boiler
        return {
            "water_flow_kg_h": o.water_flow_kg_h,
            "water_in_temp_C": o.water_in_temp_C,
            "water_out_temp_C": o.water_out_temp_C,
            "boiler_water_temp_C": b.t_boiler_C,
            "flue_gas_temp_C": b.t_flue_gas_C,
            "flue_gas_O2_pct": b.o2_pct,
            "flue_gas_CO2_pct": b.co2_pct,
            "flue_gas_CO_ppm": b.co_ppm,
            "flue_gas_velocity_m_s": o.flue_gas_velocity_m_s,
            "chimney_draught_Pa": o.chimney_draught_Pa,
            "balance_mass_kg": o.balance_mass_kg,
            "room_temp_C": o.room_temp_C,
            "ambient_pressure_hPa": o.ambient_pressure_hPa,
            "relative_humidity_pct": o.relative_humidity_pct,
            "electric_power_W": b.p_el_W,
            "boiler_on": 1.0 if b.mode == STARTUP or b.mode == MODULATING else 0.0,
        }

    def close(self) -> None:
        pass
