"""Protocol files whose phases end by their time-outs (rules that cannot be met), so a run's
marks fall where a test wants them: t0 after the preheat's limit, t1 after the start-up's,
t2 after the sequences, the first cooling at its limit."""

from __future__ import annotations


def timed_protocol(
    name: str,
    sequences: list[tuple[str, float | tuple[float, float], float]],
    cooling_1_s: float,
    cooling_2_after_t2_s: float,
    preheat_s: float = 60.0,
    start_up_s: tuple[float, float, float] = (30.0, 30.0, 60.0),
) -> str:
    """The YAML of such a protocol: ``sequences`` as (name, load % or (from, to), duration
    s); ``start_up_s`` the t1 window, and the start-up's least and longest duration."""
    window, least, longest = start_up_s
    lines = []
    for seq, load, duration in sequences:
        shown = f"[{load[0]:g}, {load[1]:g}]" if isinstance(load, tuple) else f"{load:g}"
        lines.append(f"    - {{name: {seq}, load_pct: {shown}, duration: {duration:g}}}")
    return f"""\
name: {name}
test: {name}
acquisition_period_s: 1
flow_spread_K: 15
preheat: {{temperature_C: 80, tolerance_K: 0.1, hold_s: 10, load_pct: 100,
          max_duration_s: {preheat_s:g}}}
start_up: {{return_setpoint_C: 55, t1_window_s: {window:g}, t1_max_rise_K_min: 0.001,
           min_duration_s: {least:g}, max_duration_s: {longest:g}}}
test_sequence:
  return_setpoint_C: 55
  sequences:
{chr(10).join(lines)}
cooling_1: {{load_pct: 20, return_setpoint_C: 55, until_forward_C: 5,
            max_duration_s: {cooling_1_s:g}}}
cooling_2: {{until_after_t2_s: {cooling_2_after_t2_s:g}}}
"""
