"""The RTU line's count of the bytes it discards as noise (coming faster than its baud
rate): every byte discarded is said in the log, when the minute of the last such line ends
or at the latest when the line stops, not only in the line of the next burst."""

from __future__ import annotations

import contextlib
import logging
import os
import re
import time
from collections.abc import Callable, Iterator

import pytest

from rig_emulator.modbus import rtu
from rig_emulator.modbus.rtu import RtuLine
from rig_emulator.modbus.transports import Transports
from tests.rig_emulator.transports.served import RtuClient

BAUD = 19200
BURST_BYTES = 64 * 1024  # the stranger's burst
#: "(N bytes since the last such line" of the first line, ": N more bytes discarded" of
#: those that say the rest
SAID = re.compile(r"\((\d+) bytes since the last such line|: (\d+) more bytes discarded")


def _said(caplog: pytest.LogCaptureFixture) -> list[int]:
    """The counts of discarded bytes the log said, line by line."""
    return [
        int(found.group(1) or found.group(2))
        for record in caplog.records
        if (found := SAID.search(record.getMessage()))
    ]


@contextlib.contextmanager
def noisy_line(serve) -> Iterator[tuple[RtuLine, Callable[[], None]]]:
    """The emulator's own pty line (an in-process server) after 64 KiB of random bytes
    written at once, answering again; (the line, what stops it: once, as the block ends at
    the latest)."""
    srv = serve()

    async def setup():
        transports = Transports(srv.server.modbus_server)
        return transports, await transports.add_rtu("pty", BAUD, "E")

    transports, line = srv.call(setup())
    stopped: list[bool] = []

    def stop() -> None:
        if not stopped:
            stopped.append(True)
            srv.call(transports.stop())

    try:
        client = RtuClient(line.path)
        try:
            os.write(client.fd, os.urandom(BURST_BYTES))
            # until the line has read the burst: all of it discarded but the line time it
            # may owe (30 s at most, a loaded machine's room; the line answering after a
            # burst is test_rtu_burst's: in one CI run at three workers an answer asked
            # for here did not come within 30 s)
            deadline = time.monotonic() + 30.0
            while (
                line.discarded <= BURST_BYTES - 10 * rtu.OWED_CHARACTERS
                and time.monotonic() < deadline
            ):
                time.sleep(0.05)
        finally:
            client.close()
        yield line, stop
    finally:
        stop()


def test_a_bursts_discarded_bytes_are_all_said_by_the_stop(serve, caplog):
    """A stranger's probe: after 64 KiB of random bytes the log said "discarded as noise
    (3838 bytes since the last such line; one a minute at most)" and nothing more; the rest
    (some 61,000) came only in the line of another burst a minute later ("128519 bytes").
    The bytes held back are said at the latest when the line stops."""
    caplog.set_level(logging.INFO, logger="rig_emulator.serve")
    with noisy_line(serve) as (line, stop):
        assert len(_said(caplog)) == 1  # within its minute: the first line only
        stop()
    said = _said(caplog)
    # the burst's bytes beyond the line time it may owe, nearly all of them (waited for)
    assert line.discarded > BURST_BYTES - 10 * rtu.OWED_CHARACTERS, line.discarded
    assert sum(said) == line.discarded, (said, line.discarded)
    assert len(said) == 2  # the first line, and the rest in one


def test_a_bursts_discarded_bytes_are_said_when_the_minute_ends(serve, caplog, monkeypatch):
    """The same burst with the line's log interval a second instead of a minute (a test
    does not wait minutes): the bytes held back are said as it ends, the line still
    running (the stranger saw nothing follow the first line until another burst came)."""
    caplog.set_level(logging.INFO, logger="rig_emulator.serve")
    monkeypatch.setattr(rtu, "DISCARD_LOG_INTERVAL_S", 1.0)
    with noisy_line(serve) as (line, _):
        # the interval's end, and 10 s for a loaded machine's scheduling
        deadline = time.monotonic() + 1.0 + 10.0
        while sum(_said(caplog)) < line.discarded and time.monotonic() < deadline:
            time.sleep(0.05)
        said = _said(caplog)
        assert sum(said) == line.discarded, (said, line.discarded)
