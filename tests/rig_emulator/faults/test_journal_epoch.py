"""The fault journal names the server start it is of, and keeps count of the lines it lost.

A stranger's probe: a server killed and restarted under a run wrote a second journal that
the fault report matched with the first plant's rows by time alone (neither journal said
which start it was); and ``serve --fault-log /dev/full`` lost every line yet exited 0."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rig_emulator.boilers import load_boiler
from rig_emulator.emulator import Emulator
from rig_emulator.faults import FaultJournal, faults_from_list, read_journal
from rig_emulator.instruments import load_profile
from rig_emulator.modbus.fault_control import ServerFaults
from rig_emulator.registers import encode, load_map


def test_every_line_carries_the_servers_epoch_id_in_hex(tmp_path):
    path = tmp_path / "j.jsonl"
    emulator = Emulator(load_boiler("windhager_12kw"), load_profile("clean"), 0)
    faults = faults_from_list([{"kind": "offset", "signal": "room_temp_C", "value": 1.0}])
    server = ServerFaults(emulator, load_map(), faults, path, epoch_id=0x0BADF00D)
    server.begin_journal()
    emulator.values()  # the readings evaluated: the fault starts
    server.inject({"kind": "no_reply", "unit": 2, "for_s": 1})
    emulator.advance(5.0)
    emulator.values()  # ... and the no_reply ends
    server.close()
    lines = read_journal(path)
    assert [(e["event"], e["kind"]) for e in lines] == [
        ("start", "offset"),
        ("start", "no_reply"),
        ("end", "no_reply"),
    ]
    assert {e.get("epoch_id") for e in lines} == {"0badf00d"}
    # a journal of no server (no epoch id given) has no such field
    journal = FaultJournal(tmp_path / "none.jsonl")
    journal.write({"event": "start", "id": 1, "t_sim_s": 0.0, "kind": "disconnect"})
    journal.close()
    assert "epoch_id" not in json.loads((tmp_path / "none.jsonl").read_text())


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
def test_the_lines_lost_are_counted_after_close(tmp_path, caplog):
    journal = FaultJournal("/dev/full", epoch_id=1)
    for i in range(3):
        journal.write({"event": "start", "id": i, "t_sim_s": 0.0, "kind": "disconnect"})
    journal.close()
    assert journal.lines_lost == 3  # (serve exits 1 on it)
    assert caplog.text.count("3 line(s) lost") == 1


def test_a_servers_journal_carries_the_epoch_id_it_publishes(serve, tmp_path):
    """The epoch id in the journal is the one the server publishes in its simulation
    control (what a client records in its meta), read over the wire."""
    from tests.modbus_helpers import ADVANCE, client, point, read_point, write

    path = tmp_path / "j.jsonl"
    faults = faults_from_list([{"kind": "no_reply", "unit": 2, "at_s": 1, "for_s": 2}])
    srv = serve(faults=faults, fault_log=path)
    c = client(srv.port)
    assert not write(c, srv, *ADVANCE, 10).isError()
    published = int(read_point(c, *point(srv, "sim_control", "epoch")))
    c.close()
    lines = read_journal(path)
    assert lines and {e["epoch_id"] for e in lines} == {f"{published:08x}"}


def test_a_server_restarted_on_the_same_journal_keeps_the_first_ones(tmp_path):
    """A stranger's probe, left alone until now: a server restarted under a run with the
    same ``--fault-log`` (the same command line, as a CI job restarts it) emptied the first
    server's journal, the faults of the plant the run's first rows came from. The earlier
    journal is now set aside under its epoch id, and a warning says where; each file is
    one server's, as the fault report wants."""
    import signal
    import subprocess

    from hil_client.demo import rig_emulator_serve
    from tests.modbus_helpers import client, read_point

    faults = tmp_path / "faults.yaml"
    faults.write_text("faults:\n  - {kind: no_reply, unit: 2, at_s: 1, for_s: 2}\n")
    journal = tmp_path / "j.jsonl"
    options = ("--lockstep", "--faults", str(faults), "--fault-log", str(journal))
    sim = load_map().device("sim_control")
    advance = next(p for p in sim.points if p.name == "lockstep_advance")
    epoch = next(p for p in sim.points if p.name == "epoch")
    epochs, errors = [], []
    for _ in range(2):
        with rig_emulator_serve("windhager_12kw", *options, stderr=subprocess.PIPE) as (
            port,
            proc,
        ):
            c = client(port, timeout_s=60)
            ten_s = encode(advance, 10)
            assert not c.write_registers(advance.address, ten_s, device_id=100).isError()
            epochs.append(f"{int(read_point(c, sim, epoch)):08x}")
            c.close()
            proc.send_signal(signal.SIGINT)
            assert proc.wait(timeout=60) == 0
            errors.append(proc.stderr.read().decode())
    kept = tmp_path / f"j.{epochs[0]}.jsonl"
    assert {e["epoch_id"] for e in read_journal(kept)} == {epochs[0]}
    assert {e["epoch_id"] for e in read_journal(journal)} == {epochs[1]}
    assert len(read_journal(kept)) == len(read_journal(journal)) == 2  # start and end
    assert "kept as" not in errors[0] and f"kept as {kept}" in errors[1], errors
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["faults.yaml", "j.jsonl", kept.name]
    )
