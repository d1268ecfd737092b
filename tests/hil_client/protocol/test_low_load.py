"""The 13 % step of the clean 12 kW load cycle against Fig. 7 (Carlon et al. 2015, 3.2.2)."""

import math

import pytest

from hil_client.protocol.definition import load_protocol
from hil_client.protocol.low_load import (
    PAPER_FIRST_COOLING_MIN,
    PAPER_T_AT_T2_C,
    low_load_sequence,
)
from hil_client.protocol.runner import run_protocol
from hil_client.rigs.local import LocalRig
from rig_emulator.boilers import load_boiler
from rig_emulator.instruments import load_profile


@pytest.fixture(scope="module")
def sequence_12kw():
    """The clean 12 kW load cycle played offline (about 1 s) and its 13 % step."""
    params = load_boiler("windhager_12kw")
    rows: list = []
    rig = LocalRig(params, load_profile("clean"))
    result = run_protocol(load_protocol("load_cycle"), params.p_nom_kW, rig, rows.append)
    assert result.notes == []  # every phase rule was met
    return low_load_sequence(rows, result.times), params


def test_two_cutouts_a_restart_and_a_second_stop(sequence_12kw):
    """Section 3.2.2: 85 C, stop; back at 55 C "after 1.5 h"; restart with the maximum power
    output through the start-up; 85 C again and a second stop; still off at t2."""
    seq, params = sequence_12kw
    assert len(seq.stops_s) == 2
    # the controller decides on the water temperature at the start of the step
    assert all(t >= params.shutoff_temp_C for t in seq.stop_temps_C)
    assert len(seq.starts_s) == 1 and seq.stops_s[0] < seq.starts_s[0] < seq.stops_s[1]
    # "about 1.5 h": the 1-2 h band (measured 1.84 h: our return is held at 55 C, so
    # the water approaches 55 C from above asymptotically; see docs/model.md)
    assert 1.0 <= seq.cool_back_h <= 2.0
    # the restart's start-up at Pstart lasts startup_duration_s unless 85 C ends it; here
    # it does: the second stop comes within the start-up time after the restart
    assert seq.stops_s[1] - seq.starts_s[0] <= params.startup_duration_s
    # at t2 the boiler is cooling after the second stop (the paper's 57 C lies there too)
    assert params.restart_temp_C < seq.t_boiler_at_t2_C < params.shutoff_temp_C
    assert not math.isnan(seq.first_cooling_min) and seq.first_cooling_min > 0


@pytest.mark.xfail(
    strict=True,
    reason="known gap, docs/model.md 'Fig. 7': the second stop comes 0.6-0.7 h later than "
    "the paper's, so at t2 the water is at 69.8 C (paper 57 C) and the first cooling takes "
    "67 min (paper about 5 min)",
)
def test_t2_temperature_and_first_cooling_match_the_paper(sequence_12kw):
    """Section 3.2.2: 57 C inside the boiler at t2; the first cooling 57 -> 55 C took
    "approximately five minutes"."""
    seq, _ = sequence_12kw
    # tolerance: the paper's own Type 869 simulation of this test stayed within 4.39 K of
    # the lab's boiler-water temperature over the test sequence (Table 4, 12 kW cycle)
    assert seq.t_boiler_at_t2_C == pytest.approx(PAPER_T_AT_T2_C, abs=4.39)
    # "approximately five minutes" read as up to twice that
    assert seq.first_cooling_min == pytest.approx(PAPER_FIRST_COOLING_MIN, abs=5.0)
