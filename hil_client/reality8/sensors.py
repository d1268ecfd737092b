"""Acquisition: sampling times and the instruments' offsets, noise, lags and quantisation.

Instruments (digest Sec. 5): Pt100 water sensors (offset +-0.15 K, noise 0.02 K, 0.01 K
resolution), boiler-body sensor (+-0.3 K), flue Pt100 class B (+-1 K, 0.1 K), paramagnetic O2
behind a heated line (delay 15-40 s, cell 8-20 s, offset and drift +-0.2 %), NDIR CO2/CO,
inductive flow meter (gain +-1 %, zero cut-off below 2 kg/h), balance 0.02 kg, vortex meter
(no reading below 0.5 m/s -> missing value).
"""

from __future__ import annotations

import numpy as np

from .kernel import SIGNAL_NAMES
from .protocol import PHASES
from .series import ar1, delay_lag

SIG = {n: i for i, n in enumerate(SIGNAL_NAMES)}


def sample_times(
    rng: np.random.Generator, t_end: float, sample_s: float, jitter: bool
) -> np.ndarray:
    """Acquisition instants in [0, t_end]; with jitter each moves by up to +-20 % of sample_s."""
    n = int(np.floor(t_end / sample_s)) + 1
    t = np.arange(n) * sample_s
    if jitter:
        t = t + rng.uniform(-0.2, 0.2, n) * sample_s
        t[0] = 0.0
    return t[t <= t_end]


def _q(x: np.ndarray, step: float) -> np.ndarray:
    return np.round(x / step) * step


def measure(
    sig: np.ndarray,
    t: np.ndarray,
    rng: np.random.Generator,
    bg: dict,
    hopper0: float,
    seq_names: list[str],
) -> dict[str, np.ndarray]:
    """Lab-log columns at instants ``t`` from the 1 s signals of the kernel."""
    grid = sig[:, SIG["time"]]
    n = t.shape[0]
    idx = np.clip(np.floor(t).astype(int), 0, grid.shape[0] - 1)

    def at(name: str) -> np.ndarray:
        return np.interp(t, grid, sig[:, SIG[name]])

    def noise(sd: float) -> np.ndarray:
        return sd * rng.standard_normal(n)

    t_end = max(grid[-1], 1.0)
    cols: dict[str, np.ndarray] = {"time_s": np.round(t, 3)}
    phase = sig[idx, SIG["phase"]].astype(int)
    seq = sig[idx, SIG["seq"]]
    cols["phase"] = np.array([PHASES[i] for i in phase], dtype=object)
    names = []
    for ph, s in zip(phase, seq, strict=True):
        if ph == 2 and s >= 0:
            names.append(seq_names[int(s)])
        else:
            names.append(PHASES[ph])
    cols["sequence"] = np.array(names, dtype=object)
    flow_true = at("flow")
    flow = flow_true * bg["flow_gain"] * (1.0 + noise(0.003)) + noise(0.5)
    cols["water_flow_kg_h"] = np.where(flow_true < 2.0, 0.0, np.round(flow, 2))
    cols["water_in_temp_C"] = _q(at("t_in") + bg["off_in_K"] + noise(0.02), 0.01)
    cols["water_out_temp_C"] = _q(at("t_out_sens") + bg["off_out_K"] + noise(0.02), 0.01)
    cols["boiler_water_temp_C"] = _q(at("t_w_sens") + bg["off_wb_K"] + noise(0.03), 0.01)
    t_fg = at("t_fg_sens")
    cols["flue_gas_temp_C"] = _q(t_fg + bg["off_fg_K"] + noise(0.15), 0.1)
    d = round(bg["o2_delay_s"])
    o2 = np.interp(t, grid, delay_lag(sig[:, SIG["o2"]], d, bg["o2_tau_s"]))
    o2 = o2 + bg["off_o2_pct"] + bg["drift_o2_pct"] * t / t_end + noise(0.05)
    cols["flue_gas_O2_pct"] = _q(np.clip(o2, 0.0, 20.95), 0.01)
    co2 = np.interp(t, grid, delay_lag(sig[:, SIG["co2"]], d, bg["o2_tau_s"]))
    cols["flue_gas_CO2_pct"] = _q(np.clip(co2 + noise(0.05), 0.0, None), 0.01)
    co = np.interp(t, grid, delay_lag(sig[:, SIG["co_ppm"]], d, bg["o2_tau_s"]))
    cols["flue_gas_CO_ppm"] = np.round(np.clip(co + noise(3.0), 0.0, None))
    area = np.pi * bg["duct_d_m"] ** 2 / 4.0
    vol = at("gas_m3n_h") * (t_fg + 273.15) / 273.15 * 1013.25 / bg["pressure_hPa"] / 3600.0
    vel = vol / area * (1.0 + noise(0.02))
    cols["flue_gas_velocity_m_s"] = np.where(vel < 0.5, np.nan, np.round(vel, 3))
    draught = -12.0 + ar1(rng.standard_normal(n), 30.0, 0.3) + noise(0.2)
    cols["chimney_draught_Pa"] = np.round(draught, 2)
    bal = hopper0 + sig[idx, SIG["hopper"]] + noise(0.004)
    cols["balance_mass_kg"] = np.round(_q(bal, 0.02), 2)
    cols["room_temp_C"] = _q(at("t_room") + noise(0.05), 0.01)
    cols["ambient_pressure_hPa"] = np.round(
        bg["pressure_hPa"] + ar1(rng.standard_normal(n), 2000.0, 0.8), 1
    )
    cols["relative_humidity_pct"] = np.round(
        np.clip(bg["humidity_pct"] + ar1(rng.standard_normal(n), 2000.0, 2.0), 5.0, 95.0), 1
    )
    cols["electric_power_W"] = np.round(sig[idx, SIG["p_el"]] + noise(0.5), 1)
    cols["water_flow_setpoint_kg_h"] = np.round(sig[idx, SIG["flow_sp"]], 2)
    cols["boiler_on"] = sig[idx, SIG["boiler_on"]].astype(int)
    return cols
