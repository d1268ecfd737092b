"""One runner for every test method and every rig (Fig. 3 of Carlon et al. 2015).

Phases and the rules that end them:

- ``preheat``: water circulates at the preheat load; the bench heats the return ("outside
  help") to the preheat temperature; t0 once forward and return have both been within the
  tolerance of it for ``hold_s``.
- ``start_up`` (t0..t1): boiler switched on, return set to 55 C, flow of the first sequence's
  load; t1 once the flue-gas temperature rises by less than 0.5 K/min, the rise being the
  least-squares slope over the last ``t1_window_s`` while the burner fires, and at least
  ``min_duration_s`` after t0.
- ``test`` (t1..t2): the sequences, loads converted to flow (load * Pnom / (cp_w * 15 K)).
- ``cooling_1`` (t2..t3): boiler switched off, heat extracted at the first-cooling load until
  the forward temperature falls to 55 C.
- ``cooling_2`` (t3..t4): circulation stopped until t4 = t2 + 8 h.

Every phase also has a maximum duration so that a rig that never meets a rule still ends;
the meta file then says which rule timed out.

Breaks (CONTRACT section 7): a rig may report ``epoch`` (the ``rig_epoch`` column; one
higher after each break it went on from, e.g. a restarted real-time server) and ``gaps``.
When the epoch changes and the rig says ``restart_phase``, the current phase starts again
from that row, the first of the new plant (its rules and durations, its first sequence),
and the rig's last gap names it (``phase_restarted``); otherwise the run goes on, the rows
marked by their epoch. A restart moves no mark: the phase's start mark is where the phase
before it ended (t2 is where the test ended), and the ``phase`` column, which the analyses
read, keeps the phase's name across both attempts, as the marks do (a restart in the
first cooling moved t2 from 3518 to 5107 s, and the balance took 1487 cooling rows for a
0.913-h test at 91.1 % instead of 0.5 h at 80.6 %: a stranger's probe). Whenever the rig's
gaps change, and when the rig fails, ``on_phase`` is called too, so the meta file keeps
every gap as the run goes.

A run that cannot carry out the test method stops (:class:`MethodNotCarriedOut`, a
:class:`~hil_client.protocol.rig.RigError`: the log keeps its rows, a note says why, exit
1) rather than end "complete": a sequence of the measuring cycle that got no row and whose
setpoint was never written (a real-time server at x100000 read every 10000 s skipped the
ramp, and the 240-s test lasted 2 h 47 min: a stranger's probe), or a plant command the rig
reports refused as an illegal value (``refusal``: every setpoint of a 6-h run refused with
exception 03 ended complete with a test of 0 kWh: a stranger's probe). A sequence lost to
a break the run went on from (a gap the rig recorded over it, not a change of the clock's
speed) is no such skip: the user asked the run to go on, and a note names it (a real-time
server restarted in the second of five sequences with ``--on-restart continue`` stopped the
run for the three the outage took: a stranger's probe).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from operator import itemgetter

from hil_client.protocol.definition import ProtocolDefinition, ProtocolError, Sequence
from hil_client.protocol.rig import LOG_COLUMNS as LOG_COLUMNS  # the log's, declared there
from hil_client.protocol.rig import READING_KEYS, Rig, RigCommand, RigError, StepTiming
from rig_emulator.emulator import CommandError, check_command
from rig_emulator.model.water_heat import flow_for_heat_kg_h

PHASES = ("preheat", "start_up", "test", "cooling_1", "cooling_2")

# A row: the step's own values and the readings in READING_KEYS order, the flow setpoint
# spliced in before boiler_on (LOG_COLUMNS' order, built the same way above)
_SPLICE = READING_KEYS.index("boiler_on")
# readings by name -> values in READING_KEYS order (operator.itemgetter: C speed)
_IN_READING_ORDER = itemgetter(*READING_KEYS)
# the readings the phase rules look at, by position in READING_KEYS
_R_OUT = READING_KEYS.index("water_out_temp_C")
_R_IN = READING_KEYS.index("water_in_temp_C")
_R_FLUE = READING_KEYS.index("flue_gas_temp_C")
_R_ON = _SPLICE

Row = tuple[object, ...]


@dataclass(slots=True)
class RunResult:
    """Outcome of a protocol run: phase boundaries [s since the record start] and notes."""

    protocol: str
    test: str
    rows: int = 0
    times: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    duration_s: float = 0.0


class MethodNotCarriedOut(RigError):
    """The test method could not be carried out on this rig (see the module docstring)."""


class _SlopeWindow:
    """Least-squares slope of y(t) over a sliding time window, O(1) per sample. It keeps
    the latest reading at least a window old, so the window fills whatever the step, and
    at least three readings (a real-time server at x400 gave a row every 40 simulated
    seconds: the readings within 300 s spanned 280, the window was never full, and t1
    waited for the start-up's 2-h time-out with the flue gas flat since: a stranger's
    probe)."""

    MIN_POINTS = 3

    def __init__(self, window_s: float) -> None:
        self.window_s = window_s
        self.points: deque[tuple[float, float]] = deque()
        self.st = self.sy = self.stt = self.sty = 0.0

    def add(self, t: float, y: float) -> None:
        """Add a reading at ``t``; a missing one (NaN: a dropout) is skipped, not summed (it
        made every later slope NaN, and t1 waited for the start-up's time-out)."""
        if not math.isfinite(y):
            return
        self.points.append((t, y))
        self.st += t
        self.sy += y
        self.stt += t * t
        self.sty += t * y
        while len(self.points) > self.MIN_POINTS and self.points[1][0] <= t - self.window_s:
            t_old, y_old = self.points.popleft()
            self.st -= t_old
            self.sy -= y_old
            self.stt -= t_old * t_old
            self.sty -= t_old * y_old

    def full(self) -> bool:
        return bool(self.points) and self.points[-1][0] - self.points[0][0] >= self.window_s * 0.98

    def slope(self) -> float:
        n = len(self.points)
        if n < self.MIN_POINTS:
            return math.inf
        # centre on the last time to keep the sums well conditioned
        t_ref = self.points[-1][0]
        st = self.st - n * t_ref
        stt = self.stt - 2 * t_ref * self.st + n * t_ref * t_ref
        sty = self.sty - t_ref * self.sy
        den = n * stt - st * st
        return (n * sty - st * self.sy) / den if den > 0 else math.inf

    def clear(self) -> None:
        self.__init__(self.window_s)  # type: ignore[misc]


def flow_for_load(load_pct: float, p_nom_kW: float, spread_K: float) -> float:
    """Water flow [kg/h] that imposes ``load_pct`` of nominal load with a ``spread_K`` spread."""
    return flow_for_heat_kg_h(load_pct / 100.0 * p_nom_kW, spread_K)


def setpoints(protocol: ProtocolDefinition, p_nom_kW: float) -> Iterator[tuple[str, str, float]]:
    """Every setpoint value :func:`run_protocol` can write for a boiler of ``p_nom_kW``:
    (the protocol key it comes from, the command, the value). A ramp's extremes are its
    ends; the second cooling writes a flow of 0."""
    spread = protocol.flow_spread_K
    flows = [
        ("preheat.load_pct", protocol.preheat.load_pct),
        ("cooling_1.load_pct", protocol.cooling_1.load_pct),
    ]
    for i, seq in enumerate(protocol.sequences):
        flows += [(f"test_sequence.sequences[{i}].load_pct", seq.load_start_pct)]
        flows += [(f"test_sequence.sequences[{i}].load_pct", seq.load_end_pct)]
    for key, load in flows:
        yield key, "water_flow_setpoint_kg_h", flow_for_load(load, p_nom_kW, spread)
    for key, value in (
        ("preheat.temperature_C", protocol.preheat.temperature_C),
        ("start_up.return_setpoint_C", protocol.start_up.return_setpoint_C),
        ("test_sequence.return_setpoint_C", protocol.test_return_setpoint_C),
        ("cooling_1.return_setpoint_C", protocol.cooling_1.return_setpoint_C),
    ):
        yield key, "return_setpoint_C", value


def check_setpoints(
    protocol: ProtocolDefinition,
    p_nom_kW: float,
    boiler: str,
    within: Mapping[str, tuple[float, float]] | None = None,
) -> None:
    """Refuse (:class:`ProtocolError`, one line naming the key, the boiler and the limit)
    a protocol that would write a setpoint the emulator does not accept for ``boiler``:
    its :func:`~rig_emulator.emulator.check_command`, with a register map's narrower
    ``within`` ranges by command where given."""
    for key, command, value in setpoints(protocol, p_nom_kW):
        try:
            check_command(command, value, (within or {}).get(command))
        except CommandError as exc:
            spread = f", flow_spread_K {protocol.flow_spread_K:g}" if "flow" in command else ""
            raise ProtocolError(
                f"key '{key}' on {boiler} ({p_nom_kW:g} kW{spread}) commands {exc}"
            ) from None


#: A step that let this many times the period and the typical step of the run pass or more
#: (the median of the last :data:`HOLE_TYPICAL_STEPS` that were not holes) with no break
#: the rig recorded: the client was held up (paused, swapped out, overloaded; or waiting
#: on a slow unit) while a real-time server ran on, and the rows between were never
#: acquired. A run that is merely coarse throughout (a server at x1000) is said once at the
#: end instead.
HOLE_FACTOR = 5.0
HOLE_TYPICAL_STEPS = 60

#: The share by which a step may fall short of :data:`HOLE_FACTOR` times the period and the
#: typical step and still be a hole: a real-time server's clock carries rounding that grows
#: with its time (a hole of 5 x 20 s at 11,513 s went untold: a stranger's probe; 1e-9 s
#: was the margin), far below a millionth of a step.
HOLE_ROUNDING = 1e-6
HOLES_TOLD = 10


#: An instrument's replies waited on this long between two reads of the clock: named in a
#: hole's note (the rest answer in milliseconds on a local network)
UNIT_LATE_S = 0.1


def _hole(from_s: float, to_s: float, period_s: float, timing: StepTiming | None) -> str:
    """The note on a hole in the rows, blaming whoever held up the wall time between the
    two reads of the server's clock the hole lies between (the rig's ``step_timing``), the
    largest share of it: late replies of instruments (a slow unit, a delay fault: a 4-s
    delay on unit 1 was blamed on a server stall "0.0 s late", a stranger's probe), the
    server's own late replies (it stalled, and its clock made up the time: a server
    SIGSTOPped was blamed on the client, a stranger's probe), or the client itself."""
    missed = round((to_s - from_s) / period_s) - 1
    head = f"no row from time_s = {from_s:g} to {to_s:g} s ({missed} acquisitions missed): "
    tail = ", and the rows between were not acquired"
    client_s = timing.client_s if timing is not None else math.inf
    server_s, unit_waits = timing.waits_s if timing is not None else (0.0, {})
    units_s = sum(unit_waits.values())
    if units_s > max(server_s, client_s):
        slow = sorted(unit_waits.items(), key=itemgetter(1), reverse=True)
        late = [(unit, waited) for unit, waited in slow if waited >= UNIT_LATE_S] or slow[:1]
        if len(late) == 1:
            who = f"unit {late[0][0]} (a slow unit, or a delay fault on it)"
        else:
            named = listed([f"unit {unit} ({waited:.1f} s)" for unit, waited in late])
            who = f"{named} (slow units, or delay faults)"
        return (
            f"{head}the client waited {units_s:.1f} s on late replies of {who}, while the "
            f"server's clock ran on{tail}"
        )
    if server_s > client_s:
        return (
            f"{head}the server answered {server_s:.1f} s late (it stalled: paused, swapped "
            "out or overloaded, and its clock made up the time), while the client kept its "
            f"pace{tail}"
        )
    held = f" {client_s:.1f} s" if timing is not None else ""
    return (
        f"{head}the client fell behind the server's real-time clock (held up{held}: paused, "
        f"swapped out or overloaded){tail}"
    )


def listed(items: list[str]) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    return " and ".join(filter(None, (", ".join(items[:-1]), items[-1])))


def _sequences(indices: list[int], sequences: tuple[Sequence, ...]) -> tuple[str, str]:
    """The sequences at ``indices`` named as a protocol file gives them, and the
    grammatical number: ``("sequence 'a' (...)", "")`` or ``("sequences 'a' (...) and
    'b' (...)", "s")``."""
    named = [f"'{sequences[i].name}' (test_sequence.sequences[{i}])" for i in indices]
    plural = "s" if len(named) > 1 else ""
    return f"sequence{plural} {listed(named)}", plural


def _stop(result: RunResult, on_phase: Callable[[RunResult], None] | None, why: str) -> None:
    """Stop the run: ``why`` (one line) into its notes and the meta file, then
    :class:`MethodNotCarriedOut` (the log keeps its rows; ``hil-client run`` exits 1)."""
    result.notes.append(why)
    if on_phase is not None:
        on_phase(result)
    raise MethodNotCarriedOut(why)


def run_protocol(
    protocol: ProtocolDefinition,
    p_nom_kW: float,
    rig: Rig,
    sink: Callable[[Row], None],
    progress: Callable[[Row], None] | None = None,
    on_phase: Callable[[RunResult], None] | None = None,
) -> RunResult:
    """Play ``protocol`` on ``rig`` and hand every acquired row to ``sink``.

    Args:
        protocol: the test method.
        p_nom_kW: nominal load of the boiler under test [kW] (load-to-flow conversion).
        rig: the bench (in-process or over Modbus).
        sink: receives one row per acquisition step, in :data:`LOG_COLUMNS` order.
        progress: optional callback receiving each row too.
        on_phase: optional callback after each phase boundary (t0..t4) is found, each
            change of the rig's gaps or epoch, each hole in the rows, and before a rig
            failure is raised.
    """
    dt = protocol.acquisition_period_s
    spread = protocol.flow_spread_K
    pre = protocol.preheat
    su = protocol.start_up
    c1 = protocol.cooling_1
    sequences = protocol.sequences
    result = RunResult(protocol=protocol.name, test=protocol.test)
    times = result.times

    def flow(load_pct: float) -> float:
        return flow_for_load(load_pct, p_nom_kW, spread)

    phase = "preheat"
    phase_start = 0.0
    hold_since: float | None = None
    # the slope needs three readings: a period over half the window widens it to two periods
    slope = _SlopeWindow(max(su.t1_window_s, 2.0 * dt))
    seq_index = 0
    seq_start = 0.0
    t = 0.0
    rows = 0
    command = RigCommand(flow(pre.load_pct), pre.temperature_C, True, False, True)
    first_load = sequences[0].load_start_pct
    t4_after = protocol.cooling_2_until_after_t2_s
    gaps: list = getattr(rig, "gaps", [])
    # a rig may give its readings in READING_KEYS order at once (``read_values``); else
    # they are taken from its mapping by name
    read_values = getattr(rig, "read_values", None)
    if read_values is None:
        read = rig.read

        def read_values() -> tuple:
            return _IN_READING_ORDER(read())

    epoch = getattr(rig, "epoch", 0)
    restart_phase = bool(getattr(rig, "restart_phase", False))
    recent: deque[float] = deque(maxlen=HOLE_TYPICAL_STEPS)  # simulated time per step
    holes = missed = counted = 0  # counted: the note that counts the holes past ten
    holes_from_s = holes_to_s = 0.0  # the first hole's start, the last one's end
    # a rig that tells the flow setpoint as its wire carries it: that is logged (a uint16
    # x0.5 holds 137.5 where 137.4702 was asked, and the log said 137.4702: a stranger's
    # probe); else the commanded one (the in-process rig takes it as it is)
    carries_setpoint = hasattr(rig, "written_flow_setpoint_kg_h")
    timed = hasattr(rig, "step_timing")
    refuses = hasattr(rig, "refusal")  # (looked up once: the in-process rig's rows are many)
    played = [False] * len(sequences)  # the sequences of the test that had a row
    # ... that a break the run went on from overlapped: its span (time_s before, after)
    lost: list[tuple[float, float] | None] = [None] * len(sequences)
    cooling_2_ends = math.inf  # t2 + until_after_t2_s, or after a restart of cooling_2

    while True:
        # --- commands for this step
        sequence = ""
        if phase == "preheat":
            command.flow_setpoint_kg_h = flow(pre.load_pct)
            command.return_setpoint_C = pre.temperature_C
            command.pump_on, command.boiler_on, command.return_heating = True, False, True
        elif phase == "start_up":
            command.flow_setpoint_kg_h = flow(first_load)
            command.return_setpoint_C = su.return_setpoint_C
            command.pump_on, command.boiler_on, command.return_heating = True, True, False
        elif phase == "test":
            elapsed = t - seq_start
            while seq_index < len(sequences) - 1 and elapsed >= sequences[seq_index].duration_s:
                seq_start += sequences[seq_index].duration_s
                seq_index += 1
                elapsed = t - seq_start
            seq = sequences[seq_index]
            sequence = seq.name
            command.flow_setpoint_kg_h = flow(seq.load_at(elapsed + dt))
            command.return_setpoint_C = protocol.test_return_setpoint_C
        elif phase == "cooling_1":
            command.flow_setpoint_kg_h = flow(c1.load_pct)
            command.return_setpoint_C = c1.return_setpoint_C
            command.pump_on, command.boiler_on = True, False
        else:  # cooling_2
            command.flow_setpoint_kg_h = 0.0
            command.pump_on, command.boiler_on = False, False

        rig.apply(command)
        n_gaps = len(gaps)
        try:
            passed = rig.advance(dt)
        except RigError as exc:
            # the meta file says why the run stopped (and the break's gap, if any)
            result.notes.append(f"stopped after time_s = {t:g} s: {exc}")
            if on_phase is not None:
                on_phase(result)
            raise
        t += passed
        if len(gaps) != n_gaps:  # a break, an outage, the server's speed changed: the
            recent.clear()  # steps before tell nothing of the steps after
            broke = any("speed_after" not in gap for gap in gaps[n_gaps:])
            if broke and phase == "test":  # the sequences the break's time overlaps
                start = seq_start
                for i in range(seq_index, len(sequences)):
                    end = start + sequences[i].duration_s
                    if lost[i] is None and start < t and end > t - passed:
                        lost[i] = (t - passed, t)
                    start = end
        # (the first steps tell no typical step: a x100 server's first took 9.5 s); a
        # hole is no typical step: holes one after the other (a unit that times out every
        # row from some time on) made the typical step theirs, and went untold (a
        # stranger's probe: 13 of 19 holes of 5.0 s at a 1-s period, with no note)
        least = HOLE_FACTOR * (1.0 - HOLE_ROUNDING)
        late = passed >= least * dt and len(gaps) == n_gaps and len(recent) >= 10
        if late and passed >= least * sorted(recent)[len(recent) // 2]:
            holes += 1
            missed += round(passed / dt) - 1
            holes_from_s = holes_from_s if holes > 1 else t - passed
            holes_to_s = t
            if holes <= HOLES_TOLD:
                timing = rig.step_timing if timed else None  # type: ignore[attr-defined]
                result.notes.append(_hole(t - passed, t, dt, timing))
            if holes == HOLES_TOLD + 1:
                counted = len(result.notes)
                result.notes.append("")
            if holes > HOLES_TOLD:  # kept up to date: a run stopped or interrupted has it
                result.notes[counted] = (
                    f"more than {HOLES_TOLD} such holes in the rows: {holes} in all, from "
                    f"time_s = {holes_from_s:g} to {holes_to_s:g} s, {missed} acquisitions "
                    "missed"
                )
            if on_phase is not None and holes <= HOLES_TOLD + 1:
                on_phase(result)  # into the meta file now (a run stopped before its first
                # phase mark lost it: a re-probe)
        else:
            recent.append(passed)
        values = read_values()
        rows += 1
        rig_epoch = getattr(rig, "epoch", 0)
        if rig_epoch != epoch:  # a break the rig went on from: a new plant from this row
            epoch = rig_epoch
            if restart_phase:  # (before the row: it is the restarted phase's first, and
                # carries its first sequence, not the abandoned attempt's: a stranger's probe)
                phase_start, hold_since = t, None
                slope.clear()
                seq_index, seq_start = 0, t
                if phase == "test":
                    sequence = sequences[0].name
                    played = [False] * len(sequences)  # the restarted test plays them all
                    lost = [None] * len(sequences)
                elif phase == "cooling_2":  # it lasts what it was to last after t3
                    cooling_2_ends = t + max(t4_after - (times["t3_s"] - times["t2_s"]), 0.0)
                if gaps:
                    gaps[-1]["phase_restarted"] = phase
                kept = "" if phase == "preheat" else "; no mark moves (its start is the last's end)"
                result.notes.append(
                    f"{phase} restarted at time_s = {t:g} s on a new plant (rig_epoch {epoch})"
                    f"{kept}"
                )
            else:
                why = gaps[-1].get("reason") if gaps else None  # not always a new plant
                # (a log marked complete whose test ran on two plants said only "the run
                # went on": a stranger's probe read a cold start-up labelled test)
                cut = "" if phase == "preheat" else f"; its {phase} is not one continuous record"
                result.notes.append(
                    f"rig_epoch {epoch} from time_s = {t:g} s: "
                    f"{why or 'a new plant'}; the run went on{cut} (the analyses read one "
                    "rig_epoch)"
                )
        setpoint = command.flow_setpoint_kg_h
        if not command.pump_on:
            setpoint = 0.0
        elif carries_setpoint:
            setpoint = rig.written_flow_setpoint_kg_h  # type: ignore[attr-defined]
        row = (t, phase, sequence, *values[:_SPLICE], setpoint, *values[_SPLICE:], rig_epoch)
        sink(row)
        if progress is not None:
            progress(row)
        if on_phase is not None and len(gaps) != n_gaps:
            on_phase(result)  # a gap (closed by this row) or a break: into the meta file now
        refusal = rig.refusal if refuses else None  # type: ignore[attr-defined]
        if refusal is not None:  # the other end will refuse it all run: stop at once
            _stop(result, on_phase, f"{refusal}; stopped after time_s = {t:g} s")
        if phase == "test":
            played[seq_index] = True

        # --- rules that end the phase (evaluated on what was read)
        elapsed_phase = t - phase_start
        if phase == "preheat":
            ok = (
                abs(values[_R_OUT] - pre.temperature_C) <= pre.tolerance_K
                and abs(values[_R_IN] - pre.temperature_C) <= pre.tolerance_K
            )
            hold_since = (hold_since if hold_since is not None else t) if ok else None
            timed_out = elapsed_phase >= pre.max_duration_s
            if (hold_since is not None and t - hold_since >= pre.hold_s) or timed_out:
                if timed_out:
                    result.notes.append("t0: preheat timed out before the water was stable")
                phase, phase_start = "start_up", t
                times["t0_s"] = t
                if on_phase is not None:
                    on_phase(result)
        elif phase == "start_up":
            if values[_R_ON] >= 0.5:
                slope.add(t, values[_R_FLUE])
            else:
                slope.clear()
            rise_K_min = slope.slope() * 60.0 if slope.full() else math.inf
            timed_out = elapsed_phase >= su.max_duration_s
            if (elapsed_phase >= su.min_duration_s and rise_K_min < su.t1_max_rise_K_min) or (
                timed_out
            ):
                if timed_out:
                    result.notes.append("t1: flue-gas rule not met, start-up timed out")
                phase, phase_start = "test", t
                seq_start = t
                times["t1_s"] = t
                if on_phase is not None:
                    on_phase(result)
        elif phase == "test":
            ended = elapsed_phase >= protocol.test_duration_s - 1e-9
            unplayed = [i for i in range(len(sequences) if ended else seq_index) if not played[i]]
            breaks: dict[tuple[float, float], list[int]] = {}  # a break's span: its lost
            for i in unplayed:
                span = lost[i]
                if span is not None:
                    breaks.setdefault(span, []).append(i)
                    played[i] = True  # (named once: not again, nor as skipped)
            for (before, after), broken in breaks.items():
                named, plural = _sequences(broken, sequences)
                result.notes.append(
                    f"the test's {named} got no row: lost to the break from time_s = "
                    f"{before:g} to {after:g} s, which the run went on from (the test is short "
                    f"of {'them' if plural else 'it'})"
                )
            skipped = [i for i in unplayed if lost[i] is None]
            if skipped:
                named, plural = _sequences(skipped, sequences)
                _stop(
                    result,
                    on_phase,
                    f"the test method could not be carried out: {named} got no row and "
                    f"{'their setpoints were' if plural else 'its setpoint was'} never written "
                    f"(a step of {passed:g} s of simulated time, the acquisition period being "
                    f"{dt:g} s: a real-time server faster than this client reads; --lockstep "
                    f"or a slower --speed plays every sequence); stopped after time_s = {t:g} s",
                )
            if ended:
                phase, phase_start = "cooling_1", t
                times["t2_s"] = t
                cooling_2_ends = t + t4_after
                if on_phase is not None:
                    on_phase(result)
        elif phase == "cooling_1":
            timed_out = elapsed_phase >= c1.max_duration_s
            if values[_R_OUT] <= c1.until_forward_C or timed_out:
                if timed_out:
                    result.notes.append("t3: forward temperature rule not met, timed out")
                elif t - times["t2_s"] <= dt + 1e-9:  # (no word: a stranger's probe)
                    result.notes.append(
                        f"t3: the forward ({values[_R_OUT]:.4g} C) was already at or below "
                        f"cooling_1.until_forward_C ({c1.until_forward_C:g} C) when the test "
                        "ended; the first cooling lasted one row"
                    )
                phase, phase_start = "cooling_2", t
                times["t3_s"] = t
                if on_phase is not None:
                    on_phase(result)
        elif t >= cooling_2_ends - 1e-9:
            times["t4_s"] = t
            if times["t3_s"] - times["t2_s"] >= t4_after - 1e-9:
                result.notes.append(
                    f"t4: cooling_2.until_after_t2_s ({t4_after:g} s) had passed when the first"
                    f" cooling ended ({times['t3_s'] - times['t2_s']:g} s after t2); the second"
                    " cooling lasted one row"
                )
            if on_phase is not None:
                on_phase(result)
            break

    result.rows = rows
    result.duration_s = t
    return result
