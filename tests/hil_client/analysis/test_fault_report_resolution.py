"""The log detectors on still and quantised columns: a stranger's probe found a spike and an
offset missed where the column was otherwise constant (a clean lockstep run's O2 stands at
6.25515 for hours), while the same fault on a slightly noisy column was found."""

from __future__ import annotations

import numpy as np

from hil_client.analysis.fault_report import compare
from tests.hil_client.analysis.test_fault_report import _journal


def _found(columns: dict[str, np.ndarray], *faults: dict) -> dict[tuple[str, str], bool]:
    t = np.arange(float(next(iter(columns.values())).size))
    report = compare(_journal(*faults), [], columns, t)
    return {(r["kind"], r["signal"]): r["detected"] for r in report["faults"]}


def _fault(kind: str, signal: str, start: float, end: float | None = None) -> dict:
    return {"start": start, "end": end, "what": {"kind": kind, "signal": signal}}


def test_a_spike_and_an_offset_on_a_still_column_are_found():
    """The repro: O2 6.0 with one row at 25.0; water_out_temp_C stepping 70 -> 73 for good.
    The floor of the detectors' scale was the smallest nonzero step, on a still column the
    fault's own (19, then 3): 8 times it was never reached."""
    o2 = np.full(601, 6.0)
    o2[300] = 25.0
    water = np.where(np.arange(601) >= 300, 73.0, 70.0)
    still = np.full(601, 22.0)  # a spike fault with nothing logged: not found
    found = _found(
        {"O2": o2, "water": water, "room": still},
        _fault("spike", "O2", 300.0, 301.0),
        _fault("offset", "water", 300.0),
        _fault("spike", "room", 300.0, 301.0),
    )
    assert found == {("spike", "O2"): True, ("offset", "water"): True, ("spike", "room"): False}
    # a noisy column (readings with all their digits: no resolution) is judged by its
    # noise as before: a spike of 3 noise widths is no spike, one of 40 is
    rng = np.random.default_rng(0)
    noisy = 6.0 + rng.normal(0, 0.01, 601)  # sigma 0.01; 1 % of the level: 0.06
    small, big = noisy.copy(), noisy.copy()
    small[300] += 0.03
    big[300] += 0.4
    found = _found(
        {"small": small, "big": big},
        _fault("spike", "small", 300.0, 301.0),
        _fault("spike", "big", 300.0, 301.0),
    )
    assert found == {("spike", "small"): False, ("spike", "big"): True}


def test_a_quantised_column_flickering_by_its_resolution_shows_no_spike_or_offset():
    """A still reading rounding now and then to the next step of its resolution (0.1 K at
    level 0.5, where 1 % of the level is less than one step) is no spike and no offset: the
    floor is two steps. Three steps are a fault (the floor was the smallest step's 8)."""
    rng = np.random.default_rng(3)
    x = np.where(rng.random(400) < 0.1, 0.6, 0.5)  # still on most rows: the scale is 0
    x[195:206] = 0.5
    flickered = x.copy()
    flickered[200] = 0.6  # one step, in the spike's window
    spiked = x.copy()
    spiked[200] = 0.8
    shifted = x.copy()
    shifted[200:] += 0.3
    columns = {"flickered": flickered, "spiked": spiked, "shifted": shifted, "still": x}
    found = _found(
        columns,
        _fault("spike", "flickered", 200.0, 201.0),
        _fault("offset", "still", 200.0),
        _fault("spike", "spiked", 200.0, 201.0),
        _fault("offset", "shifted", 200.0),
    )
    assert found == {
        ("spike", "flickered"): False,
        ("offset", "still"): False,
        ("spike", "spiked"): True,
        ("offset", "shifted"): True,
    }


def test_the_resolution_is_read_from_the_logged_decimals():
    """As ``run`` writes a reading (5 decimals) off a register of 0.01, parsed back from
    text: 0.01; a column of whole numbers: 1; readings with all their digits: none."""
    from hil_client.analysis.fault_report import _resolution

    logged = np.array([float(f"{v:.5f}") for v in (20.95, 6.25, 687.35, 1e4 + 0.01)])
    assert _resolution(logged) == 0.01
    assert _resolution(np.array([float(f"{v:.5f}") for v in (6.25515, 6.25516)])) == 1e-5
    assert _resolution(np.array([70.0, 73.0, np.nan])) == 1.0
    assert _resolution(np.array([1 / 3, 2 / 7])) == 0.0


def test_a_column_that_moves_in_steps_is_judged_by_its_steps():
    """A re-probe: relative humidity logged in 0.1 % steps and updated on one row in ten
    (its median first difference 0) had its ordinary 0.3-0.6 % steps taken for offsets
    where the journal named one (31 of 31 windows where nothing was served). Its noise is
    now the size of its own steps; a real 15 % offset is still found, and a spike on a
    still column is not measured by its own jump."""
    rng = np.random.default_rng(7)
    n = 3000
    steps = np.where(rng.random(n) < 0.1, rng.choice([-0.6, -0.3, 0.3, 0.6], n), 0.0)
    rh = np.round(45.0 + np.cumsum(steps), 1)
    shifted = rh.copy()
    shifted[2000:] += 15.0
    t = np.arange(float(n))
    faults = [_fault("offset", "rh", float(s), float(s) + 20.0) for s in range(100, 1900, 100)]
    report = compare(_journal(*faults), [], {"rh": rh}, t)
    assert not any(r["detected"] for r in report["faults"]), report["faults"]
    assert _found({"rh": shifted}, _fault("offset", "rh", 2000.0, 2020.0))[("offset", "rh")]
