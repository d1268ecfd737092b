"""An instrument fault is floored where its instrument can show nothing lower
(``reading_min``), through a real server: the register serves the floor, the journal says
what the fault asked for, and a reading above the floor is left as the fault made it."""

from __future__ import annotations

import pytest

from rig_emulator.faults import faults_from_list, read_journal
from rig_emulator.registers import encode
from tests.modbus_helpers import ADVANCE, point
from tests.rig_emulator.modbus.raw import ask, read_pdu, registers_of, write_registers_pdu

VELOCITY = "flue_gas_velocity_m_s"
SIM = 100
#: A seed whose vortex meter reads the idle boiler's draught (0.18 m/s) at about 0.01 m/s
#: (:data:`tests.rig_emulator.instruments.test_reading_floor.SEED_LOW_VORTEX`)
SEED_LOW_VORTEX = 145
#: The int16 velocity register's step [m/s] (the map: 0.001 m/s), the tolerance of a
#: reading compared through it
REGISTER_STEP = 0.001


def _velocity(srv) -> float:
    """The vortex meter's register, as served [m/s]."""
    device, velocity = point(srv, "flue_gas_probe", "velocity")
    reply = ask(srv.port, device.unit_id, read_pdu(4, velocity.address, 1))
    (raw,) = registers_of(reply)
    return (raw - 65536 if raw > 32767 else raw) * velocity.scale


@pytest.mark.parametrize(("offset", "floored"), [(-1.0, True), (0.5, False)])
def test_an_offset_fault_reads_no_lower_than_the_instruments_floor(
    serve, tmp_path, offset, floored
):
    """A stranger's probe: an offset of -1 m/s on the ``lab`` profile's vortex meter, which
    reads no velocity below 0 (it counts a frequency), served -0.99 m/s. The instrument's
    floor holds with the fault as without it: the register reads 0 m/s, and the journal's
    start line still says what the fault asked for (``asked``, beside the ``reading``
    served). An offset upwards serves the fault's reading unchanged, with no ``asked``."""
    journal = tmp_path / "journal.jsonl"
    fault = {"kind": "offset", "signal": VELOCITY, "value": offset, "at_s": 2, "for_s": 5}
    srv = serve(
        profile="lab",
        seed=SEED_LOW_VORTEX,
        faults=faults_from_list([fault]),
        fault_log=journal,
    )
    _, advance = point(srv, *ADVANCE)
    ask(srv.port, SIM, write_registers_pdu(advance.address, encode(advance, 1)))
    before = _velocity(srv)  # the instrument's own reading, just above its floor
    assert 0.0 <= before < 0.1
    ask(srv.port, SIM, write_registers_pdu(advance.address, encode(advance, 1)))
    reading = _velocity(srv)
    start = next(e for e in read_journal(journal) if e["event"] == "start")
    served = start["served"]
    assert served["reading"] == pytest.approx(reading, abs=REGISTER_STEP)
    asked = served["instrument"] + offset
    if floored:
        assert reading == 0.0 and asked < 0.0
        assert served["asked"] == pytest.approx(asked, abs=REGISTER_STEP)
    else:
        assert reading == pytest.approx(asked, abs=REGISTER_STEP)
        assert "asked" not in served
    assert srv.server.truth(VELOCITY) > 0.1  # the plant's draught, untouched
