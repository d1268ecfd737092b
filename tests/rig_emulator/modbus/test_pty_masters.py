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
