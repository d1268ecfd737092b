"""Tests of the reality9 plant: balances, a closed-form steady state, effects, log I/O."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from hil_client.reality9 import (
    COLUMNS,
    EFFECT_FORMS,
    draw_background,
    read_log_csv,
    simulate_log,
    write_log_csv,
)
from hil_client.reality9.plant import run_plant

ROOT = Path(__file__).parents[3]


def _boiler(name: str) -> dict:
    return yaml.safe_load((ROOT / "rig_emulator" / "boilers" / f"{name}.yaml").read_text())


@pytest.fixture(scope="module")
def b12() -> dict:
    return _boiler("windhager_12kw")


@pytest.fixture(scope="module")
def bg12(b12) -> dict:
    return draw_background(np.random.default_rng(7), b12)


def _residuals(st: dict) -> tuple[float, float]:
    e = st["e_in"] - st["e_water"] - st["e_flue"] - st["e_ash"] - st["e_room"] - st["e_store"]
    m = st["fed_dry"] - st["burned"] - st["m_bed"]
    return float(np.max(np.abs(e))), float(np.max(np.abs(m)))


@pytest.mark.parametrize(
    ("effect", "form"),
    [
        (None, None),
        ("body_heat_diffusion", "fire_side_steel_skin"),
        ("body_heat_diffusion", "three_shell_conduction_chain"),
        ("flue_gas_lag", "hearth_stone_buffer"),
        ("flue_gas_lag", "baffle_cascade_pair"),
        ("fuel_energy_bias", "cold_wall_char_residue"),
        ("ignition_delay", "slow_kindling_front"),
    ],
)
def test_energy_and_mass_close_every_step(b12, bg12, effect, form):
    st = run_plant(b12, "load_cycle", bg12, effect, form, 0.8, 3)["steps"]
    e_res, m_res = _residuals(st)
    assert e_res < 1e-9 * max(1.0, float(np.max(st["e_in"])))
    assert m_res < 1e-12
    # cumulative: fuel energy in equals everything out plus storage, over the whole run
    total_in = st["e_in"].sum()
    total_out = sum(st[k].sum() for k in ("e_water", "e_flue", "e_ash", "e_room", "e_store"))
    assert abs(total_in - total_out) < 1e-8 * total_in
    assert total_in > 1e5  # many hours of firing, in kJ


def test_steady_state_matches_closed_form(b12, bg12):
    """At nominal load, with the random inputs switched off, the plant settles where the
    PI controller's integral puts it, and the burnt fuel balances the heat to water by the
    stoichiometry and the losses written out here independently."""
    bg = dict(bg12)
    bg.update(lump_sigma=0.0, rc_osc_amp_K=0.0, room_amp_K=0.0, co_base_ppm=0.0)
    bg.update(auger_gain=1.08, t_set_C=69.5, moisture_dev=0.0, hhv_factor=1.0)
    for name in ("ctrl", "bw", "out", "in", "fg"):
        bg[f"{name}_drift_K_h"] = 0.0
        bg[f"{name}_drift_amp_K"] = 0.0
    st = run_plant(b12, "stationary", bg, None, None, 0.0, 1)["steps"]
    sel = np.flatnonzero(st["phase"] == 2)[-3600:]  # last 2 h of the test
    assert np.all(st["p_cmd"][sel] < b12["p_max_kW"] - 0.1)  # not saturated
    t_b = st["t_b"][sel].mean()
    # PI with integral action: the controller's sensor reads its set point
    assert t_b == pytest.approx(bg["t_set_C"] - bg["ctrl_offset_K"], abs=0.02)
    assert np.ptp(st["t_b"][sel]) < 0.05
    # bed: constant feed f, burn M(1 - exp(-dt/tau)) per step  ->  M = f dt / (1 - exp(-dt/tau))
    m_b = st["m_b"][sel].mean()
    m_bed = m_b * 2.0 / 3600.0 / (1.0 - math.exp(-2.0 / bg["tau_bed_s"]))
    assert st["m_bed"][sel].mean() == pytest.approx(m_bed, rel=1e-3)
    # combustion, written out: fuel of Table 1, air from the fan law of Eq. 9
    f = b12["fuel"]
    hhv = f["hhv_dry_kJ_kg"]
    w = f["moisture"]
    o2_air = (1.866 * f["c"] + 5.56 * f["h"] + 0.7 * f["s"] - 0.7 * f["o"]) / 0.21  # m3/kg
    p_cmd = st["p_cmd"][sel].mean()
    m_cmd = p_cmd * 3600.0 / (hhv - 2442.0 * 9.0 * f["h"])
    assert m_b == pytest.approx(m_cmd * bg["auger_gain"], rel=1e-3)
    lam_set = b12["fac_a_lambda"] + b12["fac_b_lambda_h_kg"] * m_cmd
    m_air = lam_set * o2_air * 1.293 * m_cmd * bg["fan_factor"]
    lam = m_air / (o2_air * 1.293 * m_b)
    o2 = st["o2"][sel].mean()
    assert lam == pytest.approx(21.0 / (21.0 - o2), rel=0.02)  # the digest's rule of thumb
    vap = m_b * (9.0 * f["h"] + w / (1.0 - w))
    dry_gas = m_air + m_b * (1.0 - f["ash"] - 9.0 * f["h"])
    t_room = bg["room_base_C"]
    t_fg = st["t_fg"][sel].mean()
    q_fuel = m_b * hhv / 3600.0
    q_flue = (dry_gas * 1.06 + vap * 1.90) * (t_fg - t_room) / 3600.0 + vap * 2442.0 / 3600.0
    q_hx = q_fuel * (1.0 - 0.0002) - q_flue
    t_in = st["t_in"][sel].mean()
    m_w = st["m_w"][sel].mean()
    q_w = m_w * 4.19 * (t_b - t_in) / 3600.0
    q_amb = b12["ua_amb_on_W_K"] * bg["ua_on_factor"] / 1000.0 * (t_b - t_room)
    assert q_hx == pytest.approx(q_w + q_amb, rel=2e-3)
    assert t_in == pytest.approx(55.0, abs=0.01)
    assert q_w / q_fuel == pytest.approx(0.85, abs=0.06)  # the paper's ~85 % to water


SIGNAL = {  # the internal signal each effect acts on, and the phase where it shows
    "body_heat_diffusion": ("t_b", 1),
    "outlet_sensor_pipe": ("t_out_m", 4),
    "ignition_delay": ("m_b", 1),
    "flue_gas_lag": ("t_fg", 1),
    "fuel_energy_bias": ("fed_ar", 2),
}


@pytest.mark.parametrize(
    ("effect", "form"), [(e, f) for e, forms in EFFECT_FORMS.items() for f in forms]
)
def test_strength_one_changes_its_signal(b12, bg12, effect, form):
    base = run_plant(b12, "stationary", bg12, None, None, 0.0, 5)["steps"]
    st = run_plant(b12, "stationary", bg12, effect, form, 1.0, 5)["steps"]
    key, phase = SIGNAL[effect]
    a = base[key][base["phase"] == phase]
    b = st[key][st["phase"] == phase]
    n = min(len(a), len(b))
    if key == "fed_ar":  # kilograms per kWh to water
        ra = np.ptp(a) / base["e_water"][base["phase"] == phase].sum()
        rb = np.ptp(b) / st["e_water"][st["phase"] == phase].sum()
        assert abs(rb / ra - 1.0) > 0.02
    else:
        assert np.max(np.abs(a[:n] - b[:n])) > 0.5 * max(1e-3, np.std(a))


def _same(a: dict, b: dict) -> bool:
    if list(a) != list(b):
        return False
    for k in a:
        x, y = np.asarray(a[k]), np.asarray(b[k])
        if x.dtype == object or y.dtype == object:
            if not np.array_equal(x, y):
                return False
        elif not np.array_equal(x, y, equal_nan=True):
            return False
    return True


def test_strength_zero_is_bit_for_bit_and_deterministic(b12, bg12):
    kw = {"background": bg12, "seed": 11, "sample_s": 5.0, "jitter": False}
    none, m0 = simulate_log(b12, "stationary", effect=None, form=None, strength=0.0, **kw)
    zero, _ = simulate_log(
        b12, "stationary", effect="flue_gas_lag", form="baffle_cascade_pair", strength=0.0, **kw
    )
    again, m1 = simulate_log(b12, "stationary", effect=None, form=None, strength=0.0, **kw)
    assert _same(none, zero)
    assert _same(none, again)
    assert all(m0[k] == m1[k] for k in ("t0_s", "t1_s", "t2_s", "t3_s", "t4_s"))
    t = [m0[f"t{i}_s"] for i in range(5)]
    assert all(np.isfinite(t)) and t == sorted(t)
    assert t[4] - t[2] == pytest.approx(28800.0, abs=2.0)
    tiny, _ = simulate_log(
        b12, "stationary", effect="flue_gas_lag", form="baffle_cascade_pair", strength=1e-4, **kw
    )
    d = np.nanmax(np.abs(tiny["flue_gas_temp_C"] - none["flue_gas_temp_C"]))
    assert 0.0 < d < 1.0


def test_csv_round_trip_and_jitter(tmp_path, bg12):
    b6 = _boiler("windhager_6kw")
    cols, _meta = simulate_log(
        b6,
        "load_cycle",
        background=bg12,
        effect="outlet_sensor_pipe",
        form="aging_parcel_transit",
        strength=0.5,
        seed=3,
        sample_s=10.0,
        jitter=True,
    )
    assert list(cols)[: len(COLUMNS)] == list(COLUMNS)
    dt = np.diff(cols["time_s"])
    assert np.all(dt > 0) and dt.min() >= 10.0 * 0.39 and dt.max() <= 10.0 * 1.61
    assert np.std(dt) > 0.5  # irregular
    assert set(cols["phase"]) == {"preheat", "start_up", "test", "cooling_1", "cooling_2"}
    assert "stationary_13" in set(cols["sequence"])
    n = len(cols["time_s"])
    assert all(len(v) == n for v in cols.values())
    path = tmp_path / "log.csv"
    write_log_csv(cols, path)
    header = path.read_text().splitlines()[0].split(",")
    assert header == list(COLUMNS)
    back = read_log_csv(path)
    for k in COLUMNS:
        if k in ("phase", "sequence"):
            assert list(back[k]) == list(cols[k])
        else:
            np.testing.assert_array_equal(back[k], np.asarray(cols[k], dtype=float))
    w = cols["water_flow_kg_h"][cols["phase"] == "cooling_2"]
    assert np.nanmax(w[len(w) // 2 :]) == 0.0
    bal = cols["balance_mass_kg"]
    steps = np.round(np.diff(bal[np.isfinite(bal)]) / 0.02, 6)
    assert np.all(steps == np.round(steps))  # 0.02 kg resolution


def test_missing_values_written_empty(tmp_path):
    cols = {"time_s": np.array([0.0, 1.0]), "water_flow_kg_h": np.array([np.nan, 2.0])}
    cols["phase"] = np.array(["test", None], dtype=object)
    write_log_csv(cols, tmp_path / "x.csv")
    lines = (tmp_path / "x.csv").read_text().splitlines()
    assert lines[0] == "time_s,phase,water_flow_kg_h"
    assert lines[1] == "0.0,test," and lines[2] == "1.0,,2.0"


@pytest.mark.parametrize(
    "kw",
    [
        {"test": "weekly"},
        {"effect": "soot"},
        {"effect": "flue_gas_lag", "form": "plug_flow"},
        {"effect": None, "form": "hearth_stone_buffer"},
        {"sample_s": 0.5},
        {"sample_s": 11.0},
    ],
)
def test_bad_input_raises(b12, bg12, kw):
    args = {
        "test": "stationary",
        "background": bg12,
        "effect": None,
        "form": None,
        "strength": 0.5,
        "seed": 1,
        "sample_s": 1.0,
        "jitter": False,
    }
    args.update(kw)
    test = args.pop("test")
    with pytest.raises(ValueError):
        simulate_log(b12, test, **args)
