"""A number refused for its range is shown as given, every digit: ``:g`` printed an at_s of
1000000001 as 1e+09, which looked within its bound of 1e+09 (a stranger's probe)."""

from __future__ import annotations

import numpy as np
import pytest

from rig_emulator.faults import FaultError, check_spikes, faults_from_list
from rig_emulator.faults.spec import ReadingRange


@pytest.mark.parametrize(
    ("fault", "shown"),
    [
        ({"at_s": 1000000001}, "faults[0].at_s: 1000000001 must be finite, >= 0"),
        ({"for_s": 1000000000.4}, "faults[0].for_s: 1000000000.4 must be finite, > 0"),
        ({"at_s": np.int64(1000000001)}, "faults[0].at_s: 1000000001 must be"),
        ({"at_s": 1e9 + 0.5}, "faults[0].at_s: 1000000000.5 must be"),
    ],
)
def test_a_number_out_of_range_is_shown_as_given(fault, shown):
    with pytest.raises(FaultError) as err:
        faults_from_list([{"kind": "no_reply", "unit": 1, **fault}], "f.yaml")
    assert str(err.value).startswith(f"f.yaml: {shown}"), str(err.value)


def test_a_delay_just_over_its_bound_is_shown_as_given():
    with pytest.raises(FaultError, match=r"delay_ms: 600000\.001 must be finite, > 0 and <= 6"):
        faults_from_list([{"kind": "delay", "unit": 1, "delay_ms": 600000.001}], "f.yaml")


def test_a_spike_just_outside_its_register_is_shown_as_given():
    """327.6751 is past 327.67 and half a step (0.005) but printed as 327.675 by ``:g``."""
    spike = faults_from_list([{"kind": "spike", "signal": "flue_gas_temp_C", "value": 327.6751}])
    ranges = {"flue_gas_temp_C": ReadingRange(-327.67, 327.67, "unit 2 flue_temp", 0.01)}
    with pytest.raises(FaultError, match=r"fault.value: 327\.6751 is outside"):
        check_spikes(spike, ranges, "fault")
