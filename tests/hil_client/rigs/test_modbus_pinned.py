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


def test_a_reading_pinned_at_its_registers_limit_is_logged_empty(serve_process, tmp_path, capsys):
    text = SHIPPED_MAP.read_text()
    assert text.count(FLUE_GAS_POINT) == 1  # (the shipped map as this test knows it)
    narrow = tmp_path / "narrow.yaml"
    narrow.write_text(text.replace(FLUE_GAS_POINT, "datatype: int16, scale: 0.001}"))
    protocol = tmp_path / "pinned.yaml"
    protocol.write_text(PROTOCOL)
    srv = serve_process("--lockstep", "--map", str(narrow))
    out = tmp_path / "pinned.csv"
    rig = f"modbus://127.0.0.1:{srv.port}"
    argv = ["run", str(protocol), "--boiler", "windhager_12kw", "--quiet", "--rig", rig]
    assert main([*argv, "--map", str(narrow), "--out", str(out)]) == 0
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


def test_a_bench_without_an_fid_runs_with_that_column_empty(serve_process, tmp_path):
    """A stranger's probe: a lab without an FID (the map without unit 3) could not run at
    all ("no point for 'flue_gas_OGC_ppm' (the Modbus rig needs it)"), though the column
    is beyond CONTRACT section 3. The run completes, the column empty, and the meta says
    why; a reading the format requires is still refused."""
    text = SHIPPED_MAP.read_text()
    assert text.count(FID) == 1  # (the shipped map as this test knows it)
    no_fid = tmp_path / "no_fid.yaml"
    no_fid.write_text(text.replace(FID, ""))
    protocol = tmp_path / "pinned.yaml"
    protocol.write_text(PROTOCOL)
    srv = serve_process("--lockstep", "--map", str(no_fid))
    out = tmp_path / "no_fid.csv"
    rig = f"modbus://127.0.0.1:{srv.port}"
    argv = ["run", str(protocol), "--boiler", "windhager_12kw", "--quiet", "--rig", rig]
    assert main([*argv, "--map", str(no_fid), "--out", str(out)]) == 0
    log = read_log(out)
    assert np.all(np.isnan(log["flue_gas_OGC_ppm"]))
    assert np.all(np.isfinite(log["flue_gas_O2_pct"]))
    meta = json.loads(out.with_name("no_fid.meta.json").read_text())
    assert "the map has no point for flue_gas_OGC_ppm: empty columns" in meta["notes"]
    assert meta["complete"] is True
    flue_gas_probe = text.split("  - name: flue_gas_probe")[1].split("  - name:")[0]
    no_probe = tmp_path / "no_probe.yaml"
    no_probe.write_text(text.replace("  - name: flue_gas_probe" + flue_gas_probe, ""))
    assert main([*argv, "--map", str(no_probe), "--out", str(tmp_path / "x.csv")]) == 2
