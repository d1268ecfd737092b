"""The fixture's ``write`` of a switch (a coil) takes 0 or 1, False or True, and refuses
anything else before sending, on a real server: a stranger's probe found 2, 0.5 and -1 sent
as on or off and NaN as off (the server refuses such values with 03), ``"off"`` a
TypeError."""

from __future__ import annotations

import pytest

BAD = (2, -1, 0.5, float("nan"), float("inf"), "off", "0", None)


def test_a_switch_takes_0_1_false_true_and_refuses_the_rest(tmp_path):
    import numpy as np

    from rig_emulator.pytest_plugin import RigEmulator

    with RigEmulator(workdir=tmp_path) as rig:
        for on, off in ((1, 0), (True, False), (1.0, 0.0), (np.int64(1), np.bool_(False))):
            rig.write("boiler_command", on)
            assert rig.read("boiler_command") == 1.0
            rig.write("boiler_command", off)
            assert rig.read("boiler_command") == 0.0
        for before in (0, 1):
            rig.write("boiler_command", before)
            for bad in BAD:
                with pytest.raises(ValueError) as err:
                    rig.write("boiler_command", bad)
                assert str(err.value) == (
                    f"write('boiler_command', {bad!r}): boiler_command is a switch (a coil):"
                    " expected 0 or 1, False or True"
                )
                assert rig.read("boiler_command") == before, bad  # nothing was sent


def test_a_register_command_refuses_what_is_no_number(tmp_path):
    from rig_emulator.pytest_plugin import RigEmulator

    with RigEmulator(workdir=tmp_path) as rig:
        rig.write("water_flow_setpoint_kg_h", 700.0)
        for bad in ("700", None, [700.0]):
            with pytest.raises(ValueError, match=r"water_flow_setpoint_kg_h.*expected a number"):
                rig.write("water_flow_setpoint_kg_h", bad)
        assert rig.read("water_flow_setpoint_kg_h") == 700.0


def test_a_reading_or_a_status_is_no_command_and_nothing_is_sent(tmp_path):
    """A stranger's probe: ``write("water_flow_kg_h", 700)`` sent FC16 to the reading's
    address in the holding table, where the flow setpoint sits: the setpoint became 700
    and the measured flow followed, without a word; ``water_in_temp_C`` and ``boiler_on``
    set the return setpoint and the boiler's set temperature the same way."""
    from rig_emulator.pytest_plugin import RigEmulator

    with RigEmulator(workdir=tmp_path) as rig:
        commands = ("water_flow_setpoint_kg_h", "return_setpoint_C", "boiler_set_temp_C")
        before = {name: rig.read(name) for name in commands}
        for reading in ("water_flow_kg_h", "water_in_temp_C", "boiler_on", "sim_time_s"):
            with pytest.raises(ValueError, match=rf"write\('{reading}', \.\.\.\): {reading} is no"):
                rig.write(reading, 600)
        assert {name: rig.read(name) for name in commands} == before  # nothing was sent
        with pytest.raises(ValueError, match=r"read\('nope'\): no point of the register map"):
            rig.read("nope")
        with pytest.raises(ValueError, match=r"write\('nope'\): no point"):
            rig.write("nope", 1)


def test_a_refusal_names_the_exception_and_a_bad_timeout_is_named(tmp_path):
    """Stranger's probes: a refused write said "ExceptionResponse(dev_id=1,
    function_code=144, exception_code=4)"; ``reply_timeout_s = -1`` gave pymodbus's
    "Timeout value out of range", naming nothing."""
    from decimal import Decimal
    from fractions import Fraction

    import numpy as np

    from rig_emulator.pytest_plugin import RigEmulator, RigEmulatorError

    with RigEmulator(workdir=tmp_path) as rig:
        # a setpoint beyond what its point accepts: the server's 03
        with pytest.raises(RigEmulatorError, match=r"refused: exception 03 \(illegal data value\)"):
            rig.write("water_flow_setpoint_kg_h", 1e9)
        # (1e12 was an OverflowError of the socket library: a re-probe)
        bad_ones = (-1, 0, "abc", float("nan"), True, float("inf"), 1e12, 10**400)
        for bad in (*bad_ones, Decimal("sNaN"), Decimal("-1")):
            rig.reply_timeout_s = bad
            with pytest.raises(ValueError, match=r"reply_timeout_s = .*: expected a number"):
                rig.read("sim_time_s")
        # numpy's float32 and a Fraction were a TypeError in the socket library (a re-probe)
        # (a Decimal was "not a number of seconds": a stranger's probe)
        for good in (2.0, np.float32(2.0), Fraction(1, 2), Decimal("5")):
            rig.reply_timeout_s = good
            assert rig.read("sim_time_s") == 0.0
        with pytest.raises(ValueError) as err:
            rig.write("water_flow_kg_hh", 1)
        assert "water_flow_setpoint_kg_h" in str(err.value)  # the commands, not the readings
        assert "water_flow_kg_h," not in str(err.value) and "true_" not in str(err.value)
