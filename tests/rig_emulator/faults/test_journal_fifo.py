"""A fault journal on a FIFO never waits for a reader.

A stranger's probe: ``serve --fault-log FIFO`` with nobody reading blocked in the
journal's open inside the server's event loop, where no stop signal reached it. ``serve``
now refuses such a FIFO before it listens; a reader gone between that check and the
journal's start costs the journal's lines (a warning), never the server.
"""

from __future__ import annotations

import json
import logging
import os
import threading

from rig_emulator.faults import FaultJournal
from tests.fifo_helpers import FifoReader

#: how long an open that does not wait may take on a loaded machine (it takes microseconds)
OPEN_S = 10.0


def test_a_journal_on_a_fifo_nobody_reads_begins_at_once_and_loses_its_lines(tmp_path, caplog):
    fifo = tmp_path / "journal.fifo"
    os.mkfifo(fifo)
    journal = FaultJournal(fifo, begin=False)
    begun = threading.Thread(target=journal.begin, daemon=True)
    with caplog.at_level(logging.WARNING, logger="rig_emulator.serve"):
        begun.start()
        begun.join(OPEN_S)
        waited = begun.is_alive()
        if waited:  # (the old open: a reader opened and closed here releases it)
            os.close(os.open(fifo, os.O_RDONLY | os.O_NONBLOCK))
            begun.join(OPEN_S)
        journal.write({"event": "start", "id": 1, "t_sim_s": 1.0})
        journal.close()
    assert not waited, "the journal's open waited for a reader of the FIFO"
    assert journal.lines_lost == 1
    assert f"fault journal {fifo}: cannot write (no process reads the FIFO)" in caplog.text


def test_a_journal_on_a_fifo_read_writes_each_line_as_it_comes(tmp_path):
    fifo = tmp_path / "journal.fifo"
    os.mkfifo(fifo)
    reader = FifoReader(fifo)
    journal = FaultJournal(fifo, epoch_id=0xC0FFEE)
    journal.write({"event": "start", "id": 1, "t_sim_s": 1.0})
    assert reader.wait_for(1, OPEN_S), reader.lines  # flushed as written
    journal.close()
    assert reader.ended(OPEN_S)
    assert reader.lines == ['{"event": "start", "id": 1, "t_sim_s": 1.0, "epoch_id": "00c0ffee"}\n']
    assert journal.lines_lost == 0


def test_a_journal_whose_reader_stops_reading_loses_lines_never_waits(tmp_path, caplog):
    """A re-read of the fix: a reader that holds the FIFO open but stops reading filled the
    pipe (64 kB), and a blocking write then stopped the server's event loop, stop signals
    and all. The journal's writes never wait: what the pipe does not take is held back, and
    the reader gone, lost (said once)."""
    fifo = tmp_path / "journal.fifo"
    os.mkfifo(fifo)
    idle_reader = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)  # open, never read
    try:
        journal = FaultJournal(fifo)
        lines = 5000  # about 300 kB: several times a pipe's buffer
        writing = threading.Thread(
            target=lambda: [journal.write({"event": "start", "id": i}) for i in range(lines)],
            daemon=True,
        )
        with caplog.at_level(logging.WARNING, logger="rig_emulator.serve"):
            writing.start()
            writing.join(OPEN_S)
            waited = writing.is_alive()
            os.close(idle_reader)  # (the old write: EPIPE releases it)
            idle_reader = -1
            writing.join(OPEN_S)
            journal.close()
    finally:
        if idle_reader >= 0:
            os.close(idle_reader)
    assert not waited, "a journal write waited for the FIFO's reader to read"
    assert 0 < journal.lines_lost < lines
    assert caplog.text.count("its lines are lost from now on") == 1


def test_a_burst_larger_than_the_pipe_reaches_a_reader_that_reads(tmp_path):
    """A re-probe: with writes that never wait, a burst larger than the pipe's 64 kB (a tick
    of hundreds of faults at x1000) was a failed write, and the journal lost that burst and
    every line after while ``cat`` kept reading. What the pipe does not take is held back
    and written as the reader takes it (at the next line, :meth:`FaultJournal.drain`, or
    the close)."""
    fifo = tmp_path / "journal.fifo"
    os.mkfifo(fifo)
    reader = FifoReader(fifo)
    journal = FaultJournal(fifo)
    lines = 2000  # about 600 kB in one go: ten pipes' worth
    for i in range(lines):
        journal.write({"event": "start", "id": i, "note": "x" * 250})
    journal.write({"event": "end", "id": lines})  # a later line: the rest drained first
    journal.close()
    assert reader.ended(OPEN_S)
    assert journal.lines_lost == 0
    assert [json.loads(line)["id"] for line in reader.lines] == list(range(lines + 1))
