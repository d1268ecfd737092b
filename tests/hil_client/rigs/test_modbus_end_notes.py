"""What a run's end tells of instruments that failed (:meth:`ModbusRig.end_notes`), over
real sockets to a lockstep server with faults."""

from __future__ import annotations

import math

from hil_client.fault_files import unit_signals
from hil_client.protocol.rig import RigCommand
from hil_client.rigs.modbus import ModbusRig
from rig_emulator.faults import faults_from_list
from rig_emulator.registers import load_map

STEPS = 8


def _steps(port: int) -> ModbusRig:
    rig = ModbusRig(f"modbus://127.0.0.1:{port}", load_map(), timeout_s=0.3)
    for _ in range(STEPS):
        rig.apply(RigCommand(500.0, 40.0, pump_on=True, boiler_on=False))
        rig.advance(1.0)
    return rig


def test_a_unit_silent_all_run_and_one_silent_from_a_time_on_are_told(serve):
    """A stranger's probe: an analyser that never answered (a required column empty in
    every row) and one that stopped answering a minute in left a run that ended exit 0
    with no word on either; only the events file said why. A unit refusing every read was
    already told; silent units are now, and a unit that answered a while and then not
    says in how many rows and from when."""
    units = unit_signals(load_map())
    analyser = next(u for u, s in units.items() if "flue_gas_O2_pct" in s)
    balance = next(u for u, s in units.items() if "balance_mass_kg" in s)
    faults = [
        {"kind": "no_reply", "unit": analyser, "at_s": 0},
        {"kind": "exception", "unit": balance, "code": 6, "at_s": 4.5, "for_s": 2},
    ]
    srv = serve(faults=faults_from_list(faults))
    rig = _steps(srv.port)
    rig.close()
    notes = rig.end_notes()
    assert rig.rows_stepped == STEPS
    # (pipelined: the replies after its request came first, so no reply is known at once)
    silent = f"unit {analyser} never answered a read of this run (no reply (a later one came"
    assert any(n.startswith(silent) and "): flue_gas_O2_pct" in n for n in notes), notes
    assert any(n.endswith("never read, empty in every row") for n in notes), notes
    # the exception fault at 4.5-6.5 s: the rows of 5 and 6 s
    busy = next(n for n in notes if n.startswith(f"unit {balance} gave no reading"))
    assert busy == (
        f"unit {balance} gave no reading of balance_mass_kg in 2 of {STEPS} rows (from "
        "time_s = 5 to 6 s: exception 06): empty there"
    ), busy
    assert len(notes) == 2, notes
    assert math.isnan(rig.read()["flue_gas_O2_pct"])


def test_a_clean_run_ends_without_a_word(serve):
    rig = _steps(serve().port)
    rig.close()
    assert rig.end_notes() == [] and rig.rows_stepped == STEPS
