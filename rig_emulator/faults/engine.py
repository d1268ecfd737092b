"""The fault schedule in simulated time, the communication decisions and the readings.

:class:`FaultEngine` holds the faults set (from a file, a profile, Python or the simulation
control unit), starts each at the first evaluation where the simulated time has reached its
``at_s`` and ends it once ``for_s`` has passed since it started. It is evaluated whenever the
readings are evaluated (:meth:`apply`, called by the emulator each time it publishes): in
lockstep that is after every advance, in real time at every tick. A fault scheduled ahead
keeps its own window in simulated time, ``at_s`` to ``at_s + for_s``, however far one
evaluation moves the clock: it is seen by the first evaluation inside its window and gone by
the first after it, and one whose whole window falls between two evaluations (a long
lockstep advance) is journalled as started and ended, unseen. The journal gives the
window's own times. A fault set once its ``at_s`` has passed starts when it is set.

- Communication faults are decided per request by :meth:`decide` (unit ID in, delay / drop
  / exception out); a ``disconnect`` calls :attr:`on_disconnect` once. A request a delay
  holds is let go when its delay faults end (cleared, ``for_s`` elapsed, a reset): a server
  that waits out the delay inside :func:`holding` gets a :class:`DelayHold` for it. A
  request counts (``requests``, journalled at a fault's end) only for the faults whose
  effect it got (:func:`_combine`): a held request for the delay fault that held it when
  it went (:class:`DelayHold`), not for an exception-04 fault whose request the spec's
  checks refused first (:func:`refused_by_checks`), not at all if it was no request after
  all (:meth:`Tally.withdraw`), and not for a delay where it gets no reply (an RTU
  broadcast: :func:`tallying`).
- Instrument faults change only the readings handed to :meth:`apply` (a dict the emulator
  publishes); the plant, its state and the instruments' own random draws are never touched.
  What they serve is floored where the instrument can show nothing lower
  (:attr:`FaultEngine.reading_floors`).

Journal events (:mod:`rig_emulator.faults.journal`) go to :attr:`journal` when set.
"""

from __future__ import annotations

import contextlib
import logging
import math
import random
import threading
import time
from collections.abc import Callable, Collection, Iterable, Iterator, Mapping, MutableMapping
from contextvars import ContextVar
from dataclasses import dataclass, field, replace
from typing import Any

from rig_emulator.faults.journal import FaultJournal
from rig_emulator.faults.spec import (
    NEVER_FAULTED,
    PARAMETER,
    SHIPPED_INSTRUMENT_UNITS,
    SPIKE_FOR_S,
    Entry,
    FaultSpec,
    RandomSpec,
    ReadingRange,
)
from rig_emulator.signals import MEASURED

_EPS_S = 1e-9
log = logging.getLogger("rig_emulator.serve")


@dataclass(frozen=True, slots=True)
class CommDecision:
    """What a faulty unit does with a request."""

    delay_s: float = 0.0
    drop: bool = False
    exception_code: int | None = None


#: the exception code that comes at the operation, after the spec's checks (SERVER DEVICE
#: FAILURE): a request those checks refuse never meets the fault
SERVER_DEVICE_FAILURE = 4


@dataclass(slots=True)
class ActiveFault:
    """A fault that has started."""

    id: int
    spec: FaultSpec
    source: str
    start_s: float
    end_s: float | None  # simulated time it ends; None: until cleared
    held: float | None = None  # stuck: the frozen reading
    served: float = math.nan  # instrument: the reading last served
    requests: int = 0  # communication: requests answered (or not) by this fault
    closed: int = 0  # disconnect: the connections it closed
    #: delay: the requests it holds now (:class:`DelayHold`), let go when it ends
    holds: set[DelayHold] = field(default_factory=set, repr=False, compare=False)

    def as_dict(self) -> dict[str, Any]:
        out = {"id": self.id, **self.spec.as_dict(), "source": self.source}
        out["since_s"] = self.start_s
        out["until_s"] = self.end_s
        out.pop("at_s", None)
        out.pop("for_s", None)
        return out


#: guards the faults' ``requests``: a count may change in the server's event loop (a
#: request decided), an RTU line's thread (a request withdrawn) and wherever a fault ends
#: (a held request's count passed on)
_COUNTS = threading.Lock()


def _count(fault: ActiveFault, change: int) -> None:
    """Add ``change`` to the requests ``fault`` counts (from any thread)."""
    with _COUNTS:
        fault.requests += change


class DelayHold:
    """A request held by delay faults (a stranger's probe: a cleared 20 s delay still held
    the read it had taken, answered 19 s after the clear, though the journal said delay 0).

    The delay it still asks is the longest of its faults still active, from when it was
    taken: each fault that ends (cleared, ``for_s`` elapsed, a reset) drops out and calls
    :attr:`on_change`, from whichever thread ended it; :meth:`close` once it is answered.

    The request counts for the fault that holds it (``counted``, the longest delay, counted
    when decided); one that ends while another still holds the request (that one's delay
    not yet passed) passes the count on, before its end line is written: a 6000-ms delay of
    1 s and a 3000-ms delay on every unit held a read 3 s, and the journal credited the
    6000-ms fault with it, the 3000-ms one with nothing (a re-probe). A delay that ends
    with the request still waiting on it alone keeps the count: the reply went at its end.
    """

    __slots__ = ("_counted", "_delays", "_faults", "_taken", "on_change")

    def __init__(self, faults: list[ActiveFault], counted: ActiveFault | None = None) -> None:
        self._faults = faults
        self._delays = {f.id: _delay_s(f) for f in faults}
        #: the fault the request counts for (None: another fault's effect won, no reply)
        self._counted = counted
        self._taken = time.monotonic()
        #: called when one of its faults ends (the server wakes the request to look again)
        self.on_change: Callable[[], None] | None = None
        for fault in faults:
            fault.holds.add(self)

    @property
    def delay_s(self) -> float:
        """The delay its faults still active ask (0: none is, let it go) [s]."""
        return max(self._delays.values(), default=0.0)

    def ended(self, fault_ids: Collection[int]) -> None:
        """Faults ``fault_ids`` ended (at once: a clear, one evaluation): they hold the
        request no longer, and pass its count to none of them."""
        if not any(i in self._delays for i in fault_ids):
            return
        # a new dict, not a pop: the server may be reading it in its own thread
        self._delays = {i: d for i, d in self._delays.items() if i not in fault_ids}
        with _COUNTS:  # (not while the request is withdrawn in another thread)
            counted = self._counted
            if counted is not None and counted.id in fault_ids:
                heir = self._holder()
                if heir is not None:
                    counted.requests -= 1
                    heir.requests += 1
                    self._counted = heir
        if self.on_change is not None:
            self.on_change()

    def _holder(self) -> ActiveFault | None:
        """The fault that holds the request now: the longest delay still active (the
        newest of equal ones, as :func:`_combine` picks) if it has not passed yet."""
        holder: ActiveFault | None = None
        for fault in self._faults:
            if fault.id in self._delays and (
                holder is None or self._delays[fault.id] >= self._delays[holder.id]
            ):
                holder = fault
        if holder is None or self._delays[holder.id] <= time.monotonic() - self._taken:
            return None
        return holder

    def close(self) -> None:
        """The request is answered (or given up, the client gone): its faults forget it;
        it keeps its count."""
        for fault in self._faults:
            fault.holds.discard(self)
        self._faults = []

    def withdraw(self) -> None:
        """The request was none after all (:meth:`Tally.withdraw`): its count is taken
        back, and its faults forget it."""
        self.close()
        with _COUNTS:
            if self._counted is not None:
                self._counted.requests -= 1
                self._counted = None


class Tally:
    """The faults one request counted for, decided inside :func:`tallying` (for one unit,
    or for each unit an RTU broadcast reaches: each fault counts it once), so they can be
    taken back (:meth:`withdraw`).

    ``replies``: False for a request that gets no reply whatever the faults do (an RTU
    broadcast): a delay fault has nothing to delay and does not count it (three broadcasts
    and a read were journalled as four requests of a delay on unit 1: a re-probe); a
    ``no_reply`` or exception fault does, once, for the units it kept from carrying the
    write out."""

    __slots__ = ("counted", "holds", "replies")

    def __init__(self, replies: bool = True) -> None:
        self.replies = replies
        self.counted: list[ActiveFault] = []
        self.holds: list[DelayHold] = []

    def withdraw(self) -> None:
        """The request was none (an RTU read answered ahead whose frame went on: three reads
        each followed by a stray byte, no reply to any, were journalled as three requests
        answered by the unit's fault; a re-probe): every fault takes back its count."""
        counted, self.counted = self.counted, []
        for fault in counted:
            _count(fault, -1)
        holds, self.holds = self.holds, []
        for hold in holds:
            hold.withdraw()


#: the holds of the request being decided, while a server collects them (:func:`holding`)
_HOLDS: ContextVar[list[DelayHold] | None] = ContextVar("fault_delay_holds", default=None)
#: the faults the request being decided counted for, while a server keeps them (:func:`tallying`)
_TALLY: ContextVar[Tally | None] = ContextVar("fault_tally", default=None)
#: the exception-04 fault that counted the request decided last in this context (a
#: server's task), until :func:`refused_by_checks` takes the count back
_FAILING: ContextVar[ActiveFault | None] = ContextVar("fault_failing", default=None)


def refused_by_checks() -> None:
    """The request decided last in this context got the spec's 01, 02 or 03 (an illegal
    function, address or value), checked before its unit's exception-04 fault acts: that
    fault did not answer it and takes back its count (a stranger's probe: four requests,
    three of them illegal, were journalled as four answered by the fault; one got its 04)."""
    fault = _FAILING.get()
    if fault is not None:
        _count(fault, -1)
        _FAILING.set(None)
        tally = _TALLY.get()
        if tally is not None:
            tally.counted = [f for f in tally.counted if f is not fault]


@contextlib.contextmanager
def holding() -> Iterator[list[DelayHold]]:
    """Decide a request inside this: the list it gives gets a :class:`DelayHold` for each
    delay :meth:`FaultEngine.decide` hands out meanwhile, for the server to wait on (a delay
    decided outside one is a plain number: the server waits it out whole)."""
    held: list[DelayHold] = []
    token = _HOLDS.set(held)
    try:
        yield held
    finally:
        _HOLDS.reset(token)


@contextlib.contextmanager
def tallying(replies: bool = True) -> Iterator[Tally]:
    """Decide one request inside this (for one unit, or for every unit a broadcast reaches):
    the :class:`Tally` it gives keeps the faults it counted for, to take them back should
    it turn out to be no request (``replies``: see :class:`Tally`)."""
    tally = Tally(replies)
    token = _TALLY.set(tally)
    try:
        yield tally
    finally:
        _TALLY.reset(token)


@dataclass(slots=True)
class _RandomState:
    spec: RandomSpec
    rng: random.Random = field(init=False)
    next_s: float = field(init=False)

    def __post_init__(self) -> None:
        self.rng = random.Random(self.spec.seed)
        self.next_s = self.spec.at_s + self._gap()

    def _gap(self) -> float:
        return self.rng.expovariate(self.spec.rate_per_h / 3600.0)

    def draw(
        self, until_s: float, instrument_units: tuple[int, ...], signals: tuple[str, ...]
    ) -> list[FaultSpec]:
        """The faults due up to ``until_s`` (their ``at_s`` the drawn instant), a
        communication fault on one of the spec's units or else of ``instrument_units``, an
        instrument fault on one of its signals or else of ``signals``."""
        spec = self.spec
        stop_s = math.inf if spec.for_s is None else spec.at_s + spec.for_s
        drawn: list[FaultSpec] = []
        while self.next_s <= until_s + _EPS_S and self.next_s < stop_s:
            kind = self.rng.choice(spec.kinds)
            at_s = self.next_s
            self.next_s += self._gap()
            if kind == "disconnect":
                drawn.append(FaultSpec(kind, at_s, None, 0))
                continue
            # a window over before ``until_s`` (a long lockstep advance) is drawn all the
            # same: the engine journals it unseen, and the draws after it are those of
            # short steps (the same seed gives the same faults whatever the advances)
            for_s = SPIKE_FOR_S if kind == "spike" else spec.fault_for_s
            if kind in ("delay", "no_reply", "exception"):
                units = spec.units or instrument_units
                target: dict[str, Any] = {"unit": self.rng.choice(units)}
            elif kind == "offset" and "offset" not in spec.params:
                target = {"signal": "balance_mass_kg"}  # the default offset: a refill
            else:
                target = {"signal": self.rng.choice(spec.signals or signals)}
            drawn.append(FaultSpec(kind, at_s, for_s, parameter=spec.parameter(kind), **target))
        return drawn


class FaultEngine:
    """Faults in simulated time (see the module docstring).

    Args:
        entries: faults to schedule from the start (``source`` names where they came from).
        journal: where start and end events go (None: nowhere).
        plant: the plant's true values of the measured signals, for the journal.
    """

    def __init__(
        self,
        entries: Iterable[Entry] = (),
        journal: FaultJournal | None = None,
        plant: Callable[[], Mapping[str, float]] | None = None,
        source: str = "file",
    ) -> None:
        self.journal = journal
        #: the emulator's own units, which a fault on every unit (0) leaves alone (a server
        #: sets its map's: :func:`~rig_emulator.registers.emulator_units`)
        self.never_faulted: frozenset[int] = frozenset(NEVER_FAULTED)
        #: the units a random communication fault without ``units`` draws from (a server
        #: sets its map's: :func:`~rig_emulator.registers.instrument_units`; the shipped
        #: map's instruments are units 1-7)
        self.instrument_units: tuple[int, ...] = SHIPPED_INSTRUMENT_UNITS
        #: the signals a random instrument fault without ``signals`` draws from (a server
        #: sets the measured signals its map publishes)
        self.signals: tuple[str, ...] = MEASURED
        self.plant = plant
        #: closes every client connection; returns how many (set by the server)
        self.on_disconnect: Callable[[str], int] | None = None
        self.now_s = 0.0
        self._initial = [(e, source) for e in entries]
        self._next_id = 1
        #: (fault, source, simulated time it was set): one set before its at_s keeps it
        self._pending: list[tuple[FaultSpec, str, float]] = []
        self._random: list[_RandomState] = []
        self.active: dict[int, ActiveFault] = {}
        self._by_unit: dict[int, list[ActiveFault]] = {}
        #: per unit (0: every instrument unit without faults of its own), the decision and
        #: the faults whose effect it serves (:func:`_combine`)
        self._decisions: dict[int, tuple[CommDecision, tuple[ActiveFault, ...]]] = {}
        self._instrument: list[ActiveFault] = []
        self._last_instrument: dict[str, float] = {}
        #: per signal, the (lowest, highest) reading its register serves (an integer one
        #: clips there): the journal writes readings as served (set by the server)
        self.reading_ranges: Mapping[str, ReadingRange] = {}
        #: per signal, the lowest value its instrument can show (the profile's
        #: ``reading_min``; set by the server): a fault's reading is floored there as the
        #: instrument's own is, and the journal's start line says what the fault asked for
        self.reading_floors: Mapping[str, float] = {}
        #: per signal, what the faults asked of a reading its floor raised (last evaluation)
        self._asked: dict[str, float] = {}
        self._arm(self._initial)

    # ------------------------------------------------------------------ setting faults
    def _in_range(self, spec: FaultSpec) -> FaultSpec:
        """A drawn spike on a signal whose register cannot carry its value reads the
        register's end, as an instrument's overload does (random spikes of the default
        9999 on an int16 flue-gas temperature were served at 327.67 with a warning that
        blamed the map, where a spike set by hand beyond its register is refused: a
        stranger's probe)."""
        served = self.reading_ranges.get(str(spec.signal)) if spec.kind == "spike" else None
        if served is None or spec.parameter is None:
            return spec
        return replace(spec, parameter=min(max(float(spec.parameter), served.lo), served.hi))

    def _arm(self, entries: Iterable[tuple[Entry, str]]) -> None:
        for entry, source in entries:
            if isinstance(entry, RandomSpec):
                self._random.append(_RandomState(entry))
            else:
                self._pending.append((entry, source, self.now_s))

    def add_initial(self, entries: Iterable[Entry], source: str) -> None:
        """Schedule ``entries`` from the start, again after each reset of the plant."""
        new = [(e, source) for e in entries]
        self._initial += new
        self._arm(new)

    def add(self, entry: Entry, source: str = "python") -> None:
        """Set a fault (or a random source). One without ``at_s``, or whose ``at_s`` has
        passed, starts at once."""
        self._arm([(entry, source)])
        self._update(self.now_s, dict(self._last_instrument))

    def clear(self, reason: str = "cleared") -> int:
        """End every active fault and drop the scheduled and random ones; how many ended.
        The journal has lines only for faults that started, so what is dropped unstarted is
        named in the server's log."""
        n = len(self.active)
        ending = list(self.active.values())
        _let_go(ending)
        for fault in ending:
            self._end(fault, reason)
        dropped = [f"{spec.kind} at {spec.at_s or 0:g} s ({src})" for spec, src, _ in self._pending]
        dropped += ["a random fault generator"] * len(self._random)
        if dropped and reason == "cleared":  # a reset schedules them again
            log.warning("faults cleared: dropped before they started: %s", "; ".join(dropped))
        self._pending.clear()
        self._random.clear()
        self._rebuild()
        return n

    def active_faults(self) -> list[dict[str, Any]]:
        """The active faults, oldest first (for the dashboard and the API)."""
        return [f.as_dict() for f in self.active.values()]

    @property
    def idle(self) -> bool:
        return not (self.active or self._pending or self._random)

    # ------------------------------------------------------------------ per request
    def decide(self, unit_id: int) -> CommDecision | None:
        """What a request to ``unit_id`` gets now (None: a normal answer). The request
        counts once for each fault whose effect it gets (:func:`_combine`): two faults of a
        unit that overlap no longer both counted it (a stranger's probe: ten requests to
        two faulty units were journalled as 25). Decided inside :func:`holding`, a delayed
        one counts for the delay it waits out (:class:`DelayHold`); inside
        :func:`tallying`, its counts can be taken back (:class:`Tally`)."""
        if not self._decisions:
            return None
        key = unit_id if unit_id in self._decisions else 0
        if key == 0 and unit_id in self.never_faulted:
            return None
        combined = self._decisions.get(key)
        if combined is None:
            return None
        decision, effective = combined
        tally = _TALLY.get()
        if tally is not None:  # no reply to delay; a broadcast's units: each fault once
            effective = tuple(
                f
                for f in effective
                if (tally.replies or f.spec.kind != "delay")
                and all(f is not counted for counted in tally.counted)
            )
        for fault in effective:
            _count(fault, 1)
        failing = None
        if decision.exception_code == SERVER_DEVICE_FAILURE:
            failing = next((f for f in effective if f.spec.kind == "exception"), None)
        _FAILING.set(failing)
        hold = None
        if decision.delay_s > 0 and (held := _HOLDS.get()) is not None:
            delaying = next((f for f in effective if f.spec.kind == "delay"), None)
            hold = DelayHold(self._delays_on(unit_id), delaying)
            held.append(hold)
        if tally is not None:
            tally.counted += [f for f in effective if hold is None or f.spec.kind != "delay"]
            if hold is not None:
                tally.holds.append(hold)
        return decision

    def _delays_on(self, unit_id: int) -> list[ActiveFault]:
        """The delay faults acting on ``unit_id`` (as :meth:`_rebuild` combines them)."""
        faults = list(self._by_unit.get(unit_id, ()))
        if unit_id != 0 and (unit_id in self._by_unit or unit_id not in self.never_faulted):
            faults = list(self._by_unit.get(0, ())) + faults
        return [f for f in faults if f.spec.kind == "delay"]

    # ------------------------------------------------------------------ per evaluation
    def apply(self, readings: MutableMapping[str, float], t_sim_s: float) -> None:
        """Start and end faults due at ``t_sim_s``, then change ``readings`` (instrument
        readings by signal) as the active instrument faults say."""
        if self.journal is not None:  # (what a FIFO's reader was behind on, written now)
            self.journal.drain()
        if t_sim_s < self.now_s - _EPS_S:  # the plant was reset: the schedule starts again
            self.clear("reset")
            self.now_s = t_sim_s
            self._arm(self._initial)
        self.now_s = t_sim_s
        if self.idle:
            self._last_instrument = dict(readings)
            return
        self._update(t_sim_s, readings)

    def _update(self, t_sim_s: float, readings: MutableMapping[str, float] | None) -> None:
        if readings is not None:
            self._last_instrument = dict(readings)
        ended = [f for f in self.active.values() if _over(f, t_sim_s)]
        due = [p for p in self._pending if p[0].at_s is None or p[0].at_s <= t_sim_s + _EPS_S]
        if due:
            self._pending = [p for p in self._pending if p not in due]
        for state in self._random:
            due += [
                (self._in_range(s), "random", -math.inf)
                for s in state.draw(t_sim_s, self.instrument_units, self.signals)
            ]
        for fault in ended:
            del self.active[fault.id]
        _let_go(ended)
        started: list[ActiveFault] = []
        unseen: list[ActiveFault] = []  # windows wholly between two evaluations: act not
        for spec, src, set_s in due:
            fault = self._new(spec, src, _start_s(spec, set_s, t_sim_s))
            if _over(fault, t_sim_s):
                unseen.append(fault)
            else:
                started.append(self._start(fault, t_sim_s))
        if ended or started:
            self._rebuild()
        if readings is not None and self._instrument:
            self._transform(readings, t_sim_s)
        # the journal in the order of the windows' own times
        events: list[tuple[float, str, ActiveFault, dict[str, Any] | None]] = [
            (_end_s(f, t_sim_s), "end", f, None) for f in ended
        ]
        events += [(f.start_s, "start", f, None) for f in started if f.spec.kind != "disconnect"]
        once: set[int] = set()  # disconnects that happened (their end: "once")
        for fault in started:  # a disconnect is journalled as it happened: at this evaluation,
            if fault.spec.kind == "disconnect":  # in time order with the rest (it came first)
                closed = {"connections_closed": fault.closed}
                events += [(t_sim_s, "start", fault, closed), (t_sim_s, "end", fault, None)]
                once.add(fault.id)
        for fault in unseen:
            events += [(fault.start_s, "start", fault, _UNSEEN)]
            events += [(_end_s(fault, t_sim_s), "end", fault, _UNSEEN)]
        for t_s, event, fault, served in sorted(events, key=lambda e: e[0]):
            shown = None if served is not None else readings
            reason = None
            if event == "end":
                reason = "once" if fault.id in once else "for_s elapsed"
            self._journal(event, fault, t_s, shown, served, reason)

    def _new(self, spec: FaultSpec, source: str, start_s: float) -> ActiveFault:
        """A fault of ``spec`` whose window begins at ``start_s`` (a spike without ``for_s``
        lasts one acquisition)."""
        for_s = spec.for_s
        if for_s is None and spec.kind == "spike":
            for_s = SPIKE_FOR_S
        fault = ActiveFault(
            self._next_id, spec, source, start_s, None if for_s is None else start_s + for_s
        )
        self._next_id += 1
        return fault

    def _start(self, fault: ActiveFault, t_sim_s: float) -> ActiveFault:
        """Make ``fault`` act; the evaluation is at ``t_sim_s`` (a disconnect happens then)."""
        spec = fault.spec
        if spec.kind == "disconnect":  # (journalled by the caller, in time order)
            if self.on_disconnect is not None:
                fault.closed = self.on_disconnect(f"disconnect fault #{fault.id}")
            return fault
        # a stuck reading is held at what the first evaluation serves, the faults started
        # before it applied (:meth:`_transform`): an active offset or drift stays in it
        self.active[fault.id] = fault
        return fault

    def _end(self, fault: ActiveFault, reason: str) -> None:
        """End ``fault`` for ``reason`` (the requests it held let go by the caller)."""
        self.active.pop(fault.id, None)
        self._rebuild()
        self._journal("end", fault, self.now_s, None, reason=reason)

    def _rebuild(self) -> None:
        """The per-unit decisions and the instrument faults, from the active faults."""
        by_unit: dict[int, list[ActiveFault]] = {}
        instrument: list[ActiveFault] = []
        for fault in self.active.values():
            if fault.spec.is_comm:
                by_unit.setdefault(int(fault.spec.unit or 0), []).append(fault)
            else:
                instrument.append(fault)
        decisions: dict[int, tuple[CommDecision, tuple[ActiveFault, ...]]] = {}
        for unit, faults in by_unit.items():
            if unit != 0 and 0 in by_unit:
                faults = by_unit[0] + faults
            decisions[unit] = _combine(faults)
        self._by_unit = by_unit
        self._decisions = decisions
        self._instrument = instrument

    def _transform(self, readings: MutableMapping[str, float], t_sim_s: float) -> None:
        """The active instrument faults' readings, in the order they started, each on what
        the ones before it served; then each faulted signal's floor (the instrument's
        ``reading_min``), as the instrument applies it to its own reading: an offset of
        -1 m/s on the ``lab`` profile's vortex meter, which reads no velocity below 0,
        served -0.99 m/s (a stranger's probe). A NaN (a dropout) stays NaN."""
        self._asked = {}
        for fault in self._instrument:
            spec = fault.spec
            signal = str(spec.signal)
            value = readings.get(signal, math.nan)
            kind = spec.kind
            if kind == "stuck":
                if fault.held is None or math.isnan(fault.held):
                    fault.held = value
                value = fault.held
            elif kind == "drift":
                value += float(spec.parameter or 0.0) * (t_sim_s - fault.start_s) / 3600.0
            elif kind == "spike":
                value = float(spec.parameter or 0.0)
            elif kind == "dropout":
                value = math.nan
            else:  # offset
                value += float(spec.parameter or 0.0)
            readings[signal] = value
            fault.served = value
        for signal in {str(fault.spec.signal) for fault in self._instrument}:
            floor = self.reading_floors.get(signal)
            if floor is not None and readings[signal] < floor:  # (NaN: False)
                self._asked[signal] = readings[signal]
                readings[signal] = floor

    # ------------------------------------------------------------------ journal
    def _journal(
        self,
        event: str,
        fault: ActiveFault,
        t_sim_s: float,
        readings: Mapping[str, float] | None,
        served: dict[str, Any] | None = None,
        reason: str | None = None,
    ) -> None:
        if self.journal is None:
            return
        spec = fault.spec
        line: dict[str, Any] = {
            "event": event,
            "id": fault.id,
            "t_sim_s": t_sim_s,
            "t_wall": time.time(),
            "kind": spec.kind,
            **({"unit": spec.unit} if spec.is_comm else {"signal": spec.signal}),
            "source": fault.source,
        }
        name = PARAMETER[spec.kind]
        if name is not None:  # an exception code is a whole number, as served
            line[name] = int(spec.parameter or 0) if spec.kind == "exception" else spec.parameter
        if served is None:
            served = self._served(event, fault, readings)
        line["served"] = served
        if event == "start":  # as asked: a fault set after its at_s starts when it is set
            line |= {key: v for key in ("at_s", "for_s") if (v := getattr(spec, key)) is not None}
        if event == "end":
            line["reason"] = reason
            if spec.is_comm:
                line["requests"] = fault.requests
        self.journal.write(line)

    def _served(
        self, event: str, fault: ActiveFault, readings: Mapping[str, float] | None
    ) -> dict[str, Any]:
        spec = fault.spec
        if spec.kind == "delay":
            return {"delay_ms": spec.parameter} if event == "start" else {"delay_ms": 0}
        if spec.kind == "no_reply":
            return {"reply": "none"} if event == "start" else {"reply": "normal"}
        if spec.kind == "exception":
            code = int(spec.parameter or 0)
            return {"exception_code": code} if event == "start" else {"exception_code": None}
        if spec.kind == "disconnect":  # its start says how many it closed; its end nothing
            return {}
        signal = str(spec.signal)
        truth = math.nan
        if self.plant is not None:
            truth = float(self.plant().get(signal, math.nan))
        if readings is None:  # ended between evaluations: the instrument's own reading
            reading = self._last_instrument.get(signal, math.nan) if event == "end" else math.nan
        else:
            reading = readings.get(signal, math.nan)
        instrument = self._last_instrument.get(signal, math.nan)
        served = self.reading_ranges.get(signal)
        if served is not None:  # as served: a spike of 9999 on 327.67 at most, on its steps
            reading, instrument = served.served(reading), served.served(instrument)
        out = {"reading": reading, "instrument": instrument, "truth": truth}
        if event == "start" and readings is not None and signal in self._asked:
            asked = self._asked[signal]  # (below the instrument's floor: not served)
            out["asked"] = asked if served is None else _on_steps(served, asked)
        return out


_UNSEEN = {"seen": False, "why": "its whole window fell between two evaluations"}


def _start_s(spec: FaultSpec, set_s: float, t_sim_s: float) -> float:
    """Where a due fault's window starts: its ``at_s`` if it was set before that, else now."""
    if spec.at_s is not None and spec.at_s >= set_s - _EPS_S:
        return min(spec.at_s, t_sim_s)
    return t_sim_s


def _on_steps(served: ReadingRange, value: float) -> float:
    """``value`` on the steps of the register that serves its signal, as its readings are
    journalled, but not clipped to the register's range: what the faults asked for (a stuck
    fault holding an offset's -0.93 m/s was journalled as asking -0.9299999999999999, a
    re-probe)."""
    if served.step <= 0 or not math.isfinite(value):
        return value
    return round(served.lo + round((value - served.lo) / served.step) * served.step, 9)


def _let_go(faults: list[ActiveFault]) -> None:
    """``faults`` ended together: the requests they held wait for them no longer (one that
    another of them held too is told once, so its count goes to none of them)."""
    holds: set[DelayHold] = set()
    for fault in faults:
        holds.update(fault.holds)
        fault.holds.clear()
    ended = {fault.id for fault in faults}
    for hold in holds:
        hold.ended(ended)


def _over(fault: ActiveFault, t_sim_s: float) -> bool:
    return fault.end_s is not None and fault.end_s <= t_sim_s + _EPS_S


def _end_s(fault: ActiveFault, t_sim_s: float) -> float:
    """The simulated time a fault's window ended (its own, not the evaluation's)."""
    return t_sim_s if fault.end_s is None else min(fault.end_s, t_sim_s)


def _combine(faults: list[ActiveFault]) -> tuple[CommDecision, tuple[ActiveFault, ...]]:
    """One decision from several communication faults on a unit, and the faults whose
    effect it serves, which alone count its requests. ``faults`` come as the all-units
    faults (unit 0) and then the unit's own, each oldest first, and of a kind the last one
    wins: the unit's own over an all-units fault, then the newest (a re-probe: an 06 set on
    unit 2 still answered after a newer 0B on every unit). No reply wins over everything
    (nothing else reaches the client); else the last exception and the longest delay (the
    last of equal ones). A fault another of its kind overrides serves nothing."""
    dropping: ActiveFault | None = None
    excepting: ActiveFault | None = None
    delaying: ActiveFault | None = None
    for fault in faults:
        kind = fault.spec.kind
        if kind == "no_reply":
            dropping = fault
        elif kind == "exception":
            excepting = fault
        elif kind == "delay" and (delaying is None or _delay_s(fault) >= _delay_s(delaying)):
            delaying = fault
    delay_s = 0.0 if delaying is None else _delay_s(delaying)
    if dropping is not None:
        return CommDecision(delay_s, True, None), (dropping,)
    code = None if excepting is None else int(excepting.spec.parameter or 0)
    effective = tuple(f for f in (excepting, delaying) if f is not None)
    return CommDecision(delay_s, False, code), effective


def _delay_s(fault: ActiveFault) -> float:
    """A delay fault's delay [s]."""
    return float(fault.spec.parameter or 0.0) / 1000.0
