"""A small acquisition script, as a lab writes one: poll the bench's instruments over
Modbus TCP with pyModbusTCP and write one CSV row per acquisition.

It is the *system under test* of ``test_acquisition.py``, which runs it against the
emulator with every fault kind. What it does about faults, as acquisition software should:

- a unit that does not answer within ``timeout_s`` (or answers an exception) leaves its
  columns empty in that row (never the previous value) and is named in the ``errors``
  column (``2:timeout``, ``5:exception 06``); the connection is closed and reopened, so a
  late reply is never taken for the next request's;
- an invalid reading is empty: NaN (floats) or the integer invalid code (0x8000 for int16,
  0x80000000 for int32), or an analyser reading while its status word says "not measuring";
- a connection the server closed is reopened and the request sent again, once.

Usage: ``python acquire.py HOST PORT OUT.csv ROWS [PERIOD_S]`` (real time), or
:class:`Acquisition` from Python (the test steps a lockstep emulator between rows).
"""

from __future__ import annotations

import csv
import math
import struct
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

from pyModbusTCP.client import ModbusClient
from pyModbusTCP.constants import MB_RECV_ERR, MB_SEND_ERR, MB_SOCK_CLOSE_ERR


@dataclass(frozen=True)
class Channel:
    """One value of one instrument: where it is and how it is encoded."""

    column: str
    address: int  # offset in the unit's input registers (or discrete inputs)
    kind: str  # f32 (ABCD), f32_cdab, f64, u16, i16, i32, bit
    scale: float = 1.0


#: unit ID -> channels (addresses from the bench's register map reference)
UNITS: dict[int, tuple[Channel, ...]] = {
    1: (
        Channel("water_flow_kg_h", 0, "f32"),
        Channel("water_in_temp_C", 2, "f32"),
        Channel("water_out_temp_C", 4, "f32"),
    ),
    2: (
        Channel("flue_gas_O2_pct", 0, "f32_cdab"),
        Channel("flue_gas_CO2_pct", 2, "f32_cdab"),
        Channel("flue_gas_CO_ppm", 4, "f32_cdab"),
        Channel("analyser_status", 10, "u16"),
    ),
    4: (Channel("flue_gas_temp_C", 0, "i16", 0.01),),
    5: (Channel("balance_mass_kg", 0, "i32", 0.001), Channel("balance_stable", 0, "bit")),
    6: (Channel("electric_power_W", 0, "f32"),),
}
_CLOSED = (MB_SEND_ERR, MB_RECV_ERR, MB_SOCK_CLOSE_ERR)  # the server closed the connection
SIM_CONTROL_UNIT = 100  # the emulator's own clock (a real bench has a PC clock instead)
ANALYSER_COLUMNS = ("flue_gas_O2_pct", "flue_gas_CO2_pct", "flue_gas_CO_ppm")
COLUMNS = ("sim_time_s", *(c.column for chans in UNITS.values() for c in chans), "errors")
_WIDTH = {"f32": 2, "f32_cdab": 2, "f64": 4, "u16": 1, "i16": 1, "i32": 2}


def _decode(channel: Channel, words: list[int]) -> float | None:
    """The value, or None when the instrument says it is invalid."""
    kind = channel.kind
    if kind in ("f32", "f32_cdab"):
        if kind == "f32_cdab":
            words = words[::-1]
        value = struct.unpack(">f", struct.pack(">2H", *words))[0]
        return None if math.isnan(value) else value
    if kind == "f64":
        return struct.unpack(">d", struct.pack(">4H", *words))[0]
    if kind == "u16":
        return float(words[0])
    if kind == "i16":
        raw = struct.unpack(">h", struct.pack(">H", words[0]))[0]
        return None if raw == -0x8000 else raw * channel.scale
    raw = struct.unpack(">i", struct.pack(">2H", *words))[0]  # i32
    return None if raw == -0x80000000 else raw * channel.scale


class Acquisition:
    """Reads every channel once per :meth:`row`."""

    def __init__(self, host: str, port: int, timeout_s: float = 1.0) -> None:
        self.client = ModbusClient(host=host, port=port, timeout=timeout_s, auto_open=True)

    def _read(self, unit: int, table: str, address: int, count: int) -> tuple[list | None, str]:
        """Registers (or bits) and '' on success, else None and what went wrong. A
        connection the server closed is reopened and the request sent once more."""
        self.client.unit_id = unit
        read = (
            self.client.read_discrete_inputs
            if table == "bits"
            else self.client.read_input_registers
        )
        words = read(address, count)
        if words is None and self.client.last_error in _CLOSED:
            self.client.close()
            words = read(address, count)
        if words is not None:
            return list(words), ""
        if self.client.last_except:
            return None, f"exception {self.client.last_except:02d}"
        self.client.close()  # a late reply must not be taken for the next request's
        return None, "timeout" if "timeout" in self.client.last_error_as_txt.lower() else (
            self.client.last_error_as_txt or "error"
        )

    def row(self) -> dict[str, float | str | None]:
        """One acquisition: every column (None = empty) and ``errors``."""
        out: dict[str, float | str | None] = dict.fromkeys(COLUMNS)
        errors = []
        words, error = self._read(SIM_CONTROL_UNIT, "registers", 0, 4)
        if words is not None:
            out["sim_time_s"] = struct.unpack(">d", struct.pack(">4H", *words))[0]
        for unit, channels in UNITS.items():
            registers = [c for c in channels if c.kind != "bit"]
            bits = [c for c in channels if c.kind == "bit"]
            if registers:
                start = min(c.address for c in registers)
                end = max(c.address + _WIDTH[c.kind] for c in registers)
                words, error = self._read(unit, "registers", start, end - start)
                if words is None:
                    errors.append(f"{unit}:{error}")
                else:
                    for c in registers:
                        at = c.address - start
                        out[c.column] = _decode(c, words[at : at + _WIDTH[c.kind]])
            for c in bits:
                words, error = self._read(unit, "bits", c.address, 1)
                if words is None:
                    errors.append(f"{unit}:{error}")
                else:
                    out[c.column] = 1.0 if words[0] else 0.0
        status = out["analyser_status"]
        if isinstance(status, float) and not int(status) & 1:  # bit 0: measuring
            for column in ANALYSER_COLUMNS:
                out[column] = None
        out["errors"] = ";".join(errors)
        return out

    def run(
        self, path: str, rows: int, between: Callable[[], None] = lambda: None
    ) -> list[dict[str, float | str | None]]:
        """Acquire ``rows`` rows into the CSV ``path``, calling ``between`` before each."""
        table = []
        with open(path, "w", newline="") as fh:
            writer = csv.DictWriter(fh, COLUMNS)
            writer.writeheader()
            for _ in range(rows):
                between()
                row = self.row()
                writer.writerow({k: "" if v is None else v for k, v in row.items()})
                fh.flush()
                table.append(row)
        self.client.close()
        return table


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) not in (4, 5):
        print(__doc__.split("Usage: ")[1].split("\n\n")[0], file=sys.stderr)
        return 2
    try:  # one line for a bad number, as the project's own commands (a traceback: a probe)
        host, port, out, rows = args[0], int(args[1]), args[2], int(args[3])
        period_s = float(args[4]) if len(args) == 5 else 1.0
    except ValueError as exc:
        print(f"acquire.py: error: {exc}", file=sys.stderr)
        return 2
    Acquisition(host, port).run(out, rows, lambda: time.sleep(period_s))
    return 0


if __name__ == "__main__":
    sys.exit(main())
