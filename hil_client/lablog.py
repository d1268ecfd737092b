"""Writing the lab log (CONTRACT section 3) and its meta file.

Each row is written and flushed as soon as it is acquired, so a killed client leaves a valid
CSV holding every row acquired so far. A missing value (NaN) is an empty field. The column
``rig_epoch`` (optional, CONTRACT section 7) says which plant a row comes from: 0, then one
higher after each break (a restarted or reset server the run went on from). A text field
holding a comma, a quote or a line break (protocol files refuse such names; a rig or a
caller might not) is quoted as RFC 4180 says, so every row keeps its width.
"""

from __future__ import annotations

import contextlib
import csv
import io
import itertools
import math
import os
import re
from operator import itemgetter
from pathlib import Path
from typing import Any

from hil_client.jsonio import strict_json
from hil_client.protocol.runner import LOG_COLUMNS, Row
from rig_emulator.atomic import replacing

#: Decimals written per column: finer than any instrument's resolution.
DECIMALS = {
    "time_s": 3,
    "water_flow_kg_h": 4,
    "flue_gas_O2_pct": 5,
    "flue_gas_CO2_pct": 5,
    "flue_gas_CO_ppm": 3,
    "flue_gas_velocity_m_s": 5,
    "chimney_draught_Pa": 3,
    "balance_mass_kg": 5,
    "ambient_pressure_hPa": 3,
    "relative_humidity_pct": 3,
    "electric_power_W": 4,
    "water_flow_setpoint_kg_h": 4,
    "boiler_on": 0,
    "flue_gas_NOx_ppm": 3,
    "flue_gas_SO2_ppm": 3,
    "flue_gas_OGC_ppm": 3,
    "rig_epoch": 0,
}
_TEXT = {"phase", "sequence"}
_TEXT_OF = itemgetter(*(i for i, column in enumerate(LOG_COLUMNS) if column in _TEXT))
_NEEDS_QUOTES = re.compile(r'[,"\r\n]')


_MISSING = re.compile(r"(?<=,)(?:nan|-?inf)(?=,|$)")


#: Format of each column's number, None for a text column (temperatures: 10 uK by default).
_FORMATS = tuple(None if c in _TEXT else f"%.{DECIMALS.get(c, 5)}f" for c in LOG_COLUMNS)


def _row_format() -> str:
    return ",".join("%s" if f is None else f for f in _FORMATS) + "\n"


class LabLogWriter:
    """CSV writer of lab-log rows, one line per row written through to the file at once. A
    row that cannot be written whole (a full disk) is taken back out, so the log ends on
    its last whole row (a probe: the rows before were kept, and half of the last one)."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = self.path.open("wb", buffering=0)
        self._size = 0  # bytes of whole lines in the file
        self._write(",".join(LOG_COLUMNS) + "\n")
        self._format = _row_format()
        self._text: tuple[object, ...] = ()  # the last row's text fields, and whether plain
        self._plain = True
        self.rows = 0

    def __call__(self, row: Row) -> None:
        text = _TEXT_OF(row)
        if text != self._text:
            self._text = text
            self._plain = not any(_NEEDS_QUOTES.search(str(v)) for v in text)
        if self._plain:
            line = self._format % row
            if "nan" in line or "inf" in line:
                line = _MISSING.sub("", line)
        else:
            line = self._quoted(row)
        self._write(line)
        self.rows += 1

    def _write(self, line: str) -> None:
        """Write ``line`` whole, or take what went of it back out and raise the error."""
        data = memoryview(line.encode("utf-8"))
        done = 0
        try:
            while done < len(data):
                done += self._file.write(data[done:]) or 0
        except OSError:
            with contextlib.suppress(OSError):
                os.ftruncate(self._file.fileno(), self._size)
            raise
        self._size += done

    def _quoted(self, row: Row) -> str:
        """The row through :mod:`csv`: its text fields quoted, a missing number empty."""
        fields = [
            str(v) if fmt is None else (fmt % v if math.isfinite(v) else "")  # type: ignore[arg-type]
            for fmt, v in zip(_FORMATS, row, strict=True)
        ]
        buffer = io.StringIO()
        csv.writer(buffer, lineterminator="\n").writerow(fields)
        return buffer.getvalue()

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> LabLogWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def meta_path(log_path: Path) -> Path:
    """``NAME.meta.json`` beside ``NAME.csv``."""
    log_path = Path(log_path)
    return log_path.with_name(log_path.stem + ".meta.json")


def same_companions(log_path: Path) -> list[Path]:
    """The other names of a log beside ``log_path`` that share its meta file and Modbus
    events file: its ``.csv`` in every other case (``NAME.CSV``, ``NAME.Csv``, ...), as
    both are named from the stem (a stranger's probe: runs writing ``s.csv`` and ``s.CSV``
    wrote one ``s.meta.json``)."""
    log_path = Path(log_path)
    if log_path.suffix.lower() != ".csv":
        return []
    spellings = ("." + "".join(c) for c in itertools.product("cC", "sS", "vV"))
    return [log_path.with_suffix(s) for s in spellings if s != log_path.suffix]


def write_meta(log_path: Path, meta: dict[str, Any]) -> Path:
    """Write the meta file beside the log, atomically: a temporary file, flushed to disk,
    then renamed over the old one (``os.replace``), so a reader or a run killed at any
    moment sees either the previous or the new file whole. ``hil-client run`` calls this
    at the start, at each phase mark and each gap, and at the end."""
    path = meta_path(log_path)
    with replacing(path) as tmp, tmp.open("w", encoding="utf-8") as fh:  # (a symlinked
        fh.write(strict_json(meta, indent=2) + "\n")  # meta file was replaced by a plain
        fh.flush()  # file with its own temporary name: a re-probe)
        os.fsync(fh.fileno())
    return path
