"""The Wieselburg bench's acquisition: true 1-s plant signals -> lab-log readings.

Instruments after Carlon et al. (2015), Section 2.2 (digest section 5): Pt100 class B
thermometers (offsets, lags in thermowells, noise, 0.01 K / 0.1 K resolution), an inductive
flow meter (gain error, noise, low-flow cut-off), a heated-line gas analyser (paramagnetic O2,
NDIR CO2/CO: transport delay, first-order response, slow O2 drift, automatic calibration gaps
logged as NaN), a vortex flue-gas velocity meter (range from about 0.3 m/s, below reads 0), a
micro-manometer for the draught (held at about -12 Pa), a 0.02 kg balance under the hopper
(vibration while the auger runs) and room sensors.

The forward (outlet) temperature passes the exit pipe first: plug flow through the pipe water
(delay = pipe mass / flow, Eq. 7 applied to a moving parcel) with heat loss to the room while
the parcel sits in the pipe; `outlet_sensor_pipe` forms make this strong (effects.py).
The boiler-water sensor sits high in the body: it reads the water node plus a stratification
offset proportional to the heat flowing into the water.

Assumptions: chimney diameter 0.10 m; vapour and dry gas at the flue-gas temperature; the
quantities come from kernel.py's per-second records.
"""

from __future__ import annotations

import numpy as np

from .kernel import dead_leg_sensor, first_order_lag

CHIMNEY_AREA_M2 = np.pi * 0.10**2 / 4.0
VORTEX_CUTOFF_M_S = 0.3
BACKGROUND_PIPE_TAU_LOSS_S = 14_400.0  # insulated exit pipe, 4 h
BACKGROUND_PIPE_HOLD_FRAC = 0.98  # stagnant pipe kept warm by conduction from the body


def _quantise(x: np.ndarray, step: float) -> np.ndarray:
    return np.round(x / step) * step


def _lag(x: np.ndarray, tau_s: float) -> np.ndarray:
    return first_order_lag(np.ascontiguousarray(x, dtype=np.float64), np.full(x.shape, tau_s), 1.0)


def exit_pipe_temperature(
    t_water: np.ndarray,
    flow_kg_h: np.ndarray,
    t_room: np.ndarray,
    pipe_kg: float,
    tau_loss_s: float,
    hold_frac: float,
) -> np.ndarray:
    """Water temperature at the sensor, `pipe_kg` of water downstream of the boiler outlet.

    The parcel now at the sensor left the boiler at the last time the cumulative mass that
    passed was `pipe_kg` less than now; it relaxes towards T_room + hold_frac * (T_w - T_room)
    with time constant tau_loss_s during its residence time."""
    n = t_water.shape[0]
    mass = np.concatenate(([0.0], np.cumsum(flow_kg_h[:-1] / 3600.0)))
    target = mass - pipe_kg
    left = np.searchsorted(mass, target, side="right") - 1
    left = np.clip(left, 0, n - 1)
    k = np.arange(n)
    residence_s = (k - left).astype(np.float64)
    t_parcel = t_water[left]
    t_asym = t_room + hold_frac * (t_water - t_room)
    return t_asym + (t_parcel - t_asym) * np.exp(-residence_s / tau_loss_s)


def analyser_gaps(n: int, bg: dict, rng: np.random.Generator) -> np.ndarray:
    """Boolean mask of the analyser's automatic calibrations (readings missing)."""
    gap = np.zeros(n, dtype=bool)
    period = bg["analyser_cal_period_s"]
    length = int(bg["analyser_cal_len_s"])
    start = period * rng.uniform(0.3, 1.0)
    while start < n:
        i = int(start)
        gap[i : i + length] = True
        start += period
    return gap


def measure(truth: dict, bg: dict, eff: dict, par_info: dict, rng: np.random.Generator) -> dict:
    """Per-second readings of every log column (floats), from the plant's true signals."""
    n = truth["t_water_C"].shape[0]
    t = np.arange(n, dtype=np.float64)
    room = truth["room_C"]
    flow = truth["flow_kg_h"]
    flow_nom = par_info["flow_nom_kg_h"]
    cols: dict[str, np.ndarray] = {}

    meas_flow = flow * (1.0 + bg["flow_gain_error"]) + rng.normal(
        0.0, bg["flow_noise_frac"] * flow_nom, n
    )
    meas_flow[np.abs(meas_flow) < 2.0] = 0.0
    cols["water_flow_kg_h"] = _quantise(meas_flow, 0.1)

    t_in = _lag(truth["t_in_C"], bg["t_water_tau_s"]) + bg["t_in_offset_K"]
    cols["water_in_temp_C"] = _quantise(t_in + rng.normal(0.0, 0.02, n), 0.01)

    pipe_kg = bg["outlet_pipe_kg"] + eff.get("pipe_extra_kg", 0.0)
    tau_loss = eff.get("pipe_tau_loss_s", BACKGROUND_PIPE_TAU_LOSS_S)
    hold = BACKGROUND_PIPE_HOLD_FRAC
    if "pipe_tau_loss_s" in eff:
        hold = BACKGROUND_PIPE_HOLD_FRAC - 0.5 * eff["pipe_extra_kg"] / 2.2
    t_pipe = exit_pipe_temperature(truth["t_water_C"], flow, room, pipe_kg, tau_loss, hold)
    if "dead_leg_tau_flow_s" in eff:
        t_pipe = dead_leg_sensor(
            t_pipe,
            flow / flow_nom,
            room,
            eff["dead_leg_tau_flow_s"],
            eff["dead_leg_tau_loss_s"],
            0.5,
            1.0,
        )
    t_out = _lag(t_pipe, bg["t_water_tau_s"]) + bg["t_out_offset_K"]
    cols["water_out_temp_C"] = _quantise(t_out + rng.normal(0.0, 0.02, n), 0.01)

    q_rel = np.clip(truth["q_in_water_kW"] / par_info["p_nom_kW"], -0.5, 1.2)
    t_body = truth["t_water_C"] + bg["boiler_stratification_K"] * q_rel
    t_body = _lag(t_body, bg["boiler_sensor_tau_s"]) + bg["boiler_sensor_offset_K"]
    cols["boiler_water_temp_C"] = _quantise(t_body + rng.normal(0.0, 0.03, n), 0.01)

    t_fg = _lag(truth["t_fg_C"], bg["flue_sensor_tau_s"]) + bg["flue_sensor_offset_K"]
    cols["flue_gas_temp_C"] = _quantise(t_fg + rng.normal(0.0, 0.15, n), 0.1)

    delay = round(bg["analyser_delay_s"])
    gaps = analyser_gaps(n, bg, rng)

    def analyser(x: np.ndarray) -> np.ndarray:
        shifted = np.concatenate((np.full(delay, x[0]), x[: n - delay]))
        return _lag(shifted, bg["analyser_tau_s"])

    o2 = analyser(truth["o2_pct"]) + bg["o2_offset_pct"] + bg["o2_drift_pct_h"] * t / 3600.0
    o2 = np.clip(o2 + rng.normal(0.0, 0.03, n), 0.0, 21.5)
    co2 = np.clip(analyser(truth["co2_pct"]) + rng.normal(0.0, 0.03, n), 0.0, None)
    co_true = analyser(truth["co_ppm"])
    co = np.clip(co_true * (1.0 + rng.normal(0.0, 0.03, n)) + rng.normal(0.0, 2.0, n), 0.0, None)
    o2, co2, co = _quantise(o2, 0.01), _quantise(co2, 0.01), _quantise(co, 1.0)
    for x in (o2, co2, co):
        x[gaps] = np.nan
    cols["flue_gas_O2_pct"] = o2
    cols["flue_gas_CO2_pct"] = co2
    cols["flue_gas_CO_ppm"] = co

    pressure = bg["pressure_hPa"] + bg["pressure_trend_hPa"] * t / max(t[-1], 1.0)
    vel = (
        truth["gas_m3_s"]
        * (truth["t_fg_C"] + 273.15)
        / 273.15
        * (1013.25 / pressure)
        / CHIMNEY_AREA_M2
    )
    vel = _lag(vel, 3.0) + rng.normal(0.0, 0.02, n)
    vel[vel < VORTEX_CUTOFF_M_S] = 0.0
    cols["flue_gas_velocity_m_s"] = _quantise(vel, 0.01)

    draught_noise = _lag(rng.normal(0.0, 1.5, n), 8.0)
    draught = bg["draught_Pa"] - 0.4 * truth["fan_on"] + draught_noise
    cols["chimney_draught_Pa"] = _quantise(draught, 0.1)

    fed_before = np.concatenate(([0.0], np.cumsum(truth["feed_kg"][:-1])))
    balance = bg["balance_tare_kg"] + bg["fuel_initial_kg"] - fed_before
    balance = balance + rng.normal(0.0, bg["balance_noise_kg"], n)
    balance = balance + truth["auger_on"] * rng.normal(0.0, 0.02, n)
    cols["balance_mass_kg"] = _quantise(balance, 0.02)

    cols["room_temp_C"] = _quantise(room + rng.normal(0.0, 0.05, n), 0.1)
    cols["ambient_pressure_hPa"] = _quantise(pressure + rng.normal(0.0, 0.05, n), 0.1)
    humidity = bg["humidity_pct"] - 1.5 * (room - bg["room_temp_mean_C"])
    cols["relative_humidity_pct"] = _quantise(humidity + rng.normal(0.0, 0.3, n), 0.1)
    cols["electric_power_W"] = _quantise(truth["p_el_W"] + rng.normal(0.0, 0.5, n), 0.1)
    cols["water_flow_setpoint_kg_h"] = _quantise(truth["flow_set_kg_h"], 0.1)
    cols["boiler_on"] = truth["boiler_on"].astype(np.int64)
    return cols
