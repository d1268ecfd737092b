"""The bench operator's schedule, read from the project's protocol definitions.

Carlon et al. (2015), Section 2.3 and Fig. 3: preheat to supply = return = 45 C (t0), start-up
until the flue-gas temperature rises by less than 0.5 K/min over 5 min (t1), the test sequences
with the return held at 55 C and the load imposed through the water flow
(load = m_w * cp_w * 15 K), first cooling at 20 % of the nominal output until the forward
temperature is 55 C (t3), second cooling with the pump stopped until t4 = t2 + 8 h.

The YAML files are read as data (`hil_client/protocol/definitions/<test>.yaml`); no project code
is imported.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

PROTOCOL_DIR = Path(__file__).resolve().parents[1] / "protocol" / "definitions"
TESTS = ("stationary", "load_cycle")


@dataclass(frozen=True)
class Schedule:
    """One test's operator schedule (times in s, loads as fractions of the nominal load)."""

    test: str
    flow_spread_K: float
    preheat_temp_C: float
    preheat_tol_K: float
    preheat_hold_s: float
    preheat_load: float
    preheat_max_s: float
    return_setpoint_C: float
    startup_window_s: float
    startup_max_rise_K_min: float
    startup_min_s: float
    startup_max_s: float
    seq_names: tuple[str, ...]
    seq_start_s: np.ndarray
    seq_duration_s: np.ndarray
    seq_load_from: np.ndarray
    seq_load_to: np.ndarray
    cooling1_load: float
    cooling1_return_C: float
    cooling1_until_forward_C: float
    cooling1_max_s: float
    cooling2_until_after_t2_s: float

    @property
    def test_duration_s(self) -> float:
        return float(self.seq_start_s[-1] + self.seq_duration_s[-1])


def _hms_to_s(text) -> float:
    if isinstance(text, int | float):
        return float(text)
    parts = [float(p) for p in str(text).split(":")]
    seconds = 0.0
    for p in parts:
        seconds = seconds * 60.0 + p
    return seconds


def load_schedule(test: str) -> Schedule:
    """Read `<test>.yaml` of the protocol definitions into a Schedule."""
    if test not in TESTS:
        raise ValueError(f"unknown test {test!r}; expected one of {TESTS}")
    with open(PROTOCOL_DIR / f"{test}.yaml", encoding="utf-8") as fh:
        doc = yaml.safe_load(fh)
    pre, su, ts = doc["preheat"], doc["start_up"], doc["test_sequence"]
    c1, c2 = doc["cooling_1"], doc["cooling_2"]
    names, starts, durs, l_from, l_to = [], [], [], [], []
    t = 0.0
    for seq in ts["sequences"]:
        load = seq["load_pct"]
        a, b = (load[0], load[1]) if isinstance(load, list | tuple) else (load, load)
        dur = _hms_to_s(seq["duration"])
        names.append(str(seq["name"]))
        starts.append(t)
        durs.append(dur)
        l_from.append(float(a) / 100.0)
        l_to.append(float(b) / 100.0)
        t += dur
    return Schedule(
        test=test,
        flow_spread_K=float(doc.get("flow_spread_K", 15.0)),
        preheat_temp_C=float(pre["temperature_C"]),
        preheat_tol_K=float(pre["tolerance_K"]),
        preheat_hold_s=float(pre["hold_s"]),
        preheat_load=float(pre.get("load_pct", 100)) / 100.0,
        preheat_max_s=float(pre["max_duration_s"]),
        return_setpoint_C=float(ts.get("return_setpoint_C", su["return_setpoint_C"])),
        startup_window_s=float(su["t1_window_s"]),
        startup_max_rise_K_min=float(su["t1_max_rise_K_min"]),
        startup_min_s=float(su["min_duration_s"]),
        startup_max_s=float(su["max_duration_s"]),
        seq_names=tuple(names),
        seq_start_s=np.array(starts, dtype=np.float64),
        seq_duration_s=np.array(durs, dtype=np.float64),
        seq_load_from=np.array(l_from, dtype=np.float64),
        seq_load_to=np.array(l_to, dtype=np.float64),
        cooling1_load=float(c1["load_pct"]) / 100.0,
        cooling1_return_C=float(c1["return_setpoint_C"]),
        cooling1_until_forward_C=float(c1["until_forward_C"]),
        cooling1_max_s=float(c1["max_duration_s"]),
        cooling2_until_after_t2_s=float(c2["until_after_t2_s"]),
    )
