"""What a non-editable install holds: the wheel alone, unpacked away from the checkout, must
run without the checkout's files (a CI user's ``pip install`` had no register map, so
``serve`` and the pytest plugin could not start)."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

CHECK = """
import sys
sys.path.insert(0, {unpacked!r})
import hil_client, rig_emulator
assert rig_emulator.__file__.startswith({unpacked!r}), rig_emulator.__file__
from rig_emulator.registers import load_map
from rig_emulator.boilers import load_boiler
from rig_emulator.instruments import load_profile
from importlib import resources
from hil_client.protocol.definition import load_protocol
assert load_map().devices
for name in ("windhager_6kw", "windhager_12kw"):
    load_boiler(name)
for name in ("clean", "lab", "lab_instruments", "lab_faulty"):
    load_profile(name)
for name in ("stationary", "load_cycle"):
    load_protocol(name)
assert resources.files("rig_emulator.dashboard").joinpath("static/index.html").is_file()
print("ok")
"""


@pytest.fixture(scope="module")
def unpacked_wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    # built from a copy of the sources alone: a checkout's stale build/ would lend the wheel
    # files that the package data no longer declares
    source = out / "source"
    shutil.copytree(
        ROOT,
        source,
        symlinks=True,
        ignore=shutil.ignore_patterns(
            ".git", ".venv", "build", "*.egg-info", "out", "__pycache__", ".pytest_cache"
        ),
    )
    built = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(source), "--no-deps", "-q", "-w", str(out)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    if built.returncode != 0:  # no package index to fetch the build backend from
        print(built.stderr)
        pytest.skip("pip could not build the wheel (no setuptools from the package index?)")
    (wheel,) = out.glob("*.whl")
    target = out / "unpacked"
    with zipfile.ZipFile(wheel) as zf:
        zf.extractall(target)
    return target


def test_the_installed_package_runs_without_the_checkout(unpacked_wheel, tmp_path):
    done = subprocess.run(
        [sys.executable, "-I", "-c", CHECK.format(unpacked=str(unpacked_wheel))],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"
