"""The lab's test procedure, read as data from the project's protocol definitions
(``hil_client/protocol/definitions/*.yaml``, Carlon et al. 2015 Section 2.3 and Table 2).

Only the YAML is read (``yaml.safe_load``); the scheduler that plays it is this plant's own
(:func:`hil_client.reality.kernel.run_test`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

DEFINITIONS = Path(__file__).resolve().parents[1] / "protocol" / "definitions"
TESTS = ("stationary", "load_cycle")


def _seconds(text: str | float) -> float:
    """'HH:MM:SS' (or a number of seconds) in seconds."""
    if isinstance(text, int | float):
        return float(text)
    h, m, s = (float(x) for x in str(text).split(":"))
    return 3600.0 * h + 60.0 * m + s


def load_test(test: str) -> tuple[dict[str, float], dict[str, np.ndarray]]:
    """(scalar settings by kernel name, sequences as arrays load0/load1 [%] and dur [s])."""
    if test not in TESTS:
        raise ValueError(f"test must be one of {TESTS}, not {test!r}")
    d = yaml.safe_load((DEFINITIONS / f"{test}.yaml").read_text(encoding="utf-8"))
    pre, su, c1 = d["preheat"], d["start_up"], d["cooling_1"]
    settings = {
        "spread_K": float(d["flow_spread_K"]),
        "pre_temp": float(pre["temperature_C"]),
        "pre_tol": float(pre["tolerance_K"]),
        "pre_hold": float(pre["hold_s"]),
        "pre_load": float(pre["load_pct"]),
        "pre_max": float(pre["max_duration_s"]),
        "su_ret": float(su["return_setpoint_C"]),
        "su_win": float(su["t1_window_s"]),
        "su_rise": float(su["t1_max_rise_K_min"]),
        "su_min": float(su["min_duration_s"]),
        "su_max": float(su["max_duration_s"]),
        "test_ret": float(d["test_sequence"]["return_setpoint_C"]),
        "c1_load": float(c1["load_pct"]),
        "c1_ret": float(c1["return_setpoint_C"]),
        "c1_until": float(c1["until_forward_C"]),
        "c1_max": float(c1["max_duration_s"]),
        "c2_after": float(d["cooling_2"]["until_after_t2_s"]),
    }
    seqs = d["test_sequence"]["sequences"]
    load0, load1, dur, names = [], [], [], []
    for s in seqs:
        load = s["load_pct"]
        a, b = (load, load) if isinstance(load, int | float) else (load[0], load[1])
        load0.append(float(a))
        load1.append(float(b))
        dur.append(_seconds(s["duration"]))
        names.append(str(s["name"]))
    arrays = {
        "load0": np.array(load0),
        "load1": np.array(load1),
        "dur": np.array(dur),
    }
    return settings, arrays | {"names": names}  # type: ignore[dict-item]
