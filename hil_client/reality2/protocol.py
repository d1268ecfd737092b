"""The test protocols (hil_client/protocol/definitions/*.yaml) read as data, for this plant's
own scheduler: durations, loads and the rules' thresholds, by name."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

DEFINITIONS = Path(__file__).resolve().parent.parent / "protocol" / "definitions"
TESTS = ("stationary", "load_cycle")


def _seconds(text: str | float) -> float:
    if isinstance(text, int | float):
        return float(text)
    h, m, s = (float(x) for x in str(text).split(":"))
    return 3600.0 * h + 60.0 * m + s


def load_protocol(test: str) -> dict:
    """Named scheduler settings and the test sequences of ``test``.

    Returns a dict with ``sequences`` (list of (name, duration_s, load_start, load_end))
    and the numbers the scheduler needs (``preheat_t``, ``t1_window_s``, ...).
    """
    if test not in TESTS:
        raise ValueError(f"test must be one of {TESTS}, got {test!r}")
    d = yaml.safe_load((DEFINITIONS / f"{test}.yaml").read_text())
    seqs = []
    for s in d["test_sequence"]["sequences"]:
        load = s["load_pct"]
        a, b = load if isinstance(load, list) else [load, load]
        seqs.append((str(s["name"]), _seconds(s["duration"]), float(a), float(b)))
    pre, su, c1 = d["preheat"], d["start_up"], d["cooling_1"]
    return {
        "name": d["name"],
        "sample_s": float(d.get("acquisition_period_s", 1)),
        "spread_K": float(d["flow_spread_K"]),
        "sequences": seqs,
        "preheat_t": float(pre["temperature_C"]),
        "preheat_tol": float(pre["tolerance_K"]),
        "preheat_hold_s": float(pre["hold_s"]),
        "preheat_load": float(pre["load_pct"]),
        "preheat_max_s": float(pre["max_duration_s"]),
        "return_set": float(d["test_sequence"]["return_setpoint_C"]),
        "t1_window_s": float(su["t1_window_s"]),
        "t1_max_rise": float(su["t1_max_rise_K_min"]),
        "t1_min_s": float(su["min_duration_s"]),
        "t1_max_s": float(su["max_duration_s"]),
        "cool1_load": float(c1["load_pct"]),
        "cool1_return": float(c1["return_setpoint_C"]),
        "cool1_until": float(c1["until_forward_C"]),
        "cool1_max_s": float(c1["max_duration_s"]),
        "cool2_after_t2_s": float(d["cooling_2"]["until_after_t2_s"]),
    }


def schedule_array(protocol: dict) -> np.ndarray:
    """Rows (duration_s, load_start_pct, load_end_pct) of the test sequences."""
    return np.array([[s[1], s[2], s[3]] for s in protocol["sequences"]], dtype=float)


def longest_record_s(protocol: dict) -> int:
    """Upper bound of the record length [s] (every phase at its maximum duration)."""
    test = sum(s[1] for s in protocol["sequences"])
    return int(
        protocol["preheat_max_s"]
        + protocol["t1_max_s"]
        + max(test + protocol["cool2_after_t2_s"], test + protocol["cool1_max_s"])
        + 60
    )
