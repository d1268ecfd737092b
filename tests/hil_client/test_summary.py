"""The run's summary table: per-phase totals as the rows come."""

from __future__ import annotations

import math

import pytest

from hil_client.protocol.runner import LOG_COLUMNS
from hil_client.summary import RunSummary


def _row(t: float, phase: str, mass: float, epoch: int = 0) -> tuple:
    values = dict.fromkeys(LOG_COLUMNS, 0.0)
    values.update(time_s=t, phase=phase, balance_mass_kg=mass, water_flow_kg_h=600.0)
    values.update(rig_epoch=epoch)
    values.update(water_in_temp_C=55.0, water_out_temp_C=70.0, boiler_water_temp_C=70.0)
    return tuple(values[name] for name in LOG_COLUMNS)


def test_a_refill_is_taken_out_of_the_fuel_and_a_missing_reading_skipped():
    """A +15 kg refill in the test (the README's offset fault): the summary printed -13 kg
    where balance gave 2 kg. A row without a reading (NaN) changes nothing."""
    summary = RunSummary()
    masses = [250.0, 249.5, 249.0, math.nan, 263.5, 263.0, 262.5]  # +15 kg between 3 and 4
    for i, mass in enumerate(masses):
        summary(_row(float(i + 1), "test", mass))
    # 0.5 kg per row read; across the refill only the rise is known (14.5 kg from 249.0):
    # the fuel burnt while the reading was missing is inside it, as in the balance command
    assert summary.phases["test"].fuel_kg == pytest.approx(2.0)
    assert summary.median_interval_s == 1.0


def test_a_missing_reading_at_a_phase_boundary_costs_neither_phase_its_fuel():
    """A dropout of the balance on a phase's last row made that phase's fuel, and the next
    one's, NaN (a reviewer's finding)."""
    summary = RunSummary()
    for i, (phase, mass) in enumerate(
        [("start_up", 250.0), ("start_up", 249.8), ("start_up", math.nan), ("test", 249.4),
         ("test", 249.2)]
    ):  # fmt: skip
        summary(_row(float(i + 1), phase, mass))
    assert summary.phases["start_up"].fuel_kg == pytest.approx(0.2)
    assert summary.phases["test"].fuel_kg == pytest.approx(0.6)  # from 249.8, the last read


def test_a_phase_the_balance_never_read_has_unknown_fuel_not_zero():
    summary = RunSummary()
    for i, (phase, mass) in enumerate(
        [("start_up", 250.0), ("test", math.nan), ("test", math.nan), ("cooling_1", 249.0)]
    ):
        summary(_row(float(i + 1), phase, mass))
    assert math.isnan(summary.phases["test"].fuel_kg)
    line = next(x for x in summary.table().splitlines() if x.startswith("test"))
    assert " - " in line and "0.00 kg" not in line


def test_a_phase_across_a_break_is_said_to_join_two_plants():
    """--on-restart continue: the test's totals were summed across a restarted server's
    two plants without a word (a stranger's probe)."""
    summary = RunSummary()
    for i, (phase, epoch) in enumerate([("start_up", 0), ("test", 0), ("test", 1), ("test", 1)]):
        summary(_row(float(i + 1), phase, 250.0 - i, epoch))
    notes = [line for line in summary.table().splitlines() if line.startswith("note:")]
    assert notes == [
        "note: test spans a break of the record (rig_epoch 0..1): its totals join two plants;"
        " hil-client balance reads one"
    ]


def test_a_balance_read_below_zero_is_noted_when_it_first_does():
    """A rig whose plant has no refills (another server than this emulator, whose hopper is
    topped up) can burn its balance below 0 kg: the run notes when it first did."""
    summary = RunSummary()
    for i, mass in enumerate([0.4, 0.2, 0.0, -0.2, -0.4]):
        summary(_row(float(i + 1), "test", mass))
    assert summary.empty_at_s == 4.0
