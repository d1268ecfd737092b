"""The two test procedures of Carlon et al. (2015), Section 2.3 and Table 2.

Written from the paper (and checked against the protocol definitions for durations and
setpoints); only the measuring sequence t1..t2 differs between the tests. The shared
start-up and cooling rules live in the kernel's scheduler.
"""

from __future__ import annotations

import numpy as np


def _hms(text: str) -> float:
    h, m, s = (int(x) for x in text.split(":"))
    return 3600.0 * h + 60.0 * m + s


#: (sequence name, load at start [% of nominal], load at end, duration [s])
SEQUENCES: dict[str, tuple[tuple[str, float, float, float], ...]] = {
    "stationary": (("stationary_100", 100.0, 100.0, _hms("06:00:00")),),
    "load_cycle": (
        ("peak", 100.0, 100.0, _hms("00:04:52")),
        ("gradient_100_48", 100.0, 48.0, _hms("00:26:00")),
        ("stationary_48", 48.0, 48.0, _hms("00:50:15")),
        ("gradient_48_39", 48.0, 39.0, _hms("00:09:00")),
        ("stationary_39", 39.0, 39.0, _hms("01:13:44")),
        ("gradient_39_63", 39.0, 63.0, _hms("00:12:00")),
        ("stationary_63", 63.0, 63.0, _hms("00:24:38")),
        ("gradient_63_30", 63.0, 30.0, _hms("00:22:00")),
        ("stationary_30", 30.0, 30.0, _hms("00:53:14")),
        ("gradient_30_13", 30.0, 13.0, _hms("00:34:00")),
        ("stationary_13", 13.0, 13.0, _hms("02:50:17")),
    ),
}


def schedule_arrays(test: str) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """Names, durations, start loads and end loads of the test's measuring sequences."""
    if test not in SEQUENCES:
        raise ValueError(f"unknown test {test!r}; known: {sorted(SEQUENCES)}")
    seqs = SEQUENCES[test]
    names = [s[0] for s in seqs]
    dur = np.array([s[3] for s in seqs], dtype=float)
    l0 = np.array([s[1] for s in seqs], dtype=float)
    l1 = np.array([s[2] for s in seqs], dtype=float)
    return names, dur, l0, l1
