"""Room conditions of the test hall.

Constants by default (the paper reports room temperature 18-30 C and air pressure
969-1004 hPa over its tests; we take mid values), or a piecewise-linear profile over time.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field


@dataclass(frozen=True, slots=True)
class RoomConditions:
    """Room air: temperature [C], pressure [hPa], relative humidity [%].

    ``profile`` optionally holds (time_s, temp_C, pressure_hPa, humidity_pct) points,
    interpolated linearly and held constant outside their range.
    """

    temp_C: float = 22.0
    pressure_hPa: float = 985.0
    humidity_pct: float = 45.0
    profile: tuple[tuple[float, float, float, float], ...] = field(default=())

    def at(self, time_s: float) -> tuple[float, float, float]:
        """(temperature [C], pressure [hPa], humidity [%]) at ``time_s``."""
        if not self.profile:
            return (self.temp_C, self.pressure_hPa, self.humidity_pct)
        times = [p[0] for p in self.profile]
        i = bisect.bisect_right(times, time_s)
        if i == 0:
            return self.profile[0][1:]
        if i == len(times):
            return self.profile[-1][1:]
        (ta, *a), (tb, *b) = self.profile[i - 1], self.profile[i]
        w = (time_s - ta) / (tb - ta)
        return tuple(x + (y - x) * w for x, y in zip(a, b, strict=True))  # type: ignore[return-value]
