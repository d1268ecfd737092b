"""The Modbus rig against a map whose encodings are too narrow (a stranger's probe with maps
of their own): a setpoint its point cannot carry is refused, never clipped on the wire, and
a simulated time its point cannot count on stops the run naming the map, not another client."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import pytest
import yaml

from hil_client.cli import main
from hil_client.protocol.rig import RigCommand, RigError
from hil_client.rigs.modbus import ModbusRig
from rig_emulator.emulator import CommandError
from rig_emulator.registers import MAP_DIR, load_map


def _map_file(tmp_path: Path, **changes: dict[str, Any]) -> Path:
    """The shipped map with some points (by name) changed, as a file."""
    data = yaml.safe_load((MAP_DIR / "wieselburg_bench.yaml").read_text())
    for device in data["devices"]:
        for p in device["points"]:
            p.update(changes.get(p["name"], {}))
    path = tmp_path / "narrow.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


FLOW_U16 = {"flow_setpoint": {"datatype": "uint16", "scale": 0.01}}  # at most 655.35 kg/h
# at most 327.67 s (int16 in hundredths): a few lockstep steps reach it
TIME_I16 = {"sim_time": {"datatype": "int16", "scale": 0.01}}


def test_run_refuses_a_setpoint_its_point_cannot_carry(serve, tmp_path, capsys) -> None:
    path = _map_file(tmp_path, **FLOW_U16)
    srv = serve(register_map=load_map(path))
    before = srv.values()["water_flow_setpoint_kg_h"]
    out = tmp_path / "r.csv"
    code = main(
        [
            "run",
            "stationary",  # 687 kg/h at full load of the 12 kW boiler
            "--boiler",
            "windhager_12kw",
            "--rig",
            f"modbus://127.0.0.1:{srv.port}",
            "--map",
            str(path),
            "--out",
            str(out),
            "--quiet",
        ]
    )
    err = capsys.readouterr().err
    assert code == 2, err
    assert "water_flow_setpoint_kg_h" in err and "0..655.35" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["narrow.yaml"]  # nothing written
    assert srv.values()["water_flow_setpoint_kg_h"] == before  # nor sent


def test_rig_refuses_what_its_point_cannot_carry_and_takes_its_end(serve, tmp_path) -> None:
    register_map = load_map(_map_file(tmp_path, **FLOW_U16))
    srv = serve(register_map=register_map)
    rig = ModbusRig(f"modbus://127.0.0.1:{srv.port}", register_map)
    try:
        with pytest.raises(CommandError, match=r"outside 0\.\.655\.35"):
            rig.apply(RigCommand(655.36, 55.0, True, False))
        rig.apply(RigCommand(655.35, 55.0, True, False))  # the end it carries goes out
        rig.advance(1.0)
        assert srv.values()["water_flow_setpoint_kg_h"] == pytest.approx(655.35, abs=1e-9)
    finally:
        rig.close()


def _steps_until_error(rig: ModbusRig, errors: list[str]) -> None:
    try:
        for _ in range(200):
            rig.advance(10.0)
    except RigError as exc:
        errors.append(str(exc))


@pytest.mark.parametrize("lockstep", [True, False])
def test_a_time_its_point_cannot_count_stops_the_run_naming_it(serve, tmp_path, lockstep) -> None:
    register_map = load_map(_map_file(tmp_path, **TIME_I16))
    srv = serve(register_map=register_map, lockstep=lockstep, speed=100.0)
    rig = ModbusRig(f"modbus://127.0.0.1:{srv.port}", register_map, reconnect_timeout_s=5.0)
    rig.apply(RigCommand(600.0, 55.0, True, False))
    errors: list[str] = []
    steps = threading.Thread(target=_steps_until_error, args=(rig, errors), daemon=True)
    steps.start()
    steps.join(timeout=60)  # 33 steps of 10 s; in real time x100 about 3.3 s of wall time
    alive = steps.is_alive()
    rig.close()
    assert not alive, "the rig waited for a time the map cannot count to"
    (error,) = errors
    assert "sim_time stands at 327.67 s" in error and "int16 x0.01" in error, error
    assert "another client" not in error
    assert rig.gaps[-1]["action"] == "abort"


@pytest.mark.parametrize(
    ("change", "carried"),
    [({"datatype": "uint16", "scale": 0.3}, "9.9 s"), ({"datatype": "uint16", "scale": 0.001}, "")],
)
def test_run_refuses_an_advance_its_point_cannot_carry(serve, tmp_path, capsys, change, carried):
    """A re-probe: lockstep_advance as uint16 x0.3 sent 9.9 s for 10 (x0.001 tops at
    65.5 s, under a 120-s step), and the run stopped blaming "another client". Refused
    before the first row, naming the point."""
    path = _map_file(tmp_path, lockstep_advance=change)
    srv = serve(register_map=load_map(path))
    step = "10" if carried else "120"
    protocol = tmp_path / "p.yaml"
    shipped = Path(__file__).parents[2] / "hil_client" / "protocol" / "definitions"
    text = (shipped / "stationary.yaml").read_text()
    protocol.write_text(text.replace("acquisition_period_s: 1", f"acquisition_period_s: {step}"))
    argv = ["run", str(protocol), "--boiler", "windhager_12kw", "--rig"]
    argv += [f"modbus://127.0.0.1:{srv.port}", "--map", str(path), "--out", str(tmp_path / "r.csv")]
    assert main([*argv, "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "its lockstep_advance point 'lockstep_advance'" in err and carried in err, err
    assert not (tmp_path / "r.csv").exists()
