"""Readings at their register's limit: a map whose type and scale cannot carry a reading's
value (the flue gas as int16 x0.001 tops out at 32.767 C) pinned it there for hours, the
log said 32.767, the phases were found from it and the balance was wrong, exit 0 (a
stranger's probe). Such readings are logged empty, and a warning and the meta say which."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from hil_client.analysis.logio import read_log
from hil_client.cli import main
from tests.hil_client.timed_protocol import timed_protocol

SHIPPED_MAP = Path(__file__).resolve().parents[3] / "register_maps" / "wieselburg_bench.yaml"
FLUE_GAS_POINT = "datatype: int16, scale: 0.01}"  # the flue gas's, as the shipped map has it
PROTOCOL = timed_protocol("pinned", [("peak", 100, 300)], cooling_1_s=120, cooling_2_after_t2_s=200)


def _shipped_map_with(tmp_path: Path, old: str, new: str) -> Path:
    """The shipped map with ``old`` (found there once: the map as this test knows it)
    replaced by ``new``."""
    text = SHIPPED_MAP.read_text()
    assert text.count(old) == 1, old
    path = tmp_path / f"map_{len(list(tmp_path.glob('map_*.yaml')))}.yaml"
    path.write_text(text.replace(old, new))
    return path


def _run(srv, register_map: Path, out: Path, tmp_path: Path) -> int:
    """``hil-client run`` of :data:`PROTOCOL` on ``srv`` with the client map given."""
    protocol = tmp_path / "pinned.yaml"
    protocol.write_text(PROTOCOL)
    rig = f"modbus://127.0.0.1:{srv.port}"
    argv = ["run", str(protocol), "--boiler", "windhager_12kw", "--quiet", "--rig", rig]
    return main([*argv, "--map", str(register_map), "--out", str(out)])


def test_a_reading_pinned_at_its_registers_limit_is_logged_empty(serve_process, tmp_path, capsys):
    narrow = _shipped_map_with(tmp_path, FLUE_GAS_POINT, "datatype: int16, scale: 0.001}")
    out = tmp_path / "pinned.csv"
    assert _run(serve_process("--lockstep", "--map", str(narrow)), narrow, out, tmp_path) == 0
    err = capsys.readouterr().err
    flue_gas = read_log(out)["flue_gas_temp_C"]
    # the room's flue gas (about 20 C) is a reading; a firing boiler's is beyond the limit
    assert not np.any(flue_gas == 32.767)
    assert np.isnan(flue_gas).sum() > 100 and np.nanmax(flue_gas) < 32.767
    said = "flue_gas_temp_C (unit 4 point 'flue_gas_temp' at 32.767"
    assert said in err, err
    meta = json.loads(out.with_name("pinned.meta.json").read_text())
    assert any(said in note for note in meta["notes"]), meta["notes"]


FID = """  - name: fid
    unit_id: 3
    instrument: flame-ionisation detector (organic gaseous carbon)
    points:
      - {name: OGC, signal: flue_gas_OGC_ppm, table: input, address: 0, datatype: int16,
         scale: 0.1}

"""


def test_a_bench_without_an_fid_runs_with_that_column_empty(serve_process, tmp_path, capsys):
    """A stranger's probe: a lab without an FID (the map without unit 3) could not run at
    all ("no point for 'flue_gas_OGC_ppm' (the Modbus rig needs it)"), though the column
    is beyond CONTRACT section 3. The run completes, the column empty, and the meta says
    why; a reading the format requires is still refused."""
    no_fid = _shipped_map_with(tmp_path, FID, "")
    srv = serve_process("--lockstep", "--map", str(no_fid))
    out = tmp_path / "no_fid.csv"
    assert _run(srv, no_fid, out, tmp_path) == 0
    log = read_log(out)
    assert np.all(np.isnan(log["flue_gas_OGC_ppm"]))
    assert np.all(np.isfinite(log["flue_gas_O2_pct"]))
    meta = json.loads(out.with_name("no_fid.meta.json").read_text())
    assert "the map has no point for flue_gas_OGC_ppm: empty columns" in meta["notes"]
    assert meta["complete"] is True
    text = SHIPPED_MAP.read_text()
    probe = text.split("  - name: flue_gas_probe")[1].split("  - name:")[0]
    no_probe = _shipped_map_with(tmp_path, "  - name: flue_gas_probe" + probe, "")
    capsys.readouterr()
    assert _run(srv, no_probe, tmp_path / "x.csv", tmp_path) == 2
    assert "no point for 'flue_gas_temp_C'" in capsys.readouterr().err
