"""The server through clients this project did not write: a small C program on libmodbus
(Debian libmodbus-dev, compiled here with gcc) and pyModbusTCP. Reads, writes and the spec's
exception codes as those libraries report them."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from tests.modbus_helpers import point

C_CLIENT = Path(__file__).parent / "c" / "libmodbus_client.c"
LIBMODBUS_HEADER = Path("/usr/include/modbus/modbus.h")


@pytest.fixture(scope="module")
def libmodbus_client(tmp_path_factory) -> Path:
    """The C client, compiled once; skipped with the reason when gcc or libmodbus is absent."""
    gcc = shutil.which("gcc") or shutil.which("cc")
    if gcc is None:
        pytest.skip("no C compiler (gcc/cc) found: the libmodbus interop test needs one")
    if not LIBMODBUS_HEADER.exists():
        pytest.skip("libmodbus-dev not installed (make tools installs it where apt-get works)")
    binary = tmp_path_factory.mktemp("libmodbus") / "libmodbus_client"
    build = subprocess.run(
        [gcc, "-Wall", "-o", str(binary), str(C_CLIENT), "-I/usr/include/modbus", "-lmodbus"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    if build.returncode != 0:
        pytest.skip(f"the libmodbus client does not build here: {build.stderr.strip()[:300]}")
    return binary


def test_libmodbus_client_reads_writes_and_gets_the_specs_exceptions(serve, libmodbus_client):
    srv = serve()
    model = srv.values()
    run = subprocess.run(
        [str(libmodbus_client), "127.0.0.1", str(srv.port)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    lines = dict(line.split("=", 1) for line in run.stdout.splitlines())
    assert run.returncode == 0, run.stdout + run.stderr
    # float32 ABCD, printed by the C client with 6 significant digits
    assert float(lines["water_flow_kg_h"]) == pytest.approx(model["water_flow_kg_h"], rel=1e-5)
    assert float(lines["flow_setpoint_kg_h"]) == 512.5
    assert float(lines["return_setpoint_C"]) == 55.5  # FC23: written before it is read
    assert lines["on_command"] == "1"
    after = srv.values()
    assert after["water_flow_setpoint_kg_h"] == 512.5
    assert after["return_setpoint_C"] == 55.5
    assert after["boiler_command"] == 1.0
    assert lines["unmapped_read"] == "illegal_data_address"
    assert lines["report_slave_id"] == "illegal_function"  # FC17 is not implemented: 01
    assert lines["unknown_unit"] == "gateway_target"
    assert lines["write_coil_0x1234"] == "8503"
    assert lines["read_126_registers"] == "8403"


def test_pymodbustcp_reads_writes_and_exceptions(serve):
    from pyModbusTCP.client import ModbusClient
    from pyModbusTCP.constants import (
        EXP_DATA_ADDRESS,
        EXP_DATA_VALUE,
    )
    from pyModbusTCP.constants import (
        EXP_GATEWAY_TARGET_DEVICE_FAILED_TO_RESPOND as EXP_GATEWAY_TARGET,
    )

    srv = serve()
    dev, set_temp = point(srv, "boiler_controller", "set_temp")
    c = ModbusClient(host="127.0.0.1", port=srv.port, unit_id=dev.unit_id, timeout=10)
    assert c.write_single_register(set_temp.address, 650)  # scaled int16: 65.0 C
    assert c.read_holding_registers(set_temp.address, 1) == [650]
    assert srv.values()["boiler_set_temp_C"] == pytest.approx(65.0)
    assert c.write_single_coil(0, True)
    assert c.read_coils(0, 1) == [True]
    assert not c.write_single_register(set_temp.address, 950)  # 95 C: outside 40..80
    assert c.last_except == EXP_DATA_VALUE
    assert srv.values()["boiler_set_temp_C"] == pytest.approx(65.0)
    assert c.read_input_registers(40, 2) is None
    assert c.last_except == EXP_DATA_ADDRESS
    c.unit_id = 42
    assert c.read_input_registers(0, 2) is None
    assert c.last_except == EXP_GATEWAY_TARGET
    c.close()
