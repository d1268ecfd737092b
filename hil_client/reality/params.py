"""The plant's parameters by name: one immutable record handed to the numba kernel.

:data:`PlantParams` is a named tuple of floats (numba reads it by attribute); build it with
:func:`pack` from a mapping, which names any key that is missing or unknown.
"""

from __future__ import annotations

from collections import namedtuple
from collections.abc import Mapping

NAMES: tuple[str, ...] = (
    # fuel as the controller assumes it, and as it really is
    "hhv_true", "moist_ar_nom", "moist_ar_true", "moist_true", "lhv_ar_nom",
    "o_min", "air_min", "v_co2", "v_so2", "v_n2f", "water_h",
    # boiler: power, body, losses, exchanger, air, electricity, CO
    "p_nom", "p_min", "p_max", "p_start",
    "c_metal", "c_water", "tau_mw", "ua_shell_kW_K", "draught_kW_K", "bc_share",
    "ntu_nom", "ntu_exp", "w_nom_kW_K", "sink_kappa", "ntu_fire_exp", "q_rel_nom_kW",
    "fire_share_min",
    "lam_a", "lam_b", "lam_floor", "fan_min_nm3_h", "duct_area_m2",
    "pel_min", "pel_max", "pel_off", "p_ign_W",
    "co_at_max", "co_at_min", "co_start_ppm", "co_stop_ppm", "co_tau_s",
    # controller
    "t_set", "kp_kW_K", "ti_s", "p_step_kW", "t_shut", "t_restart", "t_safety",
    "min_burn_s", "min_off_s", "t_purge_s", "t_ign_stage_s", "t_igniter_s", "ign_share",
    "t_ramp_s", "t_hold_s", "hold_exit_K", "t_post_s", "aug_period_s", "aug_max_share",
    "ctrl_tau_s", "ctrl_offset_K",
    # effects (forms coded 0 = absent)
    "body_form", "tau_body", "split_cap", "split_share",
    "pipe_form", "pipe_kg", "pipe_tau_loss_s", "well_tau_s",
    "flue_form", "flue_cap", "flue_ntu", "flue_ua_kW_K",
    "ign_form", "light_delay_s", "ign_ramp_s", "bed_tau_s",
    # bench: flow, return conditioning, room
    "flow_tau_s", "ret_tau_s", "ret_tau2_s", "q_cool_max_kW", "q_heat_max_kW",
    "ret_offset_K", "ret_ripple_K", "ret_ripple_period_s", "ret_stag_tau_s",
    "room0", "room_amp", "room_period_s", "room_phase", "room_trend_K_h",
    "p0_hPa", "p_amp", "rh0", "rh_amp", "t_init", "hopper_kg", "tare_kg",
    # instruments
    "tau_water_s", "tau_flue_s", "off_in", "off_out", "off_bw", "drift_in", "drift_out",
    "drift_bw", "noise_water_K", "noise_flue_K", "off_fg", "o2_delay_s", "o2_off",
    "o2_noise", "co2_gain", "flow_gain", "flow_noise", "strat_beta", "room_off",
    "draught_off", "dropout_p",
    # protocol
    "spread_K", "pre_temp", "pre_tol", "pre_hold", "pre_load", "pre_max", "su_ret",
    "su_win", "su_rise", "su_min", "su_max", "test_ret", "c1_load", "c1_ret", "c1_until",
    "c1_max", "c2_after",
    # run
    "sample_s", "jitter", "seed",
)  # fmt: skip

PlantParams = namedtuple("PlantParams", NAMES)


def pack(values: Mapping[str, float]) -> PlantParams:
    """The record of ``values`` (every name of :data:`NAMES`, nothing else), as floats."""
    missing = [n for n in NAMES if n not in values]
    unknown = [n for n in values if n not in NAMES]
    if missing or unknown:
        raise KeyError(f"plant parameters: missing {missing}, unknown {unknown}")
    return PlantParams(*(float(values[n]) for n in NAMES))
