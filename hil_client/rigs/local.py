"""The in-process rig: steps the emulator's bench directly (no network)."""

from __future__ import annotations

from hil_client.protocol.rig import RigCommand
from rig_emulator.bench import Bench, BenchConfig
from rig_emulator.model.layout import Y_CO, Y_CO2, Y_O2, Y_P_EL, Y_T_BOILER, Y_T_FG
from rig_emulator.model.params import BoilerParams

PROFILES = ("clean",)


class LocalRig:
    """A :class:`~rig_emulator.bench.Bench` behind the rig interface.

    Profile ``clean``: the ideal model read by perfect instruments.
    """

    def __init__(
        self,
        params: BoilerParams,
        profile: str = "clean",
        seed: int = 0,
        config: BenchConfig | None = None,
    ) -> None:
        if profile not in PROFILES:
            raise ValueError(f"unknown profile '{profile}' (available: {', '.join(PROFILES)})")
        self.bench = Bench(params, config)
        self.seed = seed
        self._stepped = False

    def apply(self, command: RigCommand) -> None:
        self.bench.set_inputs(
            command.flow_setpoint_kg_h,
            command.return_setpoint_C,
            command.pump_on,
            command.boiler_on,
            command.return_heating,
        )

    def advance(self, dt_s: float) -> None:
        self.bench.step(dt_s)
        self._stepped = True

    def read(self) -> dict[str, float]:
        if not self._stepped:
            raise RuntimeError("read() before the first advance()")
        (_, flow, t_in, t_out, room, pressure, humidity, balance, velocity, draught, _, on) = (
            self.bench.yb.tolist()
        )
        y = self.bench.y.tolist()
        return {
            "water_flow_kg_h": flow,
            "water_in_temp_C": t_in,
            "water_out_temp_C": t_out,
            "boiler_water_temp_C": y[Y_T_BOILER],
            "flue_gas_temp_C": y[Y_T_FG],
            "flue_gas_O2_pct": y[Y_O2],
            "flue_gas_CO2_pct": y[Y_CO2],
            "flue_gas_CO_ppm": y[Y_CO],
            "flue_gas_velocity_m_s": velocity,
            "chimney_draught_Pa": draught,
            "balance_mass_kg": balance,
            "room_temp_C": room,
            "ambient_pressure_hPa": pressure,
            "relative_humidity_pct": humidity,
            "electric_power_W": y[Y_P_EL],
            "boiler_on": on,
        }

    def close(self) -> None:
        pass
