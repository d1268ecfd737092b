"""A reading its point's type cannot carry is served at the type's limit, and the server
says so once per point (a stranger's probe: a balance as int16 x0.001 read 32.767 kg of
250 kg, a draught of -12 Pa as uint16 read 0, and nothing said so)."""

from __future__ import annotations

import logging
from typing import Any

import yaml

from rig_emulator.registers import MAP_DIR, map_from_mapping
from tests.modbus_helpers import ADVANCE, client, point, read_point, start_boiler, write


def _narrowed(**changes: dict[str, Any]):
    """The shipped map with some points (by name) changed."""
    data = yaml.safe_load((MAP_DIR / "wieselburg_bench.yaml").read_text())
    for device in data["devices"]:
        for p in device["points"]:
            p.update(changes.get(p["name"], {}))
    return map_from_mapping(data, source="narrowed.yaml")


def _clamps(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if "saturated at" in r.getMessage()]


def test_a_clamped_reading_is_warned_once_per_point(serve, caplog) -> None:
    caplog.set_level(logging.WARNING, logger="rig_emulator.serve")
    srv = serve(
        register_map=_narrowed(
            mass={"datatype": "int16", "scale": 0.001},
            draught={"datatype": "uint16", "scale": 0.1},
        )
    )
    mass = srv.values()["balance_mass_kg"]
    draught = srv.values()["chimney_draught_Pa"]
    assert mass > 32.767 and draught < 0.0  # the plant: beyond what the points carry
    messages = _clamps(caplog)
    assert len(messages) == 2, messages
    by_point = {m.split("'")[1]: m for m in messages}
    assert f"publishes {mass:g} kg" in by_point["mass"]
    assert "int16 x0.001" in by_point["mass"] and "saturated at 32.767 kg" in by_point["mass"]
    assert "uint16 x0.1" in by_point["draught"] and "saturated at 0 Pa" in by_point["draught"]
    c = client(srv.port)
    try:
        assert read_point(c, *point(srv, "balance", "mass")) == 32.767  # served, clamped
        for _ in range(3):
            assert not write(c, srv, *ADVANCE, 10).isError()
    finally:
        c.close()
    assert len(_clamps(caplog)) == 2  # once per point, not once per publish


def test_the_shipped_map_clamps_nothing_in_a_firing(serve, caplog) -> None:
    caplog.set_level(logging.WARNING, logger="rig_emulator.serve")
    srv = serve()
    c = client(srv.port)
    try:
        start_boiler(c, srv, seconds=1800)
    finally:
        c.close()
    assert srv.values()["firing_power_kW"] > 0.0  # it fired
    assert _clamps(caplog) == []


def test_an_operator_write_its_point_cannot_carry_is_refused(serve) -> None:
    """The dashboard's write (``write_signal``) encodes the value: 687 kg/h went out as
    655.35 on a uint16 x0.01 and was accepted."""
    srv = serve(register_map=_narrowed(flow_setpoint={"datatype": "uint16", "scale": 0.01}))
    before = srv.values()["water_flow_setpoint_kg_h"]
    refused = srv.call(srv.server.write_signal("water_flow_setpoint_kg_h", 687.0))
    assert refused is not None and "0..655.35" in refused and "03" in refused
    assert srv.values()["water_flow_setpoint_kg_h"] == before
    assert srv.call(srv.server.write_signal("water_flow_setpoint_kg_h", 655.35)) is None
    assert srv.values()["water_flow_setpoint_kg_h"] == 655.35
