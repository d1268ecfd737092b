"""What a map may say, as a stranger writing register maps of their own probed it: values a
point cannot carry (a temperature as a bit, half a burner switch), a unit the map does not
convert, keys accepted and ignored; and the map's identity (``map_id``), which must tell a
client every map whose writes the server refuses, and no map that changes nothing."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from hil_client.cli import main as hil_main
from rig_emulator.registers import legacy_map_identity, load_map, map_from_mapping, map_identity
from rig_emulator.registers.schema import MAP_DIR
from tests.modbus_helpers import client, point, read_point

REPO = Path(__file__).resolve().parents[3]
SHORT = str(REPO / "tests" / "data" / "short_protocol.yaml")


def _shipped() -> dict[str, Any]:
    return yaml.safe_load((MAP_DIR / "wieselburg_bench.yaml").read_text())


def _points(data: dict[str, Any], device: str) -> dict[str, dict[str, Any]]:
    """The raw points of one device of ``data``, by name (to mutate in place)."""
    dev = next(d for d in data["devices"] if d["name"] == device)
    return {p["name"]: p for p in dev["points"]}


def _map_file(tmp_path: Path, mutate: Callable[[dict[str, Any]], Any]) -> Path:
    data = _shipped()
    mutate(data)
    path = tmp_path / "theirs.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _serve(path: Path) -> subprocess.CompletedProcess[str]:
    """``rig-emulator serve --map PATH`` as its own process, as the stranger ran it (a map it
    accepts would serve: the timeout ends the test then, a failure)."""
    argv = [sys.executable, "-m", "rig_emulator.cli", "serve", "--boiler", "windhager_12kw"]
    argv += ["--lockstep", "--port", "0", "--map", str(path)]
    return subprocess.run(argv, capture_output=True, text=True, timeout=60, cwd=REPO)


def _bool_room_temp(d: dict[str, Any]) -> None:
    _points(d, "bench_plc")["room_temp"].update(table="discrete", datatype="bool", address=5)


def _half_burner(d: dict[str, Any]) -> None:
    _points(d, "boiler_controller")["on_command"].update(
        table="holding", datatype="int16", address=5, scale=0.5
    )


def _double_burner(d: dict[str, Any]) -> None:
    _points(d, "boiler_controller")["on_command"].update(
        table="holding", datatype="uint16", address=5, scale=2
    )


def _offset_fault_kind(d: dict[str, Any]) -> None:
    _points(d, "sim_control")["fault_kind"]["offset"] = 0.5


def _kelvin(d: dict[str, Any]) -> None:
    _points(d, "bench_plc")["return_temp"]["unit"] = "K"


def _scaled_coil(d: dict[str, Any]) -> None:
    _points(d, "bench_plc")["pump"]["scale"] = 2


def _offset_bit(d: dict[str, Any]) -> None:
    _points(d, "balance")["stable"]["offset"] = 1


def _min_read_only(d: dict[str, Any]) -> None:
    _points(d, "bench_plc")["room_temp"]["min"] = 0


def _max_read_only_command(d: dict[str, Any]) -> None:
    _points(d, "bench_plc")["flow_setpoint"].update(access="r", max=500)


def _no_unit_id(d: dict[str, Any]) -> None:
    del d["devices"][1]["unit_id"]


#: (change of the shipped map, what the refusal says), each a stranger's map that was served
REFUSED: list[tuple[Callable[[dict[str, Any]], None], str]] = [
    # a stranger's probe: 22 C served as 1 (and listed by map-doc), no word
    (
        _bool_room_temp,
        "device 'bench_plc' point 'room_temp': a bit carries 0/1, and 'room_temp_C' [C] "
        "is neither an on/off signal nor a command of whole numbers",
    ),
    # int16 x0.5: raw 1 decoded to 0.5 and the burner fired on it
    (
        _half_burner,
        "device 'boiler_controller' point 'on_command': 'boiler_command' takes whole "
        "numbers only, so a writable point of it has scale 1 or -1 and a whole offset "
        "(scale 0.5, offset 0",
    ),
    # a re-probe: a scale of 2 passed the first rule, and 1 written through it read 0
    (_double_burner, "point 'on_command': 'boiler_command' takes whole numbers only"),
    (_offset_fault_kind, "point 'fault_kind': 'fault_kind' takes whole numbers only"),
    # unit: K relabelled 22 C as 22 K in map-doc and on the dashboard
    (
        _kelvin,
        "device 'bench_plc' point 'return_temp': 'unit' 'K' is not the unit of "
        "'water_in_temp_C' (C)",
    ),
    # accepted and ignored
    (
        _scaled_coil,
        "point 'pump': 'scale'/'offset' apply to integer types only (a bit carries 0/1)",
    ),
    (_offset_bit, "device 'balance' point 'stable': 'scale'/'offset' apply to integer"),
    (_min_read_only, "point 'room_temp': 'min'/'max' apply to writable points"),
    (_max_read_only_command, "point 'flow_setpoint': 'min'/'max' apply to writable points"),
    # reported as "'unit_id' must be an integer 1..247"
    (_no_unit_id, "device 'flue_gas_analyser': missing required key 'unit_id'"),
]


@pytest.mark.parametrize(
    ("mutate", "message"),
    [pytest.param(mutate, message, id=mutate.__name__.strip("_")) for mutate, message in REFUSED],
)
def test_serve_refuses_a_point_that_cannot_carry_its_signal(tmp_path, mutate, message):
    """A stranger's probe: each of these maps was served (exit 0, nothing said). Refused in
    one line naming the file, device and point, exit 2, before any port is opened."""
    path = _map_file(tmp_path, mutate)
    proc = _serve(path)
    assert proc.returncode == 2, proc.stderr
    (line,) = proc.stderr.strip().splitlines()
    assert line.startswith(f"rig-emulator: error: {path}: "), line
    assert message in line, line
    assert "Traceback" not in proc.stderr and not proc.stdout


def test_what_the_rules_leave_alone_is_served_as_before(tmp_path):
    """The shipped map passes every rule (its bits are switches, its codes uint16 x1);
    the signal's own unit (as 'C', '°C' or 'kg / h': a re-probe found them refused), a
    whole scale on a whole command, a range on a writable point, a reset or a clock mode
    on a coil and a read-only echo of a code in tenths (both served before the first
    rules: a re-probe), and a number as instrument text (its text, "42", like any
    free-text key) are accepted."""
    load_map()

    def mutate(d: dict[str, Any]) -> None:
        plc = _points(d, "bench_plc")
        plc["return_temp"]["unit"] = "°C"
        plc["flow_setpoint"].update(min=0, max=1500, unit="kg / h")
        sim = next(dev for dev in d["devices"] if dev["name"] == "sim_control")
        sim["points"] += [
            {"name": "reset_coil", "signal": "reset", "table": "coil", "address": 0,
             "datatype": "bool", "access": "rw"},
            {"name": "mode_coil", "signal": "clock_mode", "table": "coil", "address": 1,
             "datatype": "bool", "access": "rw"},
            {"name": "kind_tenths", "signal": "fault_kind", "table": "input", "address": 200,
             "datatype": "int16", "scale": 0.1},
        ]  # fmt: skip
        _points(d, "sim_control")["fault_kind"].update(scale=1, offset=0)
        _points(d, "boiler_controller")["on_command"].update(
            table="holding", datatype="uint16", address=5, scale=1
        )
        d["devices"][1]["instrument"] = 42

    path = _map_file(tmp_path, mutate)
    out = tmp_path / "doc.md"
    argv = [sys.executable, "-m", "rig_emulator.cli", "map-doc", "--map", str(path)]
    proc = subprocess.run([*argv, "--out", str(out)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    doc = out.read_text()
    assert "## Unit 2: `flue_gas_analyser`\n\n42\n" in doc
    assert "| 2-3 | 30003 | return_temp | float32 | ABCD |  |  | °C | r |" in doc
    assert "| 0-1 | 40001 | flow_setpoint | float32 | ABCD |  |  | kg / h | rw | 0..1500 |" in doc


def _narrowed_flow(d: dict[str, Any]) -> None:
    _points(d, "bench_plc")["flow_setpoint"]["max"] = 500


def _read_only_return_setpoint(d: dict[str, Any]) -> None:
    _points(d, "bench_plc")["return_setpoint"]["access"] = "r"


@pytest.mark.parametrize("change", [_narrowed_flow, _read_only_return_setpoint])
def test_a_server_that_refuses_the_clients_writes_stops_the_run(serve, tmp_path, capsys, change):
    """A stranger's probe: a server whose map narrowed the flow setpoint to 0..500 kg/h
    published the shipped map's id; a client with the shipped map ran the 6-h test with
    every setpoint write refused (exception 03) and exited 0. The access and the range of a
    write are in the id: the run stops before its first row."""
    data = _shipped()
    change(data)
    srv = serve(register_map=map_from_mapping(data, "theirs.yaml"))
    c = client(srv.port)
    try:
        served = read_point(c, *point(srv, "sim_control", "map_id"))
    finally:
        c.close()
    assert int(served) == map_identity(srv.map) != map_identity(load_map())
    out = tmp_path / "refused.csv"
    argv = ["run", SHORT, "--boiler", "windhager_12kw", "--quiet", "--out", str(out)]
    assert hil_main([*argv, "--rig", f"modbus://127.0.0.1:{srv.port}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "serves another register map" in err, err
    assert not out.exists()


def test_the_word_order_of_a_one_register_point_changes_no_id(serve):
    """A stranger's probe: ``word_order: CDAB`` on a 16-bit point changes no byte on the
    wire, yet changed the map id, so a client with the shipped map refused that server.
    Same registers, same id."""
    data = _shipped()
    _points(data, "fid")["OGC"]["word_order"] = "CDAB"  # int16
    # the controller's default: its uint16, int16 and bool points; its float32 kept ABCD
    next(d for d in data["devices"] if d["name"] == "boiler_controller")["word_order"] = "CDAB"
    _points(data, "boiler_controller")["firing_power"]["word_order"] = "ABCD"
    theirs = serve(register_map=map_from_mapping(data, "theirs.yaml"))
    ours = serve()
    assert map_identity(theirs.map) == map_identity(ours.map)
    registers = []
    for srv in (theirs, ours):
        c = client(srv.port)
        try:
            registers.append(
                [
                    c.read_input_registers(0, count=count, device_id=unit).registers
                    for unit, count in ((3, 1), (7, 4))  # the FID's OGC; the controller's
                ]
                + [read_point(c, *point(srv, "sim_control", "map_id"))]
            )
        finally:
            c.close()
    assert registers[0] == registers[1]  # the same bytes, the map id among them
    # a word order that moves bytes still changes it (the controller's float32)
    del _points(data, "boiler_controller")["firing_power"]["word_order"]
    assert map_identity(map_from_mapping(data)) != map_identity(load_map())


def _git(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["git", "-C", str(REPO), *args], capture_output=True, text=True)


def test_generated_certificates_are_ignored_by_git(tmp_path):
    """A stranger's probe: ``rig-emulator certs --out certs`` in the checkout, as the README
    says, left the private keys untracked and not ignored, one ``git add .`` from a commit.
    Every file it writes under ``certs/`` is ignored."""
    if _git("rev-parse", "--is-inside-work-tree").returncode != 0:
        pytest.skip("not a git checkout")
    argv = [sys.executable, "-m", "rig_emulator.cli", "certs", "--out", str(tmp_path / "certs")]
    made = subprocess.run(argv, capture_output=True, text=True, timeout=120)
    assert made.returncode == 0, made.stderr
    names = sorted(p.name for p in (tmp_path / "certs").iterdir())
    assert any(name.endswith(".key") for name in names), names
    paths = [f"certs/{name}" for name in names]
    ignored = _git("check-ignore", "--no-index", *paths)
    assert sorted(ignored.stdout.split()) == paths, ignored.stderr
    # the module of the same name stays tracked (exit 1: not ignored)
    assert _git("check-ignore", "--no-index", "rig_emulator/certs.py").returncode == 1


def test_an_earlier_releases_id_and_a_minus_zero_range(tmp_path):
    """Re-probes: a new client refused a server of the earlier release serving the very
    same shipped map (its map_id, read over the wire from the release before the ranges
    joined the hash, 0a72832f), and advised a --map that could not help; the client
    accepts that older form of its own map's id. And a writable range written ``min:
    -0.0`` changed the id, though nothing on the wire or in the answers changes."""
    shipped = load_map()
    assert legacy_map_identity(shipped) == 0x0A72832F  # published by a388971's server
    assert legacy_map_identity(shipped) != map_identity(shipped)
    path = _map_file(tmp_path, lambda d: _points(d, "bench_plc")["flow_setpoint"].update(min=-0.0))
    assert map_identity(load_map(path)) == map_identity(shipped)
