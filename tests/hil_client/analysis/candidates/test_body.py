"""Single rules of the body candidate (hil_client.analysis.candidates.body): a mismatch the
flow washes out after a stop, or warming the forward does not share, is not a body."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from hil_client.analysis.candidates.body import _body_mark
from rig_emulator.boilers import load_boiler
from rig_emulator.model import constants as k


def test_a_mismatch_the_flow_washes_out_after_a_stop_is_no_body():
    """Lab water 5 K colder than the model's in the burn before a stop (a level mismatch)
    decays after it as the flow and the losses exchange both waters with the same return:
    exp(-(m_w cp_w + UA) t / C), here with a 20-min time constant, in the bench's 20-35
    min. Read against a constant pre-stop offset it would seem to warm by 5 (1 - e^-0.75)
    = 2.6 K in the first 15 min, above the 2-K mark of a body; read against the carried
    share it does not warm at all. A body's own hump of about 3 K on top of it still
    shows."""
    params = load_boiler("windhager_6kw")
    tau_s = 1200.0
    ua_kW_K = params.ua_amb_off_W_K / 1000.0
    flow_kg_h = (params.capacity_kJ_K / tau_s - ua_kW_K) * 3600.0 / k.CP_WATER
    t = np.arange(0.0, 3600.0, 10.0)
    stop = 180
    case = SimpleNamespace(
        t=t,
        dt=np.full(len(t), 10.0),
        flow=np.full(len(t), flow_kg_h),
        firing=SimpleNamespace(burning=np.arange(len(t)) < stop),
        phases=SimpleNamespace(mask=lambda name, t: np.arange(len(t)) < stop),
        params=params,
        memo=lambda key, compute: compute(),
    )
    after = np.clip(t - t[stop], 0.0, None)
    # while burning the loss is UA_on: the decay begins at the stop, so only UA_off counts
    washed = -5.0 * np.exp(-after / tau_s)
    blocks = [("stop", np.arange(stop, len(t)), stop)]
    mark, why = _body_mark(case, blocks, washed, washed)
    assert mark < 0.05, why  # 0.05: the rounding of the exponentials, nothing more
    hump = 6.0 * (np.exp(-after / 400.0) - np.exp(-after / 100.0))  # peaks at 2.8 K
    mark, _ = _body_mark(case, blocks, washed + hump, washed + hump)
    assert mark > 1.0


def test_warming_the_forward_does_not_share_is_the_probe_not_the_body():
    """The body's heat is the water's, so the forward sensor, in the same water, shows its
    warming after a stop as the boiler-water probe does. A probe in a slow sleeve (90 s)
    reads 3 K low while the water of the 12-kW boiler rises at 2 K/min (a start at low
    flow, 150 kg/h), and after the stop it catches up: read alone, over 2 K of warming,
    the body's mark; the fast forward sensor (5 s) lags by a quarter of a kelvin and shows
    none of it. The same 2.8-K hump in both is a body."""
    t = np.arange(0.0, 3600.0, 10.0)
    stop = 180
    case = SimpleNamespace(
        t=t,
        dt=np.full(len(t), 10.0),
        flow=np.full(len(t), 150.0),
        firing=SimpleNamespace(burning=np.arange(len(t)) < stop),
        phases=SimpleNamespace(mask=lambda name, t: np.arange(len(t)) < stop),
        params=load_boiler("windhager_12kw"),
        memo=lambda key, compute: compute(),
    )
    blocks = [("stop", np.arange(stop, len(t)), stop)]
    after = np.clip(t - t[stop], 0.0, None)
    slow_probe = -3.0 * np.exp(-after / 90.0)
    forward = -0.25 * np.exp(-after / 5.0)
    alone, _ = _body_mark(case, blocks, slow_probe, slow_probe)
    assert alone > 1.0  # what reading the boiler water alone would name
    mark, why = _body_mark(case, blocks, slow_probe, forward)
    assert mark < 0.5, why
    hump = 6.0 * (np.exp(-after / 400.0) - np.exp(-after / 100.0))
    assert _body_mark(case, blocks, hump, hump + 0.1)[0] > 1.0
    # the circulation stops with the burner: the forward sensor sits in still water in the
    # exit pipe, cooling toward the room, and says nothing of the boiler water's warming
    case.flow = np.where(np.arange(len(t)) < stop, 150.0, 0.0)
    pipe_cooling = -0.5 * after / 60.0
    assert _body_mark(case, blocks, hump, pipe_cooling)[0] > 1.0
