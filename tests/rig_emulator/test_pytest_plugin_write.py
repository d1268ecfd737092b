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
