"""Register maps at the size limit and names that display as others, as a stranger probed
them: a map of many points took minutes to validate (map-doc and serve alike), and point
names with a right-to-left override or a line break were documented as written."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

from rig_emulator.cli import main as rig_main
from rig_emulator.registers import MapError, load_map, map_from_mapping, map_identity
from rig_emulator.registers.schema import MAP_DIR
from rig_emulator.yamlio import MAX_YAML_BYTES, read_yaml
from tests.modbus_helpers import client, read_point

REPO = Path(__file__).resolve().parents[3]
#: a map of 5,000 points more than the shipped one (the stranger's had up to 30,000: the
#: comparison count of test_validating_a_map_compares_names_not_pairwise is what catches a
#: quadratic check; these two show a big map documented and served end to end)
MANY = 5_000


def _shipped() -> dict[str, Any]:
    return yaml.safe_load((MAP_DIR / "wieselburg_bench.yaml").read_text())


def _many_points_map(folder: Path, extra: int) -> Path:
    """The shipped map and a unit 200 of ``extra`` uint32 points of the seed, as the
    stranger's ``many_points.py`` made it (written as text: dumping thousands of points as YAML
    took longer than reading them)."""
    text = yaml.safe_dump(_shipped(), sort_keys=False)
    assert text.endswith("\n") and "\ndevices:\n- name: " in text  # the devices come last
    text += "- name: many\n  unit_id: 200\n  points:\n" + "".join(
        f"  - {{name: x{i}, signal: seed, table: input, address: {2 * i}, datatype: uint32}}\n"
        for i in range(extra)
    )
    path = folder / f"many_{extra}.yaml"
    path.write_text(text)
    assert path.stat().st_size < MAX_YAML_BYTES
    return path


@pytest.fixture(scope="module")
def many_map(tmp_path_factory) -> Path:
    """The stranger's map of :data:`MANY` points more than the shipped one."""
    return _many_points_map(tmp_path_factory.mktemp("many"), MANY)


def test_map_doc_documents_a_map_of_thousands_of_points(many_map, tmp_path, capsys):
    """A stranger's probe: map-doc of a map of 8,000 points more than the shipped one took
    5.9 s, of 16,000 13.4 s, of 30,000 (2.5 MB, within the size limit) more than a minute:
    each point's name was counted in the device's list of names. Now every point of a map
    of 5,000 more is documented, one row each (a few seconds; without a timing assertion,
    the machine is shared: what bounds the work is the next test)."""
    out = tmp_path / "many.md"
    assert rig_main(["map-doc", "--map", str(many_map), "--out", str(out)]) == 0, (
        capsys.readouterr()
    )
    doc = out.read_text()
    rows = re.findall(r"^\| \d+-\d+ \| \d+ \| x\d+ \| uint32 \|", doc, re.MULTILINE)
    assert len(rows) == MANY
    assert "## Unit 200: `many`" in doc
    last = 2 * (MANY - 1)  # (its PLC number has 5 digits below address 10000, 6 above)
    row = rf"^\| {last}-{last + 1} \| 3\d+ \| x{MANY - 1} \| uint32 \| ABCD \|"
    assert re.search(row, doc, re.MULTILINE)


class _CountedName(str):
    """A point name counting the comparisons of names with another (a str subclass: the
    loader takes it as the text it is)."""

    comparisons = 0

    def __eq__(self, other: object) -> bool:
        _CountedName.comparisons += 1
        return str.__eq__(self, other)

    __hash__ = str.__hash__


@pytest.mark.parametrize("extra", [1000, 4000])
def test_validating_a_map_compares_names_not_pairwise(tmp_path, extra):
    """A stranger's probe: a map's validation grew with the square of its points (30,000
    points took more than a minute): each name was compared with every other. The work is
    counted, not timed (the machine is shared): the real file read, its names counted as
    the validation compares them, fewer comparisons than points, where the pairwise check
    made about the square of them (a million for 1,000 points)."""
    path = _many_points_map(tmp_path, extra)
    data = read_yaml(path, MapError)
    for device in data["devices"]:
        for raw in device["points"]:
            raw["name"] = _CountedName(raw["name"])
    _CountedName.comparisons = 0
    register_map = map_from_mapping(data, str(path))
    points = sum(len(d.points) for d in register_map.devices)
    assert points == extra + sum(len(d["points"]) for d in _shipped()["devices"])
    # by hashing, a name is compared only with one of the same hash (itself, found by
    # identity): no comparison at all but on a hash collision
    assert _CountedName.comparisons < points, _CountedName.comparisons


def test_serve_starts_on_a_map_of_thousands_of_points(many_map):
    """A stranger's probe: serve validates the map as map-doc does, so a map of many points
    kept a server from starting (32,000 points: 108 s of validation before it listened).
    One of 5,000 points more serves: its ``map_id`` is the map's, its last point answers."""
    argv = [sys.executable, "-m", "rig_emulator.cli", "serve", "--boiler", "windhager_12kw"]
    argv += ["--lockstep", "--port", "0", "--map", str(many_map)]
    with subprocess.Popen(argv, stderr=subprocess.PIPE, text=True, cwd=REPO) as proc:
        try:
            assert proc.stderr is not None
            seen = []
            for line in proc.stderr:  # (the pytest timeout bounds the wait)
                seen.append(line)
                if match := re.search(r"serving .* on 127\.0\.0\.1:(\d+)", line):
                    break
            else:
                pytest.fail(f"serve did not start: {''.join(seen)[-500:]}")
            register_map = load_map(many_map)
            sim, many = register_map.device("sim_control"), register_map.device("many")
            c = client(int(match.group(1)))
            try:
                served_id = read_point(c, sim, next(p for p in sim.points if p.name == "map_id"))
                last = read_point(c, many, many.points[-1])
            finally:
                c.close()
            assert int(served_id) == map_identity(register_map)
            assert last == 0.0  # the seed the server runs with (serve's default, 0)
        finally:
            proc.terminate()
            proc.wait(timeout=30)


def _map_with(tmp_path: Path, device: int, index: int, name: str, field: str = "point") -> Path:
    """The shipped map with the name of ``devices[device]`` (field "device") or of its
    ``points[index]`` set to ``name``."""
    data = _shipped()
    target = data["devices"][device]
    (target if field == "device" else target["points"][index])["name"] = name
    path = tmp_path / "theirs.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True), encoding="utf-8")
    return path


HIDDEN = [
    ("\u202e", "\\u202e", "U+202E RIGHT-TO-LEFT OVERRIDE: a format character"),
    ("\n", "\\n", "U+000A: a control character"),
    ("\u2028", "\\u2028", "U+2028 LINE SEPARATOR: a line separator"),
    ("\u00ad", "\\xad", "U+00AD SOFT HYPHEN: a format character"),
    ("\ue000", "\\ue000", "U+E000: a private-use character"),
]


@pytest.mark.parametrize(("character", "escaped", "named"), HIDDEN)
def test_map_doc_refuses_a_point_name_that_displays_as_another(
    tmp_path, capsys, character, escaped, named
):
    """A stranger's probe: a point named ``temp\\u202eC`` (a right-to-left override, shown
    as another name) or with a line break passed map-doc and was printed as written. Such a
    name is refused in one line naming the point by its device and position, the name
    escaped, and the character by its code point (as boiler and role names are)."""
    path = _map_with(tmp_path, 0, 3, f"boiler{character}temp")
    assert rig_main(["map-doc", "--map", str(path)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    err = captured.err
    assert err.count("\n") == 1 and character not in err.rstrip("\n"), err
    where = f"{path}: device 'bench_plc' points[3]"
    assert f"{where}: 'name' 'boiler{escaped}temp' holds {named}" in err, err


def test_a_device_name_that_displays_as_another_is_refused_by_position(tmp_path, capsys):
    """A stranger's probe (point names with U+202E passed): a device's name is printed as
    the heading of its table, so it is refused the same way, the device by its position."""
    path = _map_with(tmp_path, 1, 0, "flue\u202egas", field="device")
    assert rig_main(["map-doc", "--map", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "\u202e" not in err, err
    assert f"{path}: devices[1]: 'name' 'flue\\u202egas' holds U+202E RIGHT-TO-LEFT" in err, err


@pytest.mark.parametrize(
    "spelled", ["\u0645\u06cc\u200c\u062e\u0648\u0627\u0647\u0645", "a\u200db"]
)
def test_names_spelled_with_a_joiner_are_documented(tmp_path, capsys, spelled):
    """The zero-width non-joiner and joiner are format characters that spell names (Persian,
    the Indic scripts), as in role names: a point so named is documented as written."""
    path = _map_with(tmp_path, 0, 3, spelled)
    assert rig_main(["map-doc", "--map", str(path)]) == 0
    assert f"| {spelled} | float32 |" in capsys.readouterr().out
