"""``body_heat_diffusion``: the body as two lumps, the metal (the documented Ctherm) heated
by the flame and giving its heat to the water through a conductance (time constant
C_metal / G); after a stop the hot metal keeps warming the water, which the one node cannot
do.
"""

from __future__ import annotations

import numpy as np

from hil_client.analysis.augment import first_order_lag, two_lump_water
from hil_client.analysis.candidates.base import CurveCandidate, carried_share
from hil_client.analysis.candidates.windows import (
    LOW_FLOW_SHARE,
    PRE_STOP_S,
    SUB_BLOCK_S,
    stop_blocks_from_burn,
    stop_ends,
    test_flow_kg_h,
)
from hil_client.analysis.replay import Case

#: What stored heat must show after stops [K], beyond what a real boiler's background
#: reaches without it: the water rising above the model's, from the steady burn before the
#: stop, by 2 K, the middle of Table 4's 1-3 K test-phase RMSD (a controller modulating down
#: before its cut-out, the bed burning out, the sensor's well and stratification move it by
#: 1-2 K without any body).
BODY_STORED_MIN_K = 2.0


def body_water(case: Case, tau_body_s: float) -> np.ndarray:
    """The water of a two-lump body (metal: the documented Ctherm) driven by the replayed
    model's heat to the exchanger; ``tau_body_s`` = C_metal / G."""
    p = case.params
    c_metal = p.c_therm_kJ_K
    ua = np.where(case.firing.burning, p.ua_amb_on_W_K, p.ua_amb_off_W_K) / 1000.0
    return two_lump_water(
        case.model["q_hx_kW"] + case.model["q_el_ign_kW"],
        case.flow,
        case.t_in,
        case.room,
        ua,
        case.dt,
        float(case.model["t_boiler_C"][0]),
        c_metal,
        p.capacity_kJ_K - c_metal,
        c_metal / tau_body_s,
    )


def _body_predict(case: Case, theta: dict[str, float] | None) -> np.ndarray:
    # the base: the same two lumps tied by a 1-s conductance, i.e. the one node
    water = body_water(case, theta["tau_body_s"] if theta else 1.0)
    return first_order_lag(water, case.dt, case.sensor_tau_s["boiler_water_temp_C"])


def _warming_after_stops(case: Case, blocks: list, r: np.ndarray) -> dict[int, float]:
    """Per stop (its anchor row): the peak of the residual ``r`` within the first 15 min
    above the mismatch carried into the stop (its mean over :data:`PRE_STOP_S` before,
    decaying as :func:`carried_share` says)."""
    t = case.t
    peaks = {}
    for anchor, end in stop_ends(blocks).items():
        ref = r[int(np.searchsorted(t, t[anchor] - PRE_STOP_S)) : anchor]
        first = np.arange(anchor, min(int(np.searchsorted(t, t[anchor] + 3 * SUB_BLOCK_S)), end))
        ok = np.isfinite(r[first])
        if len(ref) and ok.any() and np.isfinite(ref).any():
            carried = float(np.nanmean(ref)) * carried_share(case, anchor)[first[ok]]
            peaks[anchor] = float(np.max(r[first[ok]] - carried))
    return peaks


def _forward_residual(case: Case) -> np.ndarray:
    """The forward temperature less the one-node model's (as :data:`BODY` reads the
    boiler water: its forward sensor's lag, less the mean on the settled rows)."""
    water = body_water(case, 1.0)
    r = case.lab["water_out_temp_C"] - first_order_lag(
        water, case.dt, case.sensor_tau_s["water_out_temp_C"]
    )
    return r - float(np.mean(r[case.settled]))


def _body_fingerprint(case: Case, blocks: list, r: np.ndarray) -> tuple[float, str]:
    """Stored heat: after the flame goes out the metal still heats the water, so the water
    runs warmer than the model's within the first 15 min, where a body of 1-7 min shows,
    than it did in the steady burn before the stop (by :data:`BODY_STORED_MIN_K` at least
    at its peak, in the median stop); water that cools faster than the model's is a
    mismatch of level or of losses, not a body. The heat is the water's, so the forward
    sensor, which the flow passes from the same water, shows it too: a stop after which
    the water keeps flowing reads the lesser warming of the two (a slow boiler-water probe
    that keeps rising after the stop while it catches up with the water is not a body, and
    the forward does not show it); at low flow the forward reads the exit pipe, not the
    water, and the boiler water's warming stands alone."""
    return _body_mark(case, blocks, r, _forward_residual(case))


def _body_mark(
    case: Case, blocks: list, r_water: np.ndarray, r_forward: np.ndarray
) -> tuple[float, str]:
    """:func:`_body_fingerprint` from the boiler water's and the forward's residuals."""
    water = _warming_after_stops(case, blocks, r_water)
    forward = _warming_after_stops(case, blocks, r_forward)
    t, low = case.t, LOW_FLOW_SHARE * test_flow_kg_h(case)

    def flowing(anchor: int) -> bool:  # the forward reads the water only while it flows
        first = slice(anchor, int(np.searchsorted(t, t[anchor] + 3 * SUB_BLOCK_S)))
        return bool(np.all(case.flow[first] >= low))

    peaks = [min(w, forward[a]) if a in forward and flowing(a) else w for a, w in water.items()]
    if not peaks:
        return 0.0, "no stop to read the water's warming from"
    peak = float(np.median(peaks))
    return (
        peak / BODY_STORED_MIN_K,
        f"water not warmer than the model's after stops ({peak:+.2f} K, the lesser of the"
        " boiler water and the forward)",
    )


BODY = CurveCandidate(
    "body_heat_diffusion",
    "boiler_water_temp_C",
    "after_stops",
    # time constants below 20 s are the sensors' own, not the body's
    {"tau_body_s": np.geomspace(20.0, 3000.0, 16)},
    _body_predict,
    stop_blocks_from_burn,
    nuisance_drift=False,
    anchor_s=PRE_STOP_S,
    fingerprint=_body_fingerprint,
)
