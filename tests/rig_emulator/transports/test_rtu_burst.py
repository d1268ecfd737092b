"""A burst of bytes faster than the baud rate on the RTU pty of ``rig-emulator serve`` (its
own process): the line answers again within a bounded time once the burst stops, says so
once in its log, and still keeps the wire's time for every transaction."""

from __future__ import annotations

import errno
import os
import struct
import time

import pytest

from rig_emulator.modbus.rtu import OWED_CHARACTERS
from rig_emulator.modbus.rtu_wire import character_s, silence_s
from tests.rig_emulator.transports.served import RtuClient, serving

READ = struct.pack(">BHH", 4, 0, 2)  # FC4 of 2 registers: 8 characters, its reply 9
BURST_BYTES = 1 << 20  # 1 MiB: 2.4 hours of wire time at 1,200 baud, 10 minutes at 19,200


def _burst(line: RtuClient, size: int) -> int:
    """Write up to ``size`` bytes of noise as fast as the pty takes them (1 s at most: the
    pty's buffer is bounded, the server reads as it can); how many went."""
    os.set_blocking(line.fd, False)
    noise = bytes(range(256)) * 256
    written, deadline = 0, time.monotonic() + 1.0
    try:
        while written < size and time.monotonic() < deadline:
            try:
                written += os.write(line.fd, noise)
            except OSError as exc:
                if exc.errno != errno.EAGAIN:
                    raise
                time.sleep(0.001)
    finally:
        os.set_blocking(line.fd, True)
    return written


@pytest.mark.parametrize("baud", [1200, 19200])
def test_the_line_answers_soon_after_a_burst_faster_than_its_baud_rate(baud):
    """A stranger's probe: 64 KiB written at once at 19,200 baud held the line 37.9 s (its
    wire time), and 19.7 MB at 1,200 baud left it unanswered past 5 minutes (50 hours of
    wire time), without a log line. The line owes at most OWED_CHARACTERS of line time: once
    the burst stops it answers within that and a silence, and says once what it dropped."""
    with serving("--serial", "pty", "--baud", str(baud), serial=True) as served:
        line = RtuClient(served.serial)
        try:
            assert line.exchange(1, READ)[:2] == bytes([4, 4])  # the control, before
            written = _burst(line, BURST_BYTES)
            assert written >= 64 * 1024, written  # the stranger's smallest burst, at least
            stopped = time.monotonic()
            # the line is silent again at most OWED_CHARACTERS and a t3.5 after the burst;
            # 0.5 s more for a loaded machine's scheduling (the old line owed the burst's
            # whole wire time: hours here)
            quiet_s = OWED_CHARACTERS * character_s(baud) + silence_s(baud) + 0.5
            time.sleep(max(0.0, stopped + quiet_s - time.monotonic()))
            reply = line.exchange(1, READ, timeout_s=2.0)  # its transaction: 0.2 s at 1,200
            assert reply[:2] == bytes([4, 4]), (reply.hex(), time.monotonic() - stopped)
            print(f"{baud} baud: {written} bytes, answered {time.monotonic() - stopped:.2f} s on")
            # and a transaction still takes its wire time (CONTRACT section 6)
            least_s = (8 + 9) * character_s(baud) + silence_s(baud)
            started = time.monotonic()
            assert line.exchange(1, READ)[:2] == bytes([4, 4])
            assert time.monotonic() - started >= least_s
        finally:
            line.close()
    said = [text for text in served.stderr if "faster than" in text]
    assert len(said) == 1, served.stderr  # one line, not one per chunk
    assert f"bytes come faster than {baud} baud carries them" in said[0]
