"""What the journal says a floored instrument fault asked for (``asked`` on a start line),
through a real server: on the register's steps, as the ``reading`` beside it."""

from __future__ import annotations

import pytest

from rig_emulator.faults import faults_from_list, read_journal
from rig_emulator.registers import encode
from tests.modbus_helpers import ADVANCE, point
from tests.rig_emulator.instruments.test_fault_floor import REGISTER_STEP, SEED_LOW_VORTEX, VELOCITY
from tests.rig_emulator.modbus.raw import ask, write_registers_pdu

SIM = 100
#: An offset off the register's 0.001-m/s steps, down past the vortex meter's floor of 0
#: (the meter reads the idle boiler's draught at about 0.01 m/s with this seed) [m/s]
OFFSET_OFF_STEPS = -1.0004


def test_what_a_floored_fault_asked_for_is_journalled_on_the_registers_steps(serve, tmp_path):
    """A re-probe: an offset and then a ``stuck`` fault on the ``lab`` profile's vortex
    meter, floored at 0 m/s: the stuck fault's start line said ``asked:
    -0.9299999999999999``, the offset's result unrounded, beside a ``reading`` on the
    register's steps. What each fault asked for is on those steps too, here for an offset
    that is not."""
    journal = tmp_path / "journal.jsonl"
    faults = faults_from_list(
        [
            {"kind": "offset", "signal": VELOCITY, "value": OFFSET_OFF_STEPS, "at_s": 1},
            {"kind": "stuck", "signal": VELOCITY, "at_s": 2},
        ]
    )
    srv = serve(profile="lab", seed=SEED_LOW_VORTEX, faults=faults, fault_log=journal)
    _, advance = point(srv, *ADVANCE)
    for _ in range(2):
        ask(srv.port, SIM, write_registers_pdu(advance.address, encode(advance, 1)))
    starts = {e["kind"]: e["served"] for e in read_journal(journal) if e["event"] == "start"}
    for kind in ("offset", "stuck"):
        served = starts[kind]
        assert served["reading"] == 0.0  # floored
        asked = served["asked"]
        assert asked == round(asked, 3)  # on the register's steps
        # what the offset asked of the instrument's reading then (for the stuck fault: of
        # the one it held, the offset in it), to within the rounding onto a step
        assert -1.0 < asked < 0.0
    assert starts["offset"]["asked"] == pytest.approx(
        starts["offset"]["instrument"] + OFFSET_OFF_STEPS, abs=REGISTER_STEP / 2
    )
