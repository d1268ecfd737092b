"""A live progress line on a terminal (simulated time, phase, key values), throttled."""

from __future__ import annotations

import sys
import time
from typing import TextIO

from hil_client.protocol.runner import LOG_COLUMNS, Row


class ProgressLine:
    """Rewrites one stderr line at most every ``interval_s`` of wall time."""

    def __init__(self, expected_s: float, stream: TextIO | None = None, interval_s: float = 0.2):
        self.expected_s = max(expected_s, 1.0)
        self.stream = stream or sys.stderr
        self.interval_s = interval_s
        self._next = 0.0
        self._start = time.monotonic()

    def __call__(self, row: Row) -> None:
        now = time.monotonic()
        if now < self._next:
            return
        t, phase, sequence = row[0], row[1], row[2]
        reading = dict(zip(LOG_COLUMNS, row, strict=True))
        self._next = now + self.interval_s
        frac = min(t / self.expected_s, 1.0)
        width = 24
        bar = "#" * int(frac * width) + "-" * (width - int(frac * width))
        h, rem = divmod(int(t), 3600)
        self.stream.write(
            f"\r[{bar}] {frac * 100:5.1f}%  t={h:02d}:{rem // 60:02d}:{rem % 60:02d}  "
            f"{phase:<9} {sequence:<16} T_boiler={reading['boiler_water_temp_C']:6.2f} C  "
            f"T_fg={reading['flue_gas_temp_C']:6.1f} C  "
            f"flow={reading['water_flow_kg_h']:6.1f} kg/h "
        )
        self.stream.flush()

    def done(self) -> None:
        self.stream.write(f"\r{' ' * 118}\r")
        self.stream.write(f"done in {time.monotonic() - self._start:.1f} s\n")
        self.stream.flush()
