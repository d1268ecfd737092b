"""The run's meta names the server starts its rows came from, as their fault journals do:
``server_epoch_id`` (the first server's) and each gap's (the server's after it). A
stranger's probe: with a real-time server killed and restarted under ``run --on-restart
continue`` the fault report matched each journal with the rows of either plant, the meta
saying no more than ``rig_epoch`` (a count, not which server)."""

from __future__ import annotations

import random
import signal

from hil_client.analysis.logio import read_log
from hil_client.wait_for_port import free_port
from rig_emulator.registers import load_map
from tests.hil_client.test_restarts import (  # noqa: F401 (servers: a fixture)
    _realtime_client,
    _rows,
    _wait,
    servers,
)
from tests.modbus_helpers import client, read_point


def _epoch_id(port: int) -> str:
    """The server's ``epoch_id`` as its journal writes it (8 hex digits)."""
    register_map = load_map()
    dev, point = register_map.point("epoch_id")
    c = client(port)
    try:
        return f"{int(read_point(c, dev, point)):08x}"
    finally:
        c.close()


def test_meta_and_gap_name_the_server_start_of_their_rows(servers, tmp_path):  # noqa: F811
    port = free_port()
    first = servers(port, "--speed", "200")
    first_epoch = _epoch_id(port)
    out = tmp_path / "rt.csv"
    run = _realtime_client(port, out, "--on-restart", "continue")
    kill_row = random.Random(7).randint(5, 30)  # a seeded random point
    try:
        _wait(lambda: _rows(out) >= kill_row, f"{kill_row} rows")
        first.kill()
        servers(port, "--speed", "200")
        second_epoch = _epoch_id(port)
        _wait(lambda: out.read_text().count(",1\n") >= 3, "3 rows of rig_epoch 1")
        run.send_signal(signal.SIGKILL)  # the meta is written as the run goes
        run.wait(timeout=30)
    finally:
        if run.poll() is None:
            run.kill()
    assert first_epoch != second_epoch  # (random 32 bits per start)
    text = out.read_text()
    out.write_text(text[: text.rfind("\n") + 1])  # a row cut by SIGKILL is not the test's
    meta = read_log(out).meta
    assert meta["server_epoch_id"] == first_epoch
    (gap,) = meta["gaps"]
    assert gap["rig_epoch"] == 1 and gap["server_epoch_id"] == second_epoch
