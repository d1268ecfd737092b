"""Whole-file writes (rig_emulator.atomic) on real files, links and redirections."""

from __future__ import annotations

import os
import subprocess
import sys

from rig_emulator.atomic import write_atomically


def test_the_old_files_mode_is_kept(tmp_path):
    """A re-probe: a private (0600) output became world-readable once replaced."""
    path = tmp_path / "private.json"
    path.write_text("old")
    path.chmod(0o600)
    write_atomically(path, "new")
    assert path.read_text() == "new" and (path.stat().st_mode & 0o777) == 0o600


def test_a_file_of_several_hard_links_is_written_in_place(tmp_path):
    """A re-probe: replacing it left the other link with the old text."""
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text("old")
    os.link(a, b)
    write_atomically(a, "new")
    assert b.read_text() == "new" and a.stat().st_ino == b.stat().st_ino


def test_a_long_name_gets_a_short_temporary_one(tmp_path):
    """A re-probe: a 250-byte name grew past the file system's 255 with the temporary
    suffixes, and was refused."""
    path = tmp_path / ("a" * 245 + ".json")
    write_atomically(path, "new")
    assert path.read_text() == "new" and len(list(tmp_path.iterdir())) == 1


def test_standard_output_redirected_to_a_file_is_written_to_not_replaced(tmp_path):
    """A re-probe: --out /dev/stdout with stdout appended to a file replaced that file
    (its earlier lines and the table printed before were lost)."""
    log = tmp_path / "app.txt"
    log.write_text("PREVIOUS\n")
    code = "from pathlib import Path; from rig_emulator.atomic import write_atomically; "
    code += "print('table', flush=True); write_atomically(Path('/dev/stdout'), 'json\\n')"
    with log.open("a") as out:
        subprocess.run([sys.executable, "-c", code], stdout=out, check=True, timeout=60)
    assert log.read_text() == "PREVIOUS\ntable\njson\n"
