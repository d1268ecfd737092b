"""Who has a pty open (:mod:`rig_emulator.modbus.pty_masters`), on a real pty: opens and
closes counted from inotify, and the count from /proc an overflowed queue falls back on."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from rig_emulator.modbus.pty_masters import PtyMasters, count_openers

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="inotify: Linux")


@pytest.fixture
def pty_path():
    server, client = os.openpty()
    path = os.ttyname(client)
    yield path
    os.close(client)
    os.close(server)


def test_opens_and_closes_are_counted_and_the_first_and_last_told(pty_path):
    masters = PtyMasters.watch(pty_path)
    assert masters is not None
    try:
        assert masters.update() == (False, False) and masters.openers == 0
        first = os.open(pty_path, os.O_RDWR | os.O_NOCTTY)
        assert masters.update() == (True, False) and masters.openers == 1
        prober = os.open(pty_path, os.O_RDONLY | os.O_NOCTTY)  # (stty -F, a prober)
        os.close(prober)
        assert masters.update() == (False, False) and masters.openers == 1
        again = os.dup(first)  # one open description: closed once, at its last descriptor
        os.close(first)
        assert masters.update() == (False, False) and masters.openers == 1
        os.close(again)
        assert masters.update() == (False, True) and masters.openers == 0
    finally:
        masters.close()


def test_the_count_from_proc_sees_other_processes_not_this_one(pty_path):
    own = os.open(pty_path, os.O_RDWR | os.O_NOCTTY)  # (the server's own: not counted)
    try:
        with open(pty_path, "rb", buffering=0) as held:
            child = subprocess.Popen(["sleep", "30"], stdin=held)
        try:
            assert count_openers(pty_path) == 1
        finally:
            child.kill()
            child.wait()
        assert count_openers(pty_path) == 0
    finally:
        os.close(own)


def test_after_an_overflowed_queue_the_count_is_the_processes(pty_path):
    """A re-probe: 400,000 opens and closes overflowed inotify's queue; the count was then
    made again from /proc and the events queued behind the overflow applied on top of it,
    leaving a count too high (a stale reply reached the next master) or none (a live
    master unanswered). Now the count after an overflow is the processes' own."""
    with open("/proc/sys/fs/inotify/max_queued_events") as limit:
        storm = int(limit.read()) + 1000  # opens and closes: twice as many events
    masters = PtyMasters.watch(pty_path)
    assert masters is not None
    try:
        with open(pty_path, "rb", buffering=0) as held:
            child = subprocess.Popen(["sleep", "30"], stdin=held)  # a master, held open
        try:
            for _ in range(storm):
                os.close(os.open(pty_path, os.O_RDONLY | os.O_NOCTTY))
            came, left = masters.update()
            assert masters.openers == 1 and not came and not left
        finally:
            child.kill()
            child.wait()
        assert masters.update() == (False, True) and masters.openers == 0
    finally:
        masters.close()
