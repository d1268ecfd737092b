"""Showing a long run while it goes: a progress line, or a live view for demos.

Both redraw at most a few times per second of wall time, on stderr, in place.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

from hil_client.protocol.runner import LOG_COLUMNS, Row
from rig_emulator.model.water_heat import heat_to_water_kW

_I = {name: i for i, name in enumerate(LOG_COLUMNS)}


def hms(seconds: float) -> str:
    """HH:MM:SS of a duration [s]."""
    h, rem = divmod(int(seconds), 3600)
    return f"{h:02d}:{rem // 60:02d}:{rem % 60:02d}"


class ProgressLine:
    """A one-line progress bar with simulated time, phase and key values."""

    def __init__(self, expected_s: float, stream: TextIO | None = None, interval_s: float = 0.2):
        self.expected_s = max(expected_s, 1.0)
        self.stream = stream or sys.stderr
        self.interval_s = interval_s
        self._next = 0.0
        self._start = time.monotonic()

    def __call__(self, row: Row) -> None:
        self._last = row
        now = time.monotonic()
        if now < self._next:
            return
        self._next = now + self.interval_s
        self.draw(row)

    def draw(self, row: Row) -> None:
        t = float(row[0])  # type: ignore[arg-type]
        frac = min(t / self.expected_s, 1.0)
        width = 24
        bar = "#" * int(frac * width) + "-" * (width - int(frac * width))
        self.stream.write(
            f"\r[{bar}] {frac * 100:5.1f}%  t={hms(t)}  {row[1]:<9} {row[2]:<16} "
            f"T_boiler={row[_I['boiler_water_temp_C']]:6.2f} C  "
            f"T_fg={row[_I['flue_gas_temp_C']]:6.1f} C "
        )
        self.stream.flush()

    def done(self) -> None:
        self.stream.write(f"\r{' ' * 110}\r")
        self.stream.write(f"done in {time.monotonic() - self._start:.1f} s\n")
        self.stream.flush()


class LiveView(ProgressLine):
    """A block of lines redrawn in place: phase, sequence, times and the key values."""

    LINES = 5

    def __init__(self, expected_s: float, stream: TextIO | None = None, interval_s: float = 0.25):
        super().__init__(expected_s, stream, interval_s)
        self._drawn = False

    def draw(self, row: Row) -> None:
        def v(name: str) -> float:
            return float(row[_I[name]])  # type: ignore[arg-type]

        t = float(row[0])  # type: ignore[arg-type]
        wall = time.monotonic() - self._start
        q_water = heat_to_water_kW(
            v("water_flow_kg_h"), v("water_in_temp_C"), v("water_out_temp_C")
        )
        lines = [
            f"phase {row[1]:<10} sequence {row[2] or '-':<18} simulated {hms(t)} "
            f"({min(t / self.expected_s, 1) * 100:4.1f} %), wall {hms(wall)}",
            f"  boiler {'FIRING' if v('boiler_on') >= 0.5 else 'off   '}   T inside "
            f"{v('boiler_water_temp_C'):6.2f} C   forward {v('water_out_temp_C'):6.2f} C   "
            f"return {v('water_in_temp_C'):6.2f} C",
            f"  flow {v('water_flow_kg_h'):7.1f} kg/h (setpoint "
            f"{v('water_flow_setpoint_kg_h'):7.1f})   heat to water {q_water:6.2f} kW",
            f"  flue gas {v('flue_gas_temp_C'):6.1f} C   O2 {v('flue_gas_O2_pct'):5.2f} %   "
            f"CO {v('flue_gas_CO_ppm'):7.1f} ppm",
            f"  balance {v('balance_mass_kg'):8.2f} kg   electric {v('electric_power_W'):6.1f} W",
        ]
        up = f"\x1b[{self.LINES}F" if self._drawn else ""
        self.stream.write(up + "".join(f"\x1b[2K{line}\n" for line in lines))
        self.stream.flush()
        self._drawn = True

    def done(self) -> None:
        if getattr(self, "_last", None) is not None:
            self.draw(self._last)  # the final state stays on screen
        self.stream.write(f"done in {time.monotonic() - self._start:.1f} s\n")
        self.stream.flush()
