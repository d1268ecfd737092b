"""Register maps: the shipped map, the codec, validation of broken maps, the reference."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from rig_emulator.registers import (
    MAP_DIR,
    MapError,
    decode,
    encode,
    invalid_value,
    load_map,
    map_from_mapping,
    precision,
    reading_range,
    run_decoder,
    run_encoder,
)
from rig_emulator.registers.reference import markdown
from rig_emulator.registers.schema import Point
from rig_emulator.signals import MEASURED

REPO = Path(__file__).resolve().parents[3]


def _point(datatype: str, order: str = "ABCD", scale: float = 1.0, offset: float = 0.0) -> Point:
    return Point(
        "p",
        "room_temp_C",
        "input",
        0,
        datatype,
        order,
        scale,
        offset,
        "C",
        "r",
        -math.inf,
        math.inf,
        "",
    )


def test_shipped_map_has_every_instrument_and_varied_encodings():
    m = load_map()
    names = {d.name for d in m.devices}
    assert names == {
        "bench_plc",
        "flue_gas_analyser",
        "fid",
        "flue_gas_probe",
        "balance",
        "power_meter",
        "boiler_controller",
        "sim_control",
        "truth",
    }
    points = [p for d in m.devices for p in d.points]
    assert {p.signal for p in points} >= set(MEASURED)  # every measured signal is published
    assert any(p.word_order == "CDAB" and p.datatype == "float32" for p in points)
    assert any(p.datatype == "int16" and p.scale != 1.0 for p in points)
    assert any(p.datatype == "float64" for p in points)
    assert any(p.datatype == "uint32" for p in points)


@pytest.mark.parametrize("datatype", ["float32", "float64"])
@pytest.mark.parametrize("order", ["ABCD", "CDAB"])
def test_float_round_trip(datatype, order):
    p = _point(datatype, order)
    for value in np.random.default_rng(1).normal(0, 1e3, 200):
        assert abs(decode(p, encode(p, value)) - value) <= precision(p, value)


@pytest.mark.parametrize("datatype", ["int16", "uint16", "int32", "uint32"])
@pytest.mark.parametrize("order", ["ABCD", "CDAB"])
def test_scaled_integer_round_trip_and_saturation(datatype, order):
    p = _point(datatype, order, scale=0.01, offset=20.0)
    for value in (20.0, 20.004, 25.37, 300.0):
        assert abs(decode(p, encode(p, value)) - value) <= 0.005 + 1e-12
    # saturated at the type's ends short of its invalid code (the most negative value if
    # signed, the largest if unsigned), however far beyond: infinities too
    lo, hi = {"int16": (-(2**15) + 1, 2**15 - 1), "uint16": (0, 2**16 - 2),
              "int32": (-(2**31) + 1, 2**31 - 1), "uint32": (0, 2**32 - 2)}[datatype]  # fmt: skip
    for far in (1e12, math.inf):
        top, bottom = decode(p, encode(p, far)), decode(p, encode(p, -far))
        assert (bottom, top) == pytest.approx((lo * 0.01 + 20.0, hi * 0.01 + 20.0))
    # no reading (NaN, a dropout) takes the invalid code: it read as raw 0 (20.00 here), a
    # reading, and a signal on an int16 and a uint16 at once got the first one's code
    invalid = {"int16": 0x8000, "uint16": 0xFFFF, "int32": 0x8000, "uint32": 0xFFFF}[datatype]
    assert encode(p, math.nan)[0 if order == "ABCD" else -1] == invalid
    assert decode(p, encode(p, math.nan)) == pytest.approx(invalid_value(p))


@pytest.mark.parametrize(("datatype", "top"), [("uint16", 0xFFFF), ("uint32", 0xFFFFFFFF)])
def test_a_counter_uses_its_types_whole_range(datatype, top):
    """Only a reading keeps a code for no reading: the lockstep counter at 65535 was served
    65534, and every lockstep client stopped there (its 65,535th step)."""
    counter = replace(_point(datatype), signal="lockstep_counter")
    assert decode(counter, encode(counter, top)) == top
    assert decode(counter, encode(counter, top + 5)) == top  # beyond: clipped at the end
    assert invalid_value(counter) is None and reading_range(counter) == (0, top)


def test_word_orders_are_mirror_images():
    a, b = _point("float32", "ABCD"), _point("float32", "CDAB")
    assert encode(a, 6.123) == encode(b, 6.123)[::-1]
    assert encode(a, 1.0) == [0x3F80, 0x0000]  # IEEE 754 of 1.0, high word first


def _mixed_run() -> list[Point]:
    """A contiguous run mixing every datatype and both word orders."""
    kinds = [("float32", "CDAB"), ("float32", "CDAB"), ("int16", "ABCD"), ("float64", "ABCD"),
             ("uint32", "CDAB"), ("float32", "ABCD"), ("bool", "ABCD"), ("int32", "ABCD"),
             ("uint16", "CDAB"), ("float64", "CDAB")]  # fmt: skip
    run, address = [], 0
    for i, (datatype, order) in enumerate(kinds):
        p = _point(datatype, order, scale=0.01 if "int" in datatype else 1.0, offset=3.0)
        p = replace(p, name=f"p{i}", signal=f"s{i}", address=address)
        run.append(p)
        address += p.width
    return run


def test_run_encoder_and_decoder_equal_the_points_one_by_one():
    runs = [_mixed_run()] + [
        list(device.table(table))
        for device in load_map().devices
        for table in ("input", "holding", "coil", "discrete")
        if device.table(table)
    ]
    rng = np.random.default_rng(3)
    for run in runs:
        encode_run, decode_run = run_encoder(run), run_decoder(run)
        for _ in range(20):
            values = {p.signal: float(rng.normal(0, 500)) for p in run}
            values[run[0].signal] = math.nan if rng.random() < 0.2 else values[run[0].signal]
            want = [r for p in run for r in encode(p, values[p.signal])]
            assert encode_run(values) == want, [p.name for p in run]
            decoded = [decode(p, encode(p, values[p.signal])) for p in run]
            got = decode_run(want)
            assert np.allclose(got, decoded, equal_nan=True, rtol=0, atol=0), [p.name for p in run]


def _broken(mutate) -> dict:
    data = yaml.safe_load((MAP_DIR / "wieselburg_bench.yaml").read_text())
    mutate(data)
    return data


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (
            lambda d: d["devices"][0]["points"][1].update(address=1),
            "device 'bench_plc' point 'return_temp': address 1 in table 'input' overlaps point "
            "'water_flow'",
        ),
        (
            lambda d: d["devices"][1]["points"][0].update(signal="nope"),
            "device 'flue_gas_analyser' point 'O2': unknown signal 'nope'",
        ),
        (
            lambda d: d["devices"][2]["points"][0].update(datatype="int8"),
            "device 'fid' point 'OGC': bad type 'int8'",
        ),
        (
            lambda d: d["devices"][4]["points"][1].update(datatype="uint16"),
            "device 'balance' point 'stable': bad type 'uint16' for table 'discrete'",
        ),
        (
            lambda d: d["devices"][0]["points"][0].update(access="rw"),
            "point 'water_flow': writable points live in 'holding' or 'coil'",
        ),
        (
            lambda d: d["devices"][1].update(unit_id=1),
            "device 'flue_gas_analyser': unit_id 1 already used by 'bench_plc'",
        ),
        (
            lambda d: d["devices"][0]["points"][7].update(max=1e6),
            "point 'flow_setpoint': range 0..1e+06 exceeds",
        ),
        (
            lambda d: d["devices"][0]["points"][0].update(scale=0.5),
            "'scale'/'offset' apply to integer types only",
        ),
        (  # an integer of 400 digits has no float (OverflowError, a traceback: a probe)
            lambda d: d["devices"][0]["points"][7].update(max=10**400),
            "'max' must be a finite number, got 10000000000000000000...",
        ),
        # a stranger's probe: free text of another type was printed as such ([1, 2]), a
        # device named 17 was "missing required key 'name'"
        (
            lambda d: d["devices"][1].update(instrument=[1, 2]),
            "device 'flue_gas_analyser': 'instrument' must be text, got a list",
        ),
        (
            lambda d: d["devices"][0].update(name=17),
            "devices[0]: 'name' must be a non-empty text, got 17",
        ),
        (
            lambda d: d.update(description={"a": 1}),
            "'description' must be text, got a dict",
        ),
    ],
)
def test_broken_maps_name_file_device_and_point(mutate, message):
    with pytest.raises(MapError) as info:
        map_from_mapping(_broken(mutate), "maps/x.yaml")
    assert str(info.value).startswith("maps/x.yaml: ")
    assert message in str(info.value)


def test_committed_reference_is_generated_from_the_map():
    committed = (REPO / "docs" / "register_map.md").read_text()
    assert committed == markdown(load_map()), "run: rig-emulator map-doc --out docs/register_map.md"


def test_register_numbers_from_a_vendor_sheet_are_decimal(tmp_path):
    """A stranger's probe: ``unit_id: 010`` served unit 8 and ``address: 0100`` address 64
    (YAML 1.1 octal); ``address: 1:10`` address 70 (base 60). Decimal, or refused."""
    from rig_emulator.registers import load_map

    text = (MAP_DIR / "wieselburg_bench.yaml").read_text()
    data = yaml.safe_load(text)
    data["devices"] = data["devices"][:1]
    data["devices"][0]["points"] = data["devices"][0]["points"][:1]
    path = tmp_path / "m.yaml"
    path.write_text(
        yaml.safe_dump(data)
        .replace("unit_id: 1\n", "unit_id: 010\n")
        .replace("address: 0\n", "address: 0100\n")
    )
    served = load_map(str(path))
    assert served.devices[0].unit_id == 10 and served.devices[0].points[0].address == 100
    path.write_text(path.read_text().replace("address: 0100\n", "address: 1:10\n"))
    with pytest.raises(MapError, match="'address' must be an integer"):
        load_map(str(path))
