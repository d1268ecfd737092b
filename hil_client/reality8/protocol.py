"""The two test methods (Carlon et al. 2015, Sec. 2.3, Fig. 3 and Table 2) as the plant runs them.

Written out here (not read from the project) so that the plant stays independent; the values
mirror the protocol definitions ``stationary`` and ``load_cycle``: preheat to 45 C, start-up
until the flue-gas temperature rises by less than 0.5 K/min over 5 min, the test sequence with
the load imposed by the water flow (load = m_w * cp_w * 15 K), cooling 1 at 20 % load until the
forward temperature is 55 C, cooling 2 without flow until t2 + 8 h.
"""

from __future__ import annotations

import numpy as np

FLOW_SPREAD_K = 15.0
PREHEAT = {"temperature_C": 45.0, "tolerance_K": 0.5, "hold_s": 60.0, "load_pct": 100.0,
           "max_duration_s": 14400.0}  # fmt: skip
START_UP = {"return_setpoint_C": 55.0, "t1_window_s": 300.0, "t1_max_rise_K_min": 0.5,
            "min_duration_s": 300.0, "max_duration_s": 7200.0}  # fmt: skip
RETURN_SETPOINT_C = 55.0
COOLING_1 = {"load_pct": 20.0, "until_forward_C": 55.0, "max_duration_s": 10800.0}
COOLING_2_AFTER_T2_S = 28800.0

# (name, load at start %, load at end %, duration s)
SEQUENCES: dict[str, tuple[tuple[str, float, float, float], ...]] = {
    "stationary": (("stationary_100", 100.0, 100.0, 6 * 3600.0),),
    "load_cycle": (
        ("peak", 100.0, 100.0, 4 * 60 + 52.0),
        ("gradient_100_48", 100.0, 48.0, 26 * 60.0),
        ("stationary_48", 48.0, 48.0, 50 * 60 + 15.0),
        ("gradient_48_39", 48.0, 39.0, 9 * 60.0),
        ("stationary_39", 39.0, 39.0, 3600 + 13 * 60 + 44.0),
        ("gradient_39_63", 39.0, 63.0, 12 * 60.0),
        ("stationary_63", 63.0, 63.0, 24 * 60 + 38.0),
        ("gradient_63_30", 63.0, 30.0, 22 * 60.0),
        ("stationary_30", 30.0, 30.0, 53 * 60 + 14.0),
        ("gradient_30_13", 30.0, 13.0, 34 * 60.0),
        ("stationary_13", 13.0, 13.0, 2 * 3600 + 50 * 60 + 17.0),
    ),
}
TESTS: tuple[str, ...] = tuple(SEQUENCES)
PHASES: tuple[str, ...] = ("preheat", "start_up", "test", "cooling_1", "cooling_2")


def sequence_arrays(test: str) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Names, start offsets from t1 (s), durations (s), start and end loads (%) of a test."""
    if test not in SEQUENCES:
        raise ValueError(f"unknown test {test!r}; expected one of {TESTS}")
    rows = SEQUENCES[test]
    dur = np.array([r[3] for r in rows])
    start = np.concatenate(([0.0], np.cumsum(dur)[:-1]))
    return (
        [r[0] for r in rows],
        start,
        dur,
        np.array([r[1] for r in rows]),
        np.array([r[2] for r in rows]),
    )


def max_duration_s(test: str) -> int:
    """Upper bound of a record's length: preheat + start-up + test + 8 h after t2."""
    _, start, dur, _, _ = sequence_arrays(test)
    total = PREHEAT["max_duration_s"] + START_UP["max_duration_s"] + start[-1] + dur[-1]
    return int(total + COOLING_2_AFTER_T2_S + 10)
