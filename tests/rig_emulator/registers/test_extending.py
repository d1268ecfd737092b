"""docs/extending.md's recipes, proved: an instrument added from a map alone is served over
Modbus with the same reading as the bench's own instrument, and an encoding is one line."""

from __future__ import annotations

import subprocess
import sys

import pytest
import yaml

from rig_emulator.registers import decode, encode, precision
from rig_emulator.registers.datatypes import DATATYPES
from rig_emulator.registers.schema import MAP_DIR, _point, map_from_mapping
from tests.modbus_helpers import ADVANCE, client, point, read_point, start_boiler, write

# A second flue-gas thermometer and a second balance on a unit of their own, with encodings
# the shipped map does not use for these signals (scaled int32, word-swapped; uint32 grams).
EXTRA_DEVICE = {
    "name": "second_probe",
    "unit_id": 42,
    "instrument": "added by a lab from its map alone",
    "word_order": "CDAB",
    "points": [
        {"name": "flue_temp_mK", "signal": "flue_gas_temp_C", "table": "holding",
         "address": 100, "datatype": "int32", "scale": 0.001},
        {"name": "mass_g", "signal": "balance_mass_kg", "table": "input", "address": 7,
         "datatype": "uint32", "scale": 0.001, "word_order": "ABCD"},
    ],
}  # fmt: skip


def test_an_instrument_added_in_the_map_alone_is_served(serve):
    data = yaml.safe_load((MAP_DIR / "wieselburg_bench.yaml").read_text())
    data["devices"].append(EXTRA_DEVICE)
    srv = serve(register_map=map_from_mapping(data, "extended map"))
    c = client(srv.port, timeout_s=30.0)  # an 1800-s advance on a loaded machine
    try:
        start_boiler(c, srv)
        assert not write(c, srv, *ADVANCE, 1800).isError()
        for own, added in (("flue_gas_temp", "flue_temp_mK"), ("mass", "mass_g")):
            dev_o, p_o = point(srv, "flue_gas_probe" if own == "flue_gas_temp" else "balance", own)
            dev_a, p_a = point(srv, "second_probe", added)
            ours, theirs = read_point(c, dev_o, p_o), read_point(c, dev_a, p_a)
            # the same reading, to the two encodings' precision (half a step of each)
            tol = precision(p_o, ours) + precision(p_a, theirs) + 1e-9
            assert theirs == pytest.approx(ours, abs=tol), added
            assert theirs != 0.0
    finally:
        c.close()


def test_a_new_encoding_is_one_declaration():
    """Registering an int64 in DATATYPES alone makes maps accept it and the codec carry it
    (run in a fresh interpreter so the shipped declaration stays untouched here)."""
    code = """
from rig_emulator.registers.datatypes import DATATYPES, DataType
DATATYPES["int64"] = DataType("int64", "q")
from rig_emulator.registers import decode, encode, precision
from rig_emulator.registers.schema import _point
p = _point({"signal": "balance_mass_kg", "table": "input", "address": 0,
            "datatype": "int64", "scale": 1e-6}, "test", "CDAB")
regs = encode(p, 251.123456)
assert p.width == 4 and len(regs) == 4, regs
print(decode(p, regs))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert float(out.stdout) == pytest.approx(251.123456, abs=1e-6)
    assert "int64" not in DATATYPES  # the shipped set is unchanged


def test_every_declared_encoding_round_trips():
    for name, datatype in DATATYPES.items():
        if datatype.is_bit:
            continue
        data = {"signal": "flue_gas_temp_C", "table": "input", "address": 0, "datatype": name}
        if not datatype.is_float:
            data["scale"] = 0.1
        p = _point(data, "test", "ABCD")
        assert decode(p, encode(p, 123.4)) == pytest.approx(123.4, abs=0.05), name
