"""Helpers for tests that talk to the emulator over Modbus (pymodbus client)."""

from __future__ import annotations

from pathlib import Path

from pymodbus.client import ModbusTcpClient

from rig_emulator.registers import decode, encode

ADVANCE = ("sim_control", "lockstep_advance")


def client(port: int, timeout_s: float = 5.0) -> ModbusTcpClient:
    c = ModbusTcpClient("127.0.0.1", port=port, timeout=timeout_s, retries=0)
    assert c.connect()
    return c


def point(srv, device: str, name: str):
    dev = srv.map.device(device)
    return dev, next(p for p in dev.points if p.name == name)


def write(c: ModbusTcpClient, srv, device: str, name: str, value: float):
    dev, p = point(srv, device, name)
    if p.table == "coil":
        return c.write_coil(p.address, bool(value), device_id=dev.unit_id)
    return c.write_registers(p.address, encode(p, value), device_id=dev.unit_id)


def read_point(c: ModbusTcpClient, dev, p) -> float:
    fn = {
        "input": c.read_input_registers,
        "holding": c.read_holding_registers,
        "coil": c.read_coils,
        "discrete": c.read_discrete_inputs,
    }[p.table]
    r = fn(p.address, count=p.width, device_id=dev.unit_id)
    assert not r.isError(), (dev.name, p.name, r)
    return decode(p, r.bits[:1] if p.table in ("coil", "discrete") else r.registers)


def start_boiler(c, srv, seconds: float = 1800) -> None:
    for name, value in (("flow_setpoint", 600.0), ("return_setpoint", 55.0)):
        assert not write(c, srv, "bench_plc", name, value).isError()
    assert not write(c, srv, "boiler_controller", "on_command", 1).isError()
    assert not write(c, srv, *ADVANCE, seconds).isError()


def encrypted_copy(key: Path, out: Path) -> Path:
    """``key`` (PEM, unencrypted) written to ``out`` protected by a passphrase."""
    from cryptography.hazmat.primitives import serialization

    private = serialization.load_pem_private_key(key.read_bytes(), None)
    out.write_bytes(
        private.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.BestAvailableEncryption(b"secret"),
        )
    )
    return out
