"""The Modbus rig: drives a running ``rig-emulator serve`` as a test controller would.

It reads the same register map as the server, writes the flow and return setpoints every
step and the pump, heater and boiler switches when they change, lets one acquisition period
of simulated time pass, and polls every instrument. All requests go over one connection,
addressed by unit ID, and those of one step are pipelined (sent together; the server answers
them in order), so a lockstep step is a single round trip.

Time: in lockstep the rig advances the server itself (writing ``lockstep_advance``; the
reply means the new state is readable), so runs are deterministic; in real time or
accelerated mode it follows the server's clock, waiting until its simulated time has moved
on by the acquisition period.

A log never splices two plants (CONTRACT section 7). Every step also reads the simulation
control unit (in the same pipelined batch): the server's epoch (random per start), its
lockstep counter, its simulated time and the identity of its set-up (boiler, profile,
seed). The rig knows what to expect, so it detects

- a lost connection: retried with exponential backoff (0.1 s doubling to 5 s, up to
  ``reconnect_timeout_s``); on the same plant a lockstep step that may not have happened is
  settled by the counter and the time, and the outage is recorded in :attr:`gaps`;
- a restarted server (a new epoch): in lockstep with the same boiler, profile and seed, the
  rig replays its journal (every step's requests, as sent) onto the fresh plant and goes
  on, so the log equals an uninterrupted run; with another set-up it stops (:class:`RigError`);
- another client's advance or reset (time or counter not what this rig expects), and a
  restart in real time: a *break*, handled per ``on_restart``: ``abort`` (stop with a
  :class:`RigError`), ``continue`` or ``restart-phase`` (go on with :attr:`epoch` one higher,
  the runner restarting the phase for the latter).

Faulty instruments (CONTRACT section 5) never stop a run: a unit that gives no reply (a
later reply comes first, or the timeout passes), answers with an exception, or sends an
invalid reading (NaN, or an integer at its invalid code: the type's most negative value if
signed, its largest if unsigned) leaves its fields empty in that row, never the last value;
a failed setpoint write is sent again next step. Each is an entry of :attr:`comm_events`
(``time_s`` of the row, ``server_time_s``, ``event``: ``timeout``, ``no_reply``,
``exception`` with its ``code``, ``late`` with ``wait_s``, ``invalid``, ``disconnect``,
``overridden``: the boiler's controller shows another on/off state than this rig wrote,
or the bench's pump, return heating or setpoints read back (:data:`READ_BACK`) are not
what it wrote, another client's doing, written again, with ``read``: what they showed;
``unit``, ``function`` and ``signals``). After a
timeout the rig reconnects, so later steps do not queue behind a slow unit (on an RTU
line a silent unit costs one timeout per request, one transaction at a time). The
simulation control (unit 100) must answer: its transient exceptions (06 busy, a gateway's
0A and 0B) are asked again after a short pause, within the reply timeout, each an
``exception`` event with ``retried``; one that persists stops the run. A 0A or 0B before
unit 100 has ever answered is no passing one: a server without that unit (another map)
says so from the first request, and the run stops at once (it waited the whole reply
timeout for the same error: a stranger's re-probe).

What the Modbus specification leaves to a device is learned once and kept: a block of
readings a unit refuses as too long (02 or 03: it may take fewer than 125 registers a read)
is read in halves, down to a point at a time (:meth:`ModbusRig._in_pieces`); coils a unit
refuses to write with FC15 (01) go as FC5, one each, and a unit that refuses both is a
:attr:`refusal`. :attr:`ModbusRig.notes` are the lines a run tells once as they arise (a
unit that refuses its reads even in pieces, one whose coils take FC5 only);
:meth:`ModbusRig.end_notes` those of its end (a unit that refused every read, the readings
at their register's limit, each limit with its rows).

Plant commands refused as an illegal value (exception 03: the server's map does not take
that value, for the whole run) are no fault: a unit that answers its reads in the same step
but refuses a write with 03 sets :attr:`refusal`, and the runner stops (a unit under an
``exception`` fault answers its reads with it too: transient). A unit that takes commands
but has no readings (a pump PLC of its own) is read back at a written point every step,
so that its health is known the same way (never confirmed healthy, a 5-s exception fault
on it stopped the run as a refusal: a stranger's probe).
:attr:`written_flow_setpoint_kg_h` is the flow setpoint the server took from this rig's
writes, as its point's encoding carries it (the log's column). In real time every step
also reads the server's speed: a change (another client, through the simulation control)
is a gap with ``speed_before`` and ``speed_after`` that loses no row, the run going on
(:attr:`speeds`: every speed seen), and :attr:`step_timing` tells who a hole in the rows
is due to, over the wall time between the two reads of the server's clock the hole lies
between: a unit whose replies came late (a slow unit, a delay fault), a server that
answered late (it stalled), or a client held up.

Each break or outage is an entry of :attr:`gaps` in the log's own time base
(``start_time_s``: the last row before, ``end_time_s``: the first row after, None if none).
The log time is the server's time plus an offset; across a break it jumps by the time the
plant moved meanwhile (the server's time on the same plant, else the wall-clock outage at
the server's speed in real time), never joining rows as if continuous. Each entry also says
how long this client was held up since the row before it (``client_held_up_s``, measured by
:mod:`hil_client.rigs.holdups`), and the reason of a lost connection names a hold-up of
:data:`HELD_UP_S` or more: a server's idle timeout closes a client silent that long.
"""

from __future__ import annotations

import contextlib
import math
import struct
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlparse

from hil_client.modbus_client import (
    IN_ORDER_EVIDENCE,
    READ_FUNCTIONS,
    Connection,
    ConnectionLost,
    ModbusExceptionResponse,
    NoReply,
    Reply,
    UnpairedReplies,
    bits_of,
    read_pdu,
    registers_of,
    write_coils_pdu,
    write_registers_pdu,
)
from hil_client.protocol.rig import (
    OPTIONAL_READINGS,
    READING_KEYS,
    RigCommand,
    RigError,
    StepTiming,
)
from hil_client.rigs.holdups import held_up_s
from hil_client.rigs.transports import GarbledReply, RtuConnection, url_port
from rig_emulator.emulator import check_command
from rig_emulator.registers import (
    MapError,
    Point,
    RegisterMap,
    encode,
    invalid_value,
    legacy_map_identity,
    map_identity,
    reading_range,
    run_decoder,
    written_value,
)
from rig_emulator.registers.codec import accepted_range, encodable_range
from rig_emulator.registers.datatypes import DATATYPES

_READ_FUNCTION = {"coil": 1, "discrete": 2, "holding": 3, "input": 4}
_TABLE_OF_FUNCTION = {function: table for table, function in _READ_FUNCTION.items()}
#: what a unit may answer a read longer than it takes at once (the specification lets a
#: device allow fewer than 125 registers a read): 03 (illegal data value: the quantity) or
#: 02 (illegal data address: the range); the read is asked again in pieces
_TOO_LONG = {2: "02 (illegal data address)", 3: "03 (illegal data value)"}
#: what the simulation control may answer for a moment (06: busy, "retransmit the request
#: later", the specification says; 0A: a gateway found no path; 0B: the gateway's target did
#: not answer): asked again after a pause, within the reply timeout (one 0B ended a run)
TRANSIENT_CODES = frozenset({0x06, 0x0A, 0x0B})
_TRANSIENT_PAUSE_S = 0.05  # the first pause before asking again, doubled each time,
_TRANSIENT_MAX_PAUSE_S = 1.0  # up to this; all of it within --reply-timeout

#: What ``on_restart`` may say (see the module docstring).
ON_RESTART = ("abort", "restart-phase", "continue")
#: Signals of the simulation control read with every step, and also on (re)connecting.
CHECK_KEYS = ("sim_time_s", "lockstep_counter", "epoch_id")
STATUS_KEYS = (*CHECK_KEYS, "boiler_id", "profile_id", "seed")
_IDENTITY = {"boiler_id": "boiler", "profile_id": "profile", "seed": "seed"}
#: Commands the rig writes (the setpoints, the switches, the lockstep clock).
WRITES = (
    "water_flow_setpoint_kg_h",
    "return_setpoint_C",
    "pump_on",
    "return_heating",
    "boiler_command",
    "lockstep_advance_s",
)
#: The setpoints the rig writes every step (checked against what their points carry).
SETPOINTS = ("water_flow_setpoint_kg_h", "return_setpoint_C")
#: The bench's commands read back with every step's readings (with checks): another
#: client's write of one shows, as the boiler's switch shows in its controller's mode (a
#: second client switched the bench pump off mid-test: 20,000 rows of flow 0, exit 0, and
#: wrote return setpoints unseen: a stranger's probe).
READ_BACK = ("water_flow_setpoint_kg_h", "return_setpoint_C", "pump_on", "return_heating")
#: Every signal the rig reads or writes: a register map must have them all.
NEEDED = (
    *(s for s in READING_KEYS if s not in OPTIONAL_READINGS),
    *STATUS_KEYS,
    "clock_mode",
    "speed_factor",
    *WRITES,
)
# a replay batch stays in one small segment: the server drops a receive buffer above 264
# bytes (pymodbus's max_buffer_size for Modbus TCP: the largest frame, 260, and slack)
_REPLAY_SEGMENT_BYTES = 240
_TIME_TOLERANCE_S = 1e-6  # the server's float64 time against the rig's sum of the same steps
LATE_S = 0.25  # an instrument's reply this much after the one before it: a "late" event
#: this client held up this long since its last row (:mod:`hil_client.rigs.holdups`) when the
#: server closed its connection: a gap's reason names it (``serve --idle-timeout`` takes
#: fractions of a second: a 0.9-s hold-up under 0.5 s went unnamed, a re-probe; a busy
#: machine holds a process up for milliseconds)
HELD_UP_S = 0.5
#: a garbled reply (bad CRC) to the first status read is asked again this many times: a
#: line that garbles four in a row is no line to run on
GARBLED_RETRIES = 3


class _Break(Exception):
    """The plant is not the one this rig expects (restart, another client's advance or reset)."""

    def __init__(self, reason: str, status: dict[str, float]) -> None:
        super().__init__(reason)
        self.reason = reason
        self.status = status

    @property
    def foreign(self) -> bool:
        """Another client's doing (an advance or a reset), not a restart."""
        return self.reason.startswith("another client")


#: Breaks by another client's advance or reset within :data:`FOREIGN_WINDOW_STEPS` steps
#: after which a run that goes on from breaks stops: another run is stepping the same
#: server, and neither's log is one plant's (two lockstep runs with --on-restart continue
#: broke at every step, the meta grew to 2 MB and both crawled: a stranger's probe; one
#: stepping it every 30 ms, a clean step between, made 121 breaks: a re-probe)
FOREIGN_BREAKS_MAX = 5
FOREIGN_WINDOW_STEPS = 200


@dataclass(frozen=True, slots=True)
class _Read:
    """One read request: a contiguous run of points of one table of one unit."""

    unit: int
    function: int
    start: int
    count: int
    points: tuple[Point, ...]
    decode: Callable[[Sequence[int]], list[float]]  # the run's registers -> its values


def _has_point(register_map: RegisterMap, signal: str) -> bool:
    try:
        register_map.point(signal)
    except KeyError:
        return False
    return True


def check_map(register_map: RegisterMap) -> None:
    """:class:`~rig_emulator.registers.MapError` naming the first signal the rig needs
    (:data:`NEEDED`) that ``register_map`` has no point for, or cannot write."""
    for signal in NEEDED:
        try:
            _, point = register_map.point(signal)
        except KeyError:
            raise MapError(
                f"{register_map.source}: no point for '{signal}' (the Modbus rig needs it)"
            ) from None
        if signal in WRITES and not point.writable:
            raise MapError(
                f"{register_map.source}: point '{point.name}' ({signal}) is read-only; "
                "the Modbus rig writes it (access: rw)"
            )


def parse_url(url: str) -> tuple[str, int]:
    """(host, port) of ``modbus://HOST:PORT``."""
    parsed = urlparse(url)
    if parsed.scheme != "modbus" or not parsed.hostname:
        raise ValueError(f"'{url}' is not modbus://HOST:PORT")
    return parsed.hostname, url_port(url, 502)


def _read_plan(
    register_map: RegisterMap, signals: tuple[str, ...], trim: bool = False
) -> list[_Read]:
    """The fewest requests that read every signal (contiguous runs only: gaps answer 02);
    ``trim``: each request spans only from its first to its last wanted point."""
    wanted: dict[tuple[int, str], list[Point]] = {}
    for signal in signals:
        try:
            device, point = register_map.point(signal)
        except KeyError:
            raise RigError(f"register map {register_map.source}: no point for '{signal}'") from None
        wanted.setdefault((device.unit_id, point.table), []).append(point)
    plan: list[_Read] = []
    for (unit, table), points in wanted.items():
        device = next(d for d in register_map.devices if d.unit_id == unit)
        table_points = device.table(table)
        points.sort(key=lambda p: p.address)
        runs: list[list[Point]] = []
        for p in table_points:
            if not runs or p.address != runs[-1][-1].address + runs[-1][-1].width:
                runs.append([])
            runs[-1].append(p)
        for run in runs:
            hits = [i for i, q in enumerate(run) if q in points]
            if hits:
                plan.append(_make_read(unit, table, run[hits[0] : hits[-1] + 1] if trim else run))
    return plan


def _request(read: _Read) -> tuple[int, bytes]:
    """The (unit, PDU) of one read."""
    return read.unit, read_pdu(read.function, read.start, read.count)


def _make_read(unit: int, table: str, run: list[Point]) -> _Read:
    start = run[0].address
    count = run[-1].address + run[-1].width - start
    return _Read(unit, _READ_FUNCTION[table], start, count, tuple(run), run_decoder(run))


def _halves(read: _Read) -> list[_Read]:
    """``read`` (of two points or more) as two reads of about half its registers each."""
    middle = read.start + read.count / 2
    first = [p for p in read.points if p.address + p.width <= middle] or [read.points[0]]
    first = first[: len(read.points) - 1]
    table = _TABLE_OF_FUNCTION[read.function]
    return [
        _make_read(read.unit, table, first),
        _make_read(read.unit, table, list(read.points[len(first) :])),
    ]


def _register_limits(point: Point) -> tuple[float, ...]:
    """The ends of what ``point``'s register serves as a reading, a zero and infinities
    aside (a uint's 0 is a reading): an integer's type range, scaled; a float's largest
    finite value either side (a float32 at 3.4028235e38 was logged as a forward
    temperature, the summary said "inf kWh": a stranger's probe)."""
    is_float = DATATYPES[point.datatype].is_float
    ends = encodable_range(point) if is_float else reading_range(point)
    return tuple(x for x in ends if math.isfinite(x) and x != 0.0)


def _write_coil_pdu(address: int, on: bool) -> bytes:
    """FC5 (write single coil) request: 0xFF00 on, 0x0000 off."""
    return struct.pack(">BHH", 5, address, 0xFF00 if on else 0x0000)


def _role_hint(url: str, exc: ModbusExceptionResponse) -> str:
    """Why a Modbus/TCP Security server may answer 01 (its log names the role and the
    request); "" where that is not the case (a stranger's probe: a certificate of an
    unknown role read as "not a rig-emulator with this map?", one without the engineer
    role gave only "function 16 refused")."""
    if exc.code != 1 or not url.startswith("modbus+tls://"):
        return ""
    if exc.function in (1, 2, 3, 4):
        return (
            " (this client certificate's role may not read it: a role the server does not "
            "know may do nothing; the server's log says which role it read)"
        )
    return (
        " (this client certificate's role may not write it: the instruments need operator, "
        "the simulation control (a lockstep server's advance) engineer; the server's log "
        "says which role it read)"
    )


class MapMismatch(RigError):
    """The server serves another register map than the client's, found before the first
    row: the client's ``--map`` is the wrong one (bad input, as another boiler is)."""


class ModbusRig:
    """A remote bench reached over Modbus TCP (see the module docstring).

    Args:
        url: ``modbus://HOST:PORT``.
        register_map: the server's map.
        timeout_s: timeout of one request [s].
        reconnect_timeout_s: give up after an outage this long [s].
        on_restart: what a break does: ``abort``, ``restart-phase`` or ``continue``.
        checks: read and check the simulation control each step and keep the journal (off
            only to measure what they cost: ``make bench``).
        connect: opens a connection (TLS, RTU: :func:`hil_client.rigs.transports.connector`);
            None: plain TCP to the ``modbus://`` URL.
    """

    def __init__(
        self,
        url: str,
        register_map: RegisterMap,
        timeout_s: float = 5.0,
        reconnect_timeout_s: float = 60.0,
        on_restart: str = "abort",
        checks: bool = True,
        connect: Callable[[], Connection] | None = None,
    ) -> None:
        if connect is None:
            try:
                self.host, self.port = parse_url(url)
            except ValueError as exc:
                raise RigError(str(exc)) from None
        self._open = connect or (lambda: Connection(self.host, self.port, self.timeout_s))
        if on_restart not in ON_RESTART:
            raise RigError(f"on_restart: '{on_restart}' is not one of {', '.join(ON_RESTART)}")
        self.url = url
        self.map = register_map
        self.timeout_s = timeout_s
        self.reconnect_timeout_s = reconnect_timeout_s
        self.on_restart = on_restart
        check_map(register_map)
        #: the runner restarts the current phase when :attr:`epoch` changes
        self.restart_phase = on_restart == "restart-phase"
        self.checks = checks
        self.gaps: list[dict[str, Any]] = []
        #: what faulty units did (see the module docstring), in order
        self.comm_events: list[dict[str, Any]] = []
        self._step_events: list[dict[str, Any]] = []
        self._own_units = {
            register_map.point(s)[0].unit_id for s in (*STATUS_KEYS, "lockstep_advance_s")
        }
        self._invalid = {
            p.signal: v
            for d in register_map.devices
            for p in d.points
            if p.signal in READING_KEYS and (v := invalid_value(p)) is not None
        }
        #: each reading's register limits (the ends of what its point serves, a zero aside:
        #: a uint's 0 is a reading): a value there is the register's, not the plant's (a
        #: flue gas as int16 x0.001 read 32.767 C for hours, the phases were found from it
        #: and the balance was wrong, exit 0: a stranger's probe)
        self._limits: dict[str, tuple[int, str, tuple[float, ...]]] = {}
        #: the readings this map serves (a bench without an FID has no OGC: its field empty)
        self._served = tuple(
            s for s in READING_KEYS if s not in OPTIONAL_READINGS or _has_point(register_map, s)
        )
        #: the optional readings the map has no point for (their columns stay empty)
        self.absent = tuple(s for s in OPTIONAL_READINGS if s not in self._served)
        for signal in self._served:
            device, point = register_map.point(signal)
            ends = _register_limits(point)
            if ends:
                self._limits[signal] = (device.unit_id, point.name, ends)
        #: readings logged empty for standing at their register's limit: signal ->
        #: (unit, point, {limit: rows}) (:meth:`limit_note`)
        self.pinned: dict[str, tuple[int, str, dict[float, int]]] = {}
        #: lines the run tells once, as they arise (a warning each, and a note of the meta
        #: file): a unit that refuses its reads even in pieces, one whose coils take FC5 only
        self.notes: list[str] = []
        self._split_tried: set[tuple[int, int, int]] = set()  # reads asked in pieces once
        self._whole_answered: set[tuple[int, int, int]] = set()  # ... answered whole once
        self._single_coil_units: set[int] = set()  # units that refused FC15: FC5 instead
        self._single_coils_said: set[int] = set()  # ... whose FC5 answered, said in notes
        self._answered_units: set[int] = set()  # units that answered a read with data
        #: per unit, why its reads failed in this step (:meth:`_decode_tolerant`), and over
        #: the run: the rows it failed in and why (:meth:`end_notes`)
        self._step_failures: dict[int, dict[str, None]] = {}
        self._failed_rows: dict[int, dict[float, None]] = {}
        self._failure_reasons: dict[int, dict[str, None]] = {}
        self._failed_signals: dict[int, dict[str, None]] = {}  # the readings of those reads
        self.rows_stepped = 0  # steps completed: the rows of the log
        #: the ``rig_epoch`` column: 0, one higher after each break the rig went on from
        self.epoch = 0
        plan = _read_plan(register_map, self._served)  # a required reading missing fails
        self._status_plan = _read_plan(register_map, STATUS_KEYS)
        self._check_plan = _read_plan(register_map, CHECK_KEYS, trim=True)
        self._clock_plan = _read_plan(register_map, ("clock_mode", "speed_factor"))
        self._points = {s: register_map.point(s) for s in WRITES}
        #: what a setpoint's point can carry (its map range, narrowed to its encoding)
        self._accepted = {s: accepted_range(self._points[s][1]) for s in SETPOINTS}
        self._time_point = register_map.point("sim_time_s")[1]
        self._time_max = reading_range(self._time_point)[1]  # a float's: inf
        if any(p.signal == "reset" for d in register_map.devices for p in d.points):
            self._points["reset"] = register_map.point("reset")  # (optional: a rebuild)
        self._conn: Connection | None = None
        self._earlier: Connection | None = None  # the last connection closed
        self._own_answered = False  # the simulation control answered a request with data
        self._dead = False  # the last patient wait found its connection dead (_still_coming)
        self._head_own = False  # ... and the request it was silent on was the rig's own
        self._command: RigCommand | None = None
        self._written_switches: tuple[bool, bool, bool] | None = None
        #: the switches went out with this step's reads: the boiler's mode may not show them
        #: yet (a real-time server's controller takes them at its next tick)
        self._switches_in_flight = False
        self._foreign_breaks: list[int] = []  # another client's breaks: the steps by then
        #: the setpoints this step's writes carried, where the server took them (read back
        #: in real time only: in lockstep they go with the advance)
        self._setpoints_taken: dict[str, float] = {}
        self._setpoints_sent: list[dict[str, float]] = []  # ... per command request
        #: the flow setpoint the server holds from this rig's writes, as carried (the log's)
        self.written_flow_setpoint_kg_h = math.nan
        self._command_labels: list[str] = []  # what each command request of the step sets
        #: writes refused this step as no fault would (03; 01 to FC15 and FC5): (unit,
        #: what was refused and how, why the method cannot be carried out: "" the 03's)
        self._refused: list[tuple[int, str, str]] = []
        self._faulty: set[int] = set()  # units a read of which got no data, last step
        #: a plant command refused as an illegal value (see the module docstring), or None
        self.refusal: str | None = None
        #: where the wall time went between the last two reads of the server's clock
        self.step_timing = StepTiming()
        self._paced_s = 0.0  # ... since the last read of the clock: waited on purpose,
        self._server_wait_s = 0.0  # on the simulation control's replies,
        self._unit_waits: dict[int, float] = {}  # on each instrument's
        self.values: dict[str, float] = {}
        self._map_check = (plan, register_map)  # checked again when a server comes back
        try:
            status = self._first_status()
            problem = self._map_problem(plan, register_map)
            if problem is not None:
                raise MapMismatch(f"{url}: {problem}")
        except ConnectionLost as exc:
            hint = ""
            if url.startswith("modbus://") and "closed by the server" in str(exc):
                hint = " (a Modbus/TCP Security port closes plain connections: modbus+tls://?)"
            elif url.startswith("modbus-rtu://") and "no reply" in str(exc):
                hint = (  # (a stranger's probe: the emulator now answers as a device would)
                    " (a device at another baud rate or parity than the URL's gets every "
                    "frame garbled and answers none: ?baud=...&parity=...; the server's log "
                    "names the speed a master set)"
                )
            elif url.startswith("modbus+tls://") and "closed by the server" in str(exc):
                hint = (
                    " (a Modbus/TCP Security server closes the connection of a client "
                    "certificate it refuses: expired, not signed by its CA; its log says why)"
                )
            # (it answered: no "cannot reach")
            reached = isinstance(exc, UnpairedReplies | GarbledReply)
            raise RigError(f"{'' if reached else 'cannot reach '}{url}: {exc}{hint}") from None
        except ModbusExceptionResponse as exc:
            why = _role_hint(url, exc) or " (not a rig-emulator with this map?)"
            raise RigError(f"{url}: {exc}{why}") from None
        self.lockstep = status["clock_mode"] == 1.0
        self.speed = status["speed_factor"]
        #: every speed of the server's clock this run saw, in order (another client may
        #: change it)
        self.speeds = [self.speed]
        self.sim_time_s = status["sim_time_s"]
        self.identity = {key: int(status[key]) for key in ("epoch_id", *_IDENTITY)}
        self._epoch_id = status["epoch_id"]
        # journal (lockstep): every step's requests as sent, and the server time after it;
        # the server holds the first ``_applied`` of them on top of its state at the start
        self._journal: list[list[tuple[int, bytes]]] = []
        self._journal_time: list[float] = []
        self._applied = 0  # how many the server holds
        self._logged = 0  # how many were read and returned as rows
        self._base_counter = int(status["lockstep_counter"])
        self._base_time = status["sim_time_s"]
        # a restarted server can be rebuilt only if this run began on a fresh one
        self._replayable = self._base_counter == 0 and self._base_time == 0.0
        # log time = server time + offset; the last row's times
        self.log_time_s = 0.0
        self._stepped = False  # a step has given a row
        self._offset = -status["sim_time_s"]
        self._row_server_time = status["sim_time_s"]
        self._row_wall = time.monotonic()
        self._row_held_s = held_up_s()  # this process's hold-ups by the last row
        self._clock_read_at = self._row_wall  # when the server's clock was last read
        self._clock_read_held = self._row_held_s  # and this process's hold-ups by then
        if checks:  # (the map's check above asked for the readings' blocks only; ahead
            # of them: a silent unit's request last in a batch, which no later reply shows
            # dropped, costs the reply timeout at every step). In lockstep the setpoints go
            # with the step's advance, so another client's come before them and are
            # written over: the switches only (a read less a step: 10-25 % of the steps a
            # second, a re-probe)
            backs = READ_BACK if not self.lockstep else READ_BACK[len(SETPOINTS) :]
            plan = _read_plan(register_map, backs, trim=True) + plan
        # the units that take commands but serve no reading: one written point read back
        plan = plan + self._read_backs(plan)
        # the simulation control first: a slow instrument never holds up the step's checks
        reads = self._check_plan + plan if checks else plan
        if checks and not self.lockstep:  # the speed too: another client may change it
            reads = self._check_plan + self._clock_plan + plan
        if not checks and not self.lockstep:
            reads = plan + _read_plan(register_map, ("sim_time_s",))
        self._set_reads(reads)

    def _set_reads(self, reads: list[_Read]) -> None:
        """The step's reads (as first planned, or with a block a unit refused in pieces)."""
        self._reads = reads
        self._read_requests = [_request(r) for r in reads]
        self._n_reads = len(reads)
        #: the read of the server's clock among the step's reads (None: none, lockstep
        #: without checks)
        self._clock_index = next(
            (i for i, r in enumerate(reads) if self._time_point in r.points), None
        )

    def _read_backs(self, plan: list[_Read]) -> list[_Read]:
        """A read of one written point of each unit that takes this rig's plant commands
        but serves none of the readings of ``plan``: without it such a unit is never seen
        to answer, and its refusal with 03 (a fault's, or its map's) could not be told
        apart (see the module docstring)."""
        read_units = {r.unit for r in plan}
        first_point: dict[int, str] = {}
        for signal in WRITES:
            unit = self._points[signal][0].unit_id
            if unit not in read_units and unit not in self._own_units:
                first_point.setdefault(unit, signal)
        return [_read_plan(self.map, (s,), trim=True)[0] for s in first_point.values()]

    def _read_optional(self, register_map: RegisterMap, signal: str) -> float | None:
        """One read of ``signal``; None where this map or the server's has no such point."""
        if not _has_point(register_map, signal):
            return None
        (read,) = _read_plan(register_map, (signal,), trim=True)
        values: dict[str, float] = {}
        try:
            self._decode([read], self._exchange([_request(read)]), values)
        except ModbusExceptionResponse:
            return None
        return values[signal]

    def _map_problem(self, plan: list[_Read], register_map: RegisterMap) -> str | None:
        """Before the first row, and when a restarted server comes back, whether the server
        serves this client's map (None if it does): its ``map_id`` where both maps have one
        (two same-length points swapped, a word order, a scale or a type that differ read
        wrong values as readings, exit 0; a re-probe; a server restarted with another map
        went on into the same log: a stranger's probe); without one, every block of
        readings read once, a block the server answers with 01 or 02 (no such function or
        register) naming the difference (the run went on blind: every row's fields empty,
        exit 0; a stranger's probe). A server with faults active from its start (an
        exception may be one of them) is not asked for the blocks."""
        served = self._read_optional(register_map, "map_id")
        if served is not None:
            ours = map_identity(register_map)
            # (a server of an earlier release publishes the older form, without the ranges)
            if int(served) not in (ours, legacy_map_identity(register_map)):
                return (
                    f"the server serves another register map than {register_map.source} "
                    f"(map id {int(served):08x}, this one's {ours:08x}: a device added or "
                    "left out, a point moved, swapped, retyped or rescaled, or the access or "
                    "range of its writes differ); give the client the server's map (--map)"
                )
            return None
        if (self._read_optional(register_map, "active_fault_count") or 0.0) > 0:
            return None
        for block in plan:
            unserved = self._unserved(block)
            if unserved is not None:
                read, exc = unserved
                names = ", ".join(p.signal for p in read.points)
                return (
                    f"unit {read.unit} answers exception {exc.code:02X} to the read of "
                    f"{names} (function {read.function}, address {read.start}, {read.count} "
                    f"registers of {register_map.source}): the server runs another register "
                    "map; give the client the server's (--map)"
                )
        return None

    def _unserved(self, read: _Read) -> tuple[_Read, ModbusExceptionResponse] | None:
        """The first piece of ``read`` the server refuses with 01 or 02 (no such function,
        no such register) and its refusal; a block refused with 02 is asked again in halves
        (a device may take fewer registers a read than the block has: 02 for the range, a
        stranger's probe), a point refused alone is the map's. None if none is refused so
        (busy, failed, 03: an instrument's state, not the map)."""
        try:
            self._exchange([_request(read)])
        except ModbusExceptionResponse as exc:
            if exc.code not in (1, 2):
                return None
            if exc.code == 1 or len(read.points) == 1:
                return read, exc
            for half in _halves(read):
                unserved = self._unserved(half)
                if unserved is not None:
                    return unserved
        return None

    def _first_status(self) -> dict[str, float]:
        """Connect and read the server's status, asked again (at most
        :data:`GARBLED_RETRIES` times) where noise on a serial line garbled a reply: a
        frame lost is routine on a line, and one bad CRC at the start refused the run,
        "cannot reach" the server that answered (a stranger's probe)."""
        for attempt in range(GARBLED_RETRIES + 1):
            try:
                self._connect()
                return self._read_status()
            except GarbledReply:
                if attempt == GARBLED_RETRIES:
                    raise
        raise AssertionError("unreachable")

    @property
    def fresh_start(self) -> bool:
        """Whether this run began on a fresh server (time 0, no advance): only then can a
        restart of the server be replayed into its log."""
        return self._replayable

    @property
    def advances_before(self) -> int:
        """The server's lockstep counter when this run began (modulo 65536)."""
        return self._base_counter

    # ------------------------------------------------------------------ connections
    def _connect(self, abort: bool = False) -> None:
        self.close(abort)
        self._conn = self._open()
        # what the connections before showed of the order the server answers in (opened
        # again after each timeout, a fresh one would wait the timeout for every request a
        # faulty unit drops: modbus_client.Connection.in_order)
        learn = getattr(self._conn, "learn_from", None)  # (RTU: one request at a time)
        if learn is not None and self._earlier is not None:
            learn(self._earlier)
        self._learn_order()

    def _learn_order(self) -> None:
        """Show a new connection the order its server answers in before the first step:
        :data:`IN_ORDER_EVIDENCE` + 1 reads of the simulation control, pipelined (a unit no
        fault silences). Without it, a unit silent from the start at the head of every step
        (unit 1, no_reply) cost the timeout until the steps' own replies had shown the
        order: at x100, 100 simulated seconds of rows lost per timeout (a re-probe)."""
        conn = self._conn
        if not isinstance(conn, Connection) or conn.in_order or conn.reorders:
            return
        if not self._status_plan:
            return
        read = self._status_plan[0]
        count = IN_ORDER_EVIDENCE + 1
        requests = [(read.unit, read_pdu(read.function, read.start, read.count))] * count
        conn.send(requests)
        self._note_own_answers(requests, conn.receive_all(count)[0])

    def _reconnect(self, reason: str, lost: str) -> dict[str, float]:
        """Connect again (with backoff); the server's status once back (``lost``: the
        reason of the gap if it is not back in time, :meth:`_lost`)."""
        started = time.monotonic()
        delay = 0.1
        while True:
            try:
                self._connect()
                return self._read_status()
            except ConnectionLost:
                if time.monotonic() - started > self.reconnect_timeout_s:
                    self._gap(lost, "abort", {})
                    raise RigError(
                        f"{self.url}: connection lost ({reason}) and not back within "
                        f"{self.reconnect_timeout_s:g} s"
                    ) from None
                time.sleep(delay)
                delay = min(delay * 2, 5.0)
            except ModbusExceptionResponse as exc:
                raise RigError(f"{self.url}: {exc}") from None

    @property
    def server_time_offset_s(self) -> float:
        """Log time minus server time (constant between breaks)."""
        return self._offset

    def close(self, abort: bool = False) -> None:
        if self._conn is not None:
            self._conn.close(abort)
            self._earlier, self._conn = self._conn, None

    # ------------------------------------------------------------------ primitives
    def _exchange(self, requests: list[tuple[int, bytes]], patient: bool = False) -> list[bytes]:
        """Send ``(unit, pdu)`` requests pipelined; their replies, in order (``patient``:
        each waited for up to ``reconnect_timeout_s`` in all, as a replay's requests must
        be carried out whatever a fault holds up: ConnectionLost after that). Reads the
        simulation control answered with a transient exception (:data:`TRANSIENT_CODES`)
        are asked again (:meth:`_transient_pauses`); one that persists is raised."""
        pauses = self._transient_pauses()
        while True:
            try:
                return self._exchange_once(requests, patient)
            except ModbusExceptionResponse as exc:
                if not self._transient(exc, requests):
                    raise
                self._event("exception", exc.unit, exc.function, code=exc.code, retried=True)
                if not next(pauses):
                    raise

    def _transient(self, exc: ModbusExceptionResponse, requests: list[tuple[int, bytes]]) -> bool:
        """Whether ``exc``, to one of ``requests``, is the simulation control's transient
        refusal of reads alone (asked again as they are: a write is not)."""
        return self._passing(exc) and all(pdu[0] in READ_FUNCTIONS for _, pdu in requests)

    def _passing(self, reply: Reply) -> bool:
        """Whether ``reply`` is the simulation control's transient exception
        (:data:`TRANSIENT_CODES`): a gateway's 0A or 0B only once the unit has answered
        (before, it is a server without that unit: a map question, told at once)."""
        return (
            isinstance(reply, ModbusExceptionResponse)
            and reply.unit in self._own_units
            and reply.code in TRANSIENT_CODES
            and (reply.code == 0x06 or self._own_answered)
        )

    def _note_own_answers(self, requests: list[tuple[int, bytes]], replies: list[Reply]) -> None:
        """Take note of a reply with data from the simulation control among ``replies``."""
        self._own_answered = self._own_answered or any(
            isinstance(reply, bytes) and unit in self._own_units
            for (unit, _), reply in zip(requests, replies, strict=False)
        )

    def _transient_pauses(self) -> Iterator[bool]:
        """The pauses before asking the simulation control again after a transient
        exception: each sleeps (doubling from :data:`_TRANSIENT_PAUSE_S` up to
        :data:`_TRANSIENT_MAX_PAUSE_S`) and gives True, until the next would end more than
        the reply timeout after the first began: then False (the exception persists)."""
        deadline = time.monotonic() + self.timeout_s
        pause = _TRANSIENT_PAUSE_S
        while time.monotonic() + pause <= deadline:
            time.sleep(pause)
            self._server_wait_s += pause
            pause = min(2 * pause, _TRANSIENT_MAX_PAUSE_S)
            yield True
        while True:
            yield False

    def _exchange_once(
        self, requests: list[tuple[int, bytes]], patient: bool = False
    ) -> list[bytes]:
        """:meth:`_exchange`, once: its first exception reply raised (after the replies
        behind it, where it is asked again)."""
        assert self._conn is not None
        if not requests:
            return []
        sent = time.monotonic()
        replies: list[Reply] = []
        times: list[float] = []
        try:
            self._conn.send(requests)
            if not patient:
                for i in range(len(requests)):
                    try:
                        replies.append(self._conn.receive())
                    except ModbusExceptionResponse as exc:
                        if self._transient(exc, requests):  # (the replies behind it taken:
                            for _ in range(len(requests) - i - 1):  # they are not this
                                with contextlib.suppress(ModbusExceptionResponse):  # time's)
                                    self._conn.receive()
                        raise
                    times.append(time.monotonic())
                self._note_own_answers(requests, replies)
                return replies  # type: ignore[return-value]
            everything = range(len(requests))
            replies, times = self._conn.receive_all(
                len(requests), everything, self.reconnect_timeout_s, self._still_coming
            )
        finally:
            if len(times) < len(requests):  # (the one that failed waited till now)
                times.append(time.monotonic())
            self._account(requests, sent, times)
        self._note_own_answers(requests, replies)
        for reply in replies:
            if isinstance(reply, NoReply):
                self._connect(abort=True)
                raise ConnectionLost(f"{reply} while replaying this run onto the server")
            if isinstance(reply, ModbusExceptionResponse):
                raise reply
        return replies  # type: ignore[return-value]

    def _account(
        self,
        requests: list[tuple[int, bytes]],
        sent: float,
        times: list[float],
        clock_read: int | None = None,
    ) -> None:
        """Each reply's wait (from the reply before it, or the send) to the unit it came
        from; at the read of the server's clock (``clock_read``, an index of ``requests``)
        :attr:`step_timing` closes and the next one starts. An in-order server answers a
        pipelined request only after those before it, so the wait on a slow unit is its own
        reply's, and the replies behind it come at once."""
        previous = sent
        for i, ((unit, _), at) in enumerate(zip(requests, times, strict=False)):
            wait = max(at - previous, 0.0)
            previous = at
            if unit in self._own_units:
                self._server_wait_s += wait
            else:
                self._unit_waits[unit] = self._unit_waits.get(unit, 0.0) + wait
            if i == clock_read:
                held = held_up_s()
                self.step_timing = StepTiming(
                    at - self._clock_read_at,
                    self._paced_s,
                    self._server_wait_s,
                    self._unit_waits,
                    held - self._clock_read_held,
                )
                self._clock_read_at, self._clock_read_held = at, held
                self._paced_s = self._server_wait_s = 0.0
                self._unit_waits = {}

    def _event(self, event: str, unit: int, function: int, **extra: Any) -> None:
        self._step_events.append({"event": event, "unit": unit, "function": function, **extra})

    def _exchange_tolerant(
        self,
        requests: list[tuple[int, bytes]],
        own: range = range(0),
        patient: bool = False,
        clock_read: int | None = None,
    ) -> list[Reply]:
        """:meth:`_exchange_tolerant_once`; the simulation control's transient exceptions
        (:data:`TRANSIENT_CODES`) in its replies asked again after a pause
        (:meth:`_transient_pauses`) until answered or the reply timeout has passed (then
        they stand, and stop the run as before: one 0B on unit 100 ended a 6-h run, a
        stranger's probe), each an ``exception`` event. Its reads are asked again alone; a
        write of its refused (the lockstep advance, not carried out) the whole batch, whose
        reads after it saw the plant before it (the step's setpoints and switches go again
        as they were: the same values)."""
        replies = self._exchange_tolerant_once(requests, own, patient, clock_read)
        pauses = self._transient_pauses()
        while again := [i for i, reply in enumerate(replies) if self._passing(reply)]:
            for i in again:
                refused = replies[i]
                assert isinstance(refused, ModbusExceptionResponse)
                self._event("exception", refused.unit, refused.function, code=refused.code,
                            retried=True)  # fmt: skip
            if not next(pauses):
                break
            if any(requests[i][1][0] not in READ_FUNCTIONS for i in again):
                replies = self._exchange_tolerant_once(requests, own, patient, clock_read)
                continue
            asked = self._exchange_tolerant_once([requests[i] for i in again])
            replies = list(replies)
            for i, reply in zip(again, asked, strict=True):
                replies[i] = reply
        return replies

    def _exchange_tolerant_once(
        self,
        requests: list[tuple[int, bytes]],
        own: range = range(0),
        patient: bool = False,
        clock_read: int | None = None,
    ) -> list[Reply]:
        """Like :meth:`_exchange`, but a unit's failure is its outcome, not an error; a
        timeout reconnects (late replies left behind, what the server has not carried out
        dropped). Replies of instruments that came :data:`LATE_S` after the one before are
        ``late`` events. ``patient`` (lockstep): every reply is waited for, up to
        ``reconnect_timeout_s``, a slow unit's counted as a timeout all the same; the rest,
        the rig's own at the indices ``own`` (the advance, the simulation control's reads)
        among them, come behind it on the same connection: given up on, the advance could be
        carried out after the step was settled as lost, and sent again. ``clock_read``: the
        index of the read of the server's clock, which closes :attr:`step_timing`."""
        assert self._conn is not None
        if not requests:
            return []
        sent = time.monotonic()
        self._conn.send(requests)
        patience = self.reconnect_timeout_s if patient else 0.0
        self._dead = self._head_own = False
        try:
            replies, times = self._conn.receive_all(
                len(requests), own, patience, self._still_coming if patient else None
            )
        except BaseException:
            self._account(requests, sent, [time.monotonic()])
            raise
        self._account(requests, sent, times, clock_read)
        self._note_own_answers(requests, replies)
        previous = sent
        for (unit, pdu), reply, at in zip(requests, replies, times, strict=True):
            late = at - previous > LATE_S
            if late and unit not in self._own_units and not isinstance(reply, NoReply):
                self._event("late", unit, pdu[0], wait_s=round(at - previous, 3))
            previous = at
        timed_out = [
            i for i, r in enumerate(replies) if isinstance(r, NoReply) and r.reason == "timeout"
        ]
        if timed_out:
            self._connect(abort=True)
            self._read_again(requests, replies, timed_out)
        return replies

    def _read_again(
        self, requests: list[tuple[int, bytes]], replies: list[Reply], timed_out: list[int]
    ) -> None:
        """The reads given up on behind a slow unit (an in-order server answers them only
        after it), asked once more on the new connection, the slow unit's left out: only
        its own fields stay empty, not those of every unit read after it."""
        slow = requests[timed_out[0]][0]
        again = [
            i
            for i in timed_out[1:]
            if requests[i][0] != slow and requests[i][1][0] in READ_FUNCTIONS
        ]
        if not again:
            return
        assert self._conn is not None
        try:
            self._conn.send([requests[i] for i in again])
            second, _ = self._conn.receive_all(len(again))
        except ConnectionLost:
            return  # the connection is gone again: the next step finds out
        for i, reply in zip(again, second, strict=True):
            replies[i] = reply
        if any(isinstance(r, NoReply) and r.reason == "timeout" for r in second):
            self._connect(abort=True)

    def _in_pieces(self, replies: list[Reply]) -> list[Reply]:
        """The step's read ``replies`` (of :attr:`_reads`), each block an instrument refused
        as too long (:data:`_TOO_LONG`: the specification lets a device take fewer than 125
        registers a read) asked again in halves, and the halves it refuses in halves again,
        down to a point at a time (a device that took 8 registers a read gave a run of 206
        rows without a flow, a temperature or an O2, exit 0: a stranger's probe). Learned
        once per read and kept: the pieces that answered replace it in :attr:`_reads` (the
        pieces it refuses too stay, their fields empty); where no piece answers, it stays
        whole and :attr:`notes` says so once. A block its unit answered whole before is never
        asked so: its refusal is a passing one (an ``exception`` fault; a 10-s fault was
        taken for a device that cannot take the block, five events for one row and a note
        that its fields are empty while it does: a stranger's re-probe). Returns the
        replies of the new :attr:`_reads`."""
        self._whole_answered.update(
            (read.unit, read.function, read.start)
            for read, reply in zip(self._reads, replies, strict=True)
            if isinstance(reply, bytes) and len(read.points) > 1
        )
        refused = [
            i
            for i, (read, reply) in enumerate(zip(self._reads, replies, strict=True))
            if self._too_long(read, reply)
        ]
        if not refused:
            return replies
        reads, replies = list(self._reads), list(replies)
        for i in reversed(refused):  # (from the end: the indices before stay)
            read = reads[i]
            self._split_tried.add((read.unit, read.function, read.start))
            pieces, answers = self._pieces(read, replies[i])
            if any(isinstance(answer, bytes) for answer in answers):
                self._refused_event(read, replies[i])
                reads[i : i + 1], replies[i : i + 1] = pieces, answers
                continue
            code = replies[i].code  # type: ignore[union-attr]
            self.notes.append(
                f"unit {read.unit} refused the read of {', '.join(p.signal for p in read.points)}"
                f" (function {read.function}, address {read.start}, {read.count} registers) "
                f"with exception {_TOO_LONG[code]}, and in pieces down to "
                "one point at a time too: those fields are empty while it does"
            )
        self._set_reads(reads)
        return replies

    def _too_long(self, read: _Read, reply: Reply) -> bool:
        """Whether ``reply`` refuses ``read``, an instrument's of two points or more not yet
        asked in pieces and never answered whole, as a read its unit may take only in
        pieces."""
        key = (read.unit, read.function, read.start)
        return (
            isinstance(reply, ModbusExceptionResponse)
            and reply.code in _TOO_LONG
            and read.unit not in self._own_units
            and len(read.points) > 1
            and key not in self._split_tried
            and key not in self._whole_answered
        )

    def _refused_event(self, read: _Read, reply: Reply) -> None:
        """The ``exception`` event of a read refused on the way to its pieces."""
        code = reply.code  # type: ignore[union-attr]
        self._event("exception", read.unit, read.function, code=code,
                    signals=[p.signal for p in read.points])  # fmt: skip

    def _pieces(self, read: _Read, reply: Reply) -> tuple[list[_Read], list[Reply]]:
        """``read``, refused with ``reply``, asked in halves, those refused in halves again
        down to single points: the pieces and their replies (each refusal on the way an
        ``exception`` event)."""
        pieces, answers = [read], [reply]
        while halve := {
            k
            for k, (piece, answer) in enumerate(zip(pieces, answers, strict=True))
            if isinstance(answer, ModbusExceptionResponse)
            and answer.code in _TOO_LONG
            and len(piece.points) > 1
        }:
            split: list[_Read] = []
            kept: list[Reply | None] = []
            for k, (piece, answer) in enumerate(zip(pieces, answers, strict=True)):
                if k not in halve:
                    split.append(piece)
                    kept.append(answer)
                    continue
                if piece is not read:  # (the read's own refusal: :meth:`_in_pieces`)
                    self._refused_event(piece, answer)
                halves = _halves(piece)
                split += halves
                kept += [None] * len(halves)
            asked = [k for k, answer in enumerate(kept) if answer is None]
            got = self._exchange_tolerant([_request(split[k]) for k in asked])
            for k, answer in zip(asked, got, strict=True):
                kept[k] = answer
            pieces, answers = split, kept  # type: ignore[assignment]
        return pieces, answers

    def _still_coming(self, unit: int, function: int) -> bool:
        """Whether a reply the connection has been silent on is only slow rather than lost
        with a connection that died on the way (a NAT or proxy that dropped it without a
        word); asked on a connection of its own. An instrument at the head of the line is
        asked again: an answer within the timeout means it is not slow, so the connection
        is dead (False); none means it is (True). The rig's own request at the head (the
        advance, being carried out) is dead only once the server's counter shows it done:
        its reply was lost (False). A server that cannot be reached: an outage (False)."""
        own = unit in self._own_units
        self._head_own = own
        read = next((r for r in self._reads if r.unit == unit), self._reads[0])
        try:
            probe = self._open()
        except ConnectionLost:
            self._dead = True
            return False
        try:
            probe.send([(read.unit, read_pdu(read.function, read.start, read.count))])
            reply = probe.receive_all(1)[0][0]
        except ConnectionLost:
            reply = NoReply(unit, function, "timeout")
        finally:
            probe.close(abort=True)
        if own:
            if not isinstance(reply, bytes) or not self.checks:
                return True  # the server is busy, or the counter cannot tell: wait on
            status: dict[str, float] = {}
            self._decode([read], [reply], status)
            done = status.get("lockstep_counter") == self._expected(len(self._journal))[0]
            # a serial line carries one transaction at a time: a server that answers the
            # probe carries out no request, so one not done was lost on the line (a bad
            # CRC; it was waited for --reconnect-timeout, 60 s a lost frame: a probe)
            line = isinstance(self._conn, RtuConnection)
            self._dead = bool(done) or line
            return not done and not line
        slow = isinstance(reply, NoReply) and reply.reason == "timeout"
        self._dead = not slow
        return slow

    def _failed(self, unit: int, function: int, reply: Reply, signals: list[str]) -> None:
        """Record a unit's failure; the simulation control's is the rig's own error."""
        if unit in self._own_units:
            if isinstance(reply, ModbusExceptionResponse):
                raise reply
            raise ConnectionLost(f"the simulation control (unit {unit}): {reply}")
        if isinstance(reply, ModbusExceptionResponse):
            self._event("exception", unit, function, code=reply.code, signals=signals)
        else:
            # "too late" counts as a timeout: the reply came, after --reply-timeout
            event = "no_reply" if reply.reason == "no reply" else "timeout"  # type: ignore[union-attr]
            self._event(event, unit, function, signals=signals)

    def _decode_tolerant(
        self, reads: list[_Read], replies: list[Reply], into: dict[str, float]
    ) -> None:
        """:meth:`_decode`, a failed unit's fields NaN (empty), invalid readings NaN."""
        for read, reply in zip(reads, replies, strict=True):
            if not isinstance(reply, bytes):
                self._failed(read.unit, read.function, reply, [p.signal for p in read.points])
                if isinstance(reply, ModbusExceptionResponse):
                    reason = f"exception {reply.code:02X}"
                elif reply.reason == "no reply":
                    reason = "no reply (a later one came first)"
                else:  # a timeout, or a reply after it
                    reason = f"no reply within the reply timeout, {self.timeout_s:g} s"
                self._step_failures.setdefault(read.unit, {})[reason] = None
                self._failed_signals.setdefault(read.unit, {}).update(
                    dict.fromkeys(p.signal for p in read.points)
                )
                for p in read.points:
                    into[p.signal] = math.nan
                continue
            self._answered_units.add(read.unit)
            self._decode([read], [reply], into)
            invalid = [
                p.signal
                for p in read.points
                if p.signal in READING_KEYS
                and (math.isnan(into[p.signal]) or into[p.signal] == self._invalid.get(p.signal))
            ]
            if invalid:
                for signal in invalid:
                    into[signal] = math.nan
                self._event("invalid", read.unit, read.function, signals=invalid)
            for p in read.points:
                limit = self._limits.get(p.signal)
                if limit is not None and into[p.signal] in limit[2]:
                    at = self.pinned.setdefault(p.signal, (*limit[:2], {}))[2]
                    at[into[p.signal]] = at.get(into[p.signal], 0) + 1
                    into[p.signal] = math.nan

    def _check_overrides(self, values: dict[str, float]) -> None:
        """Another client (or a hand at the bench) changed a command of this rig's: the
        boiler's controller's mode (0: off, the only mode of a boiler not switched on), the
        bench's pump or return heating, or a setpoint read back (:data:`READ_BACK`) disagree
        with what this rig wrote. An ``overridden`` event naming them (``read``: what they
        showed), and the switches are written again next step (the rig writes them only
        when they change; the setpoints go every step)."""
        cmd = self._command
        in_flight, self._switches_in_flight = self._switches_in_flight, False
        taken, self._setpoints_taken = self._setpoints_taken, {}
        if cmd is None:
            return
        read: dict[str, float] = {}
        if self._written_switches is not None:
            # the boiler's mode shows a switch written with this step's reads next step
            # (its controller takes it at a tick: a restarted plant's first row read
            # "switched by another client"); a coil read back after its write shows it
            # (judged next step, a pump another client kept off went untold every other row)
            mode = values.get("boiler_mode", math.nan)
            if not in_flight and not math.isnan(mode) and (mode != 0.0) != cmd.boiler_on:
                read["boiler_command"] = mode
            for signal, on in (("pump_on", cmd.pump_on), ("return_heating", cmd.return_heating)):
                now = values.get(signal, math.nan)
                if not math.isnan(now) and (now >= 0.5) != on:
                    read[signal] = now
        for signal, written in taken.items():
            now = values.get(signal, math.nan)
            if not math.isnan(now) and not math.isclose(now, written, rel_tol=1e-6):
                read[signal] = now
        if not read:
            return
        unit, pdu = self._write_request(next(iter(read)), 0.0)
        extra = {"mode": read["boiler_command"]} if "boiler_command" in read else {}
        self._event("overridden", unit, pdu[0], signals=list(read), read=read, **extra)
        if read.keys() - set(SETPOINTS):
            self._written_switches = None

    def _commands_tolerant(self, requests: list[tuple[int, bytes]], replies: list[Reply]) -> None:
        """Failed setpoint or switch writes: recorded, and written again next step; one
        refused as an illegal value (03) is a candidate refusal (:meth:`_settle_refusals`).
        The flow setpoint (the step's first request) taken: what the server now holds."""
        self._refused.clear()
        self._setpoints_taken = {}
        replies = self._single_coils(requests, replies)
        for i, ((unit, pdu), reply) in enumerate(zip(requests, replies, strict=True)):
            if isinstance(reply, bytes):
                sent = self._setpoints_sent[i] if i < len(self._setpoints_sent) else {}
                if "water_flow_setpoint_kg_h" in sent:
                    self.written_flow_setpoint_kg_h = sent["water_flow_setpoint_kg_h"]
                if not self.lockstep:  # (read back: :meth:`_check_overrides`)
                    self._setpoints_taken.update(sent)
                continue
            self._failed(unit, pdu[0], reply, [])
            self._written_switches = None
            label = self._command_labels[i] if i < len(self._command_labels) else "a write"
            if isinstance(reply, ModbusExceptionResponse) and reply.code == 3:
                self._refused.append((unit, f"{label} with exception 03 (illegal data value)", ""))
            tls = self.url.startswith("modbus+tls://")
            if isinstance(reply, ModbusExceptionResponse) and reply.code == 1 and pdu[0] == 5:
                if tls:  # (01 there may be the role's: the run's warning says so)
                    continue
                how = (
                    f"{label} with exception 01 (illegal function) both as FC15 (write multiple "
                    "coils) and as FC5 (write single coil)"
                )
                self._refused.append((unit, how, "the device cannot be switched by Modbus"))

    def _single_coils(self, requests: list[tuple[int, bytes]], replies: list[Reply]) -> list[Reply]:
        """``replies``, the coil writes a unit refused with 01 (illegal function) as FC15
        written again as FC5, one coil each (a device need not take FC15: the map gives FC5
        or FC15 for coils; one without it ran a whole protocol with the burner off, exit 0:
        a stranger's probe); learned: that unit's coils go as FC5 from then on, said once in
        :attr:`notes`. ``requests`` takes the FC5 requests in their places (a lockstep step's
        journal is that list: a replay sends what the unit takes). Not over Modbus/TCP
        Security: there a 01 is the client's role refusing writes (an observer's FC15 was
        taken for a unit without it, every coil asked again as FC5, refused too)."""
        refused = [
            i
            for i, ((unit, pdu), reply) in enumerate(zip(requests, replies, strict=True))
            if pdu[0] == 15 and isinstance(reply, ModbusExceptionResponse) and reply.code == 1
        ]
        if not refused or self.url.startswith("modbus+tls://"):
            return replies
        self._single_coil_units |= {requests[i][0] for i in refused}
        for i in refused:
            unit, pdu = requests[i]
            address = int.from_bytes(pdu[1:3], "big")
            requests[i] = (unit, _write_coil_pdu(address, bool(pdu[6] & 1)))
        replies = list(replies)
        again = self._exchange_tolerant([requests[i] for i in refused])
        for i, reply in zip(refused, again, strict=True):
            replies[i] = reply
        # said once FC5 worked (a unit refusing both stops the run: no word of FC5 before)
        took = sorted({requests[i][0] for i in refused if isinstance(replies[i], bytes)})
        for unit in (u for u in took if u not in self._single_coils_said):
            self._single_coils_said.add(unit)
            self.notes.append(
                f"unit {unit} refused FC15 (write multiple coils) with exception 01 (illegal "
                "function): its coils are written with FC5 (write single coil)"
            )
        return replies

    def _settle_refusals(self, read_replies: list[Reply]) -> None:
        """The step's writes refused with 03 by a unit that answered its reads before the
        write (the last step's) and after it (this step's): the server does not accept the
        value (its map's range), for the whole run: :attr:`refusal`. A unit whose reads got
        an exception too (or no reply) is under a fault (transient): written again (a fault
        that ended between the write and the reads was taken for a refusal). A unit this
        rig does not read is never seen to answer: no refusal (:meth:`_read_backs` reads
        one point of each unit that takes commands)."""
        refused, self._refused = self._refused, []
        faulty = {
            read.unit
            for read, reply in zip(self._reads, read_replies, strict=True)
            if not isinstance(reply, bytes)
        }
        faulty, before = faulty, self._faulty
        self._faulty = faulty
        if self.refusal is not None:
            return
        read_units = {read.unit for read in self._reads}  # (a unit never read: never seen
        for unit, how, why in refused:  # to answer; :meth:`_read_backs` reads one)
            if unit in read_units and unit not in faulty and unit not in before:
                why = why or (
                    "the server does not accept that value (its register map's range is "
                    "narrower than this client's?)"
                )
                self.refusal = (
                    f"{self.url}: unit {unit} refused {how} while it answered its reads: "
                    f"{why}, so the test method cannot be carried out"
                )
                return

    def _decode(self, reads: list[_Read], replies: list[bytes], into: dict[str, float]) -> None:
        for read, reply in zip(reads, replies, strict=True):
            words = bits_of(reply, read.count) if read.function in (1, 2) else registers_of(reply)
            for p, value in zip(read.points, read.decode(words), strict=True):
                into[p.signal] = value

    def _read_status(self) -> dict[str, float]:
        """The simulation control: time, counter, epoch, identity, clock mode and speed."""
        reads = self._status_plan + self._clock_plan
        replies = self._exchange([(r.unit, read_pdu(r.function, r.start, r.count)) for r in reads])
        status: dict[str, float] = {}
        self._decode(reads, replies, status)
        return status

    def _write_request(self, signal: str, value: float) -> tuple[int, bytes]:
        device, point = self._points[signal]
        if point.table == "coil" and device.unit_id in self._single_coil_units:
            return device.unit_id, _write_coil_pdu(point.address, value >= 0.5)
        if point.table == "coil":
            return device.unit_id, write_coils_pdu(point.address, [value >= 0.5])
        return device.unit_id, write_registers_pdu(point.address, encode(point, value))

    def _command_requests(self) -> list[tuple[int, bytes]]:
        """Writes of the setpoints (every step) and of the switches (when they change)."""
        cmd = self._command
        if cmd is None:
            return []
        flow_dev, flow = self._points["water_flow_setpoint_kg_h"]
        ret_dev, ret = self._points["return_setpoint_C"]
        flow_words = encode(flow, cmd.flow_setpoint_kg_h)
        ret_words = encode(ret, cmd.return_setpoint_C)
        carried = {
            "water_flow_setpoint_kg_h": written_value(flow, flow_words),
            "return_setpoint_C": written_value(ret, ret_words),
        }
        flow_label = (
            f"the write of water_flow_setpoint_kg_h = {carried['water_flow_setpoint_kg_h']:g} kg/h"
        )
        ret_label = f"return_setpoint_C = {cmd.return_setpoint_C:g} C"
        if flow_dev is ret_dev and ret.address == flow.address + flow.width:
            words = flow_words + ret_words
            requests = [(flow_dev.unit_id, write_registers_pdu(flow.address, words))]
            labels = [f"{flow_label} and {ret_label}"]
            self._setpoints_sent = [carried]
        else:
            requests = [
                (flow_dev.unit_id, write_registers_pdu(flow.address, flow_words)),
                (ret_dev.unit_id, write_registers_pdu(ret.address, ret_words)),
            ]
            labels = [flow_label, f"the write of {ret_label}"]
            self._setpoints_sent = [{k: v} for k, v in carried.items()]
        switches = (cmd.pump_on, cmd.return_heating, cmd.boiler_on)
        if switches != self._written_switches:  # a new plant resets this to None
            for signal, on in zip(
                ("pump_on", "return_heating", "boiler_command"),
                (cmd.pump_on, cmd.return_heating, cmd.boiler_on),
                strict=True,
            ):
                requests.append(self._write_request(signal, float(on)))
                labels.append(f"the write of {signal} = {int(on)}")
            self._written_switches = switches
            self._switches_in_flight = True
        self._command_labels = labels
        return requests

    # ------------------------------------------------------------------ expectations
    def _expected(self, applied: int) -> tuple[int, float]:
        """Lockstep counter and server time once ``applied`` journal steps are applied."""
        counter = (self._base_counter + applied) % 65536
        return counter, self._journal_time[applied - 1] if applied else self._base_time

    def _same_plant(self, status: dict[str, float]) -> str | None:
        """Why ``status`` is not from the plant this rig expects (None if it is)."""
        if status["epoch_id"] != self._epoch_id:
            return "the server restarted (a new plant)"
        if self.lockstep:
            counter, sim_time = self._expected(self._applied)
            if status["lockstep_counter"] == counter and (
                abs(status["sim_time_s"] - sim_time) <= _TIME_TOLERANCE_S
            ):
                return None
            self._stop_if_time_pinned(status)
            return _foreign(status["sim_time_s"] - sim_time)
        if status["sim_time_s"] < self._row_server_time - _TIME_TOLERANCE_S:
            return "the server was reset (its time went back)"
        counter = status.get("lockstep_counter", math.nan)
        if not math.isnan(counter) and int(counter) != self._base_counter:
            # in real time only another client steps the clock (lockstep mode, an advance,
            # real time again): its jump was logged as a hole this client was blamed for,
            # the server "stalled", and rig_epoch stayed (a stranger's probe)
            return (
                "another client advanced the server (its step counter went from "
                f"{self._base_counter} to {int(counter)}; the time moved "
                f"{status['sim_time_s'] - self._row_server_time:g} s in this step)"
            )
        return None

    def _stop_if_time_pinned(self, status: dict[str, float]) -> None:
        """Stop (:class:`RigError`) where the server's time stands at the most its point
        carries: the map cannot count this run's time on, and no other client is to blame
        (a stranger's probe: a sim_time as int16 stopped at 32767 s, and the run ended
        with "another client reset the server")."""
        now = status.get("sim_time_s", math.nan)
        if not now >= self._time_max:
            return
        p = self._time_point
        scale = f" x{p.scale:g}" if p.scale != 1.0 else ""
        reason = (
            f"the server's sim_time stands at {now:g} s, the most its point '{p.name}' "
            f"({p.datatype}{scale}) carries: the register map cannot count this run's time "
            "on (give sim_time a wider type: float64, as the shipped map)"
        )
        self._gap(reason, "abort", status)
        raise RigError(f"{self.url}: {reason}; stopped after time_s = {self.log_time_s:g} s")

    def _check_identity(self, status: dict[str, float]) -> None:
        """Stop (:class:`RigError`) if a restarted server has another set-up."""
        changed = [
            f"{label} {int(status[key])}, was {self.identity[key]}"
            if key == "seed"
            else f"{label} id {int(status[key]):08x}, was {self.identity[key]:08x}"
            for key, label in _IDENTITY.items()
            if int(status[key]) != self.identity[key]
        ]
        mode = "lockstep" if status["clock_mode"] == 1.0 else "real time"
        if (status["clock_mode"] == 1.0) != self.lockstep:
            changed.append(f"clock {mode}")
        problem = self._map_problem(*self._map_check)
        if problem is not None:
            changed.append(problem)
        if changed:
            reason = f"the server came back as another plant ({'; '.join(changed)})"
            self._gap(reason, "abort", status)
            raise RigError(f"{self.url}: {reason}; stopped after time_s = {self.log_time_s:g} s")

    # ------------------------------------------------------------------ breaks and gaps
    def _gap(self, reason: str, action: str, status: dict[str, float]) -> dict[str, Any]:
        """A break or an outage of the run, in :attr:`gaps` (see the module docstring);
        ``server_epoch_id``: the ``epoch_id`` of the server after it (8 hex digits, as its
        fault journal writes it; None if not read), which tells the fault report whose
        journal the rows after it compare with (a stranger's probe: a restarted server's
        journal was matched with the first plant's rows); ``client_held_up_s``: how long this
        client was held up since the last row (paused, swapped out, overloaded)."""
        epoch = status.get("epoch_id")
        gap: dict[str, Any] = {
            # as the log writes time_s; None before the first row
            "start_time_s": round(self.log_time_s, 3) if self._stepped else None,
            "end_time_s": None,
            "reason": reason,
            "action": action,
            "rig_epoch": self.epoch,
            "server_time_before_s": self._row_server_time,
            "server_time_after_s": status.get("sim_time_s"),
            "outage_wall_s": round(time.monotonic() - self._row_wall, 3),
            "client_held_up_s": round(held_up_s() - self._row_held_s, 3),
            "server_epoch_id": (
                f"{int(epoch):08x}" if epoch is not None and math.isfinite(epoch) else None
            ),
        }
        self.gaps.append(gap)
        return gap

    def _lost(self, reason: str, by_server: bool) -> str:
        """The reason of a gap for a connection lost for ``reason``, saying where this
        client was held up (:data:`HELD_UP_S` or more, most of the silence since its last
        row) when the server closed it (``by_server``): a server may close a client silent
        that long as idle (one SIGSTOPped 8 s under a server's ``--idle-timeout 3`` was
        recorded as "connection closed by the server" alone, its hold-up nowhere: a
        stranger's probe). What closed it the client cannot know (a ``disconnect`` fault
        may have, in the same seconds), so the idle close is a "may"; a connection this
        client's own timeout gave up keeps its reason (the figure is in
        ``client_held_up_s``: a re-probe, a server stalled past it was "closed as idle")."""
        held = held_up_s() - self._row_held_s
        silent = time.monotonic() - self._row_wall
        if not by_server or held < max(HELD_UP_S, 0.5 * silent):
            return f"connection lost ({reason})"
        return (
            f"connection lost ({reason}) after this client was held up {held:.1f} s (paused, "
            "swapped out or overloaded): the server may have closed it as idle"
        )

    def _recover(self, reason: str, by_server: bool = False) -> None:
        """After a lost connection (``by_server``: the server closed it): connect again and
        settle what the server holds."""
        self._event("disconnect", 0, 0, reason=reason)
        lost = self._lost(reason, by_server)  # (before reconnecting: a backoff is no hold-up)
        status = self._reconnect(reason, lost)
        self._new_speed(status["speed_factor"])
        if status["epoch_id"] != self._epoch_id:
            self._check_identity(status)
            if self.lockstep and self._replayable and self._fresh(status):
                self._epoch_id = status["epoch_id"]
                self._applied = 0  # the journal is replayed with the next step
                self._gap(f"the server restarted ({reason})", "replayed", status)
                return
            why = "the server restarted (a new plant)"
            if self.lockstep:
                why += (
                    "; no replay: this run did not start on a fresh server"
                    if not self._replayable
                    else "; no replay: the new server is not fresh"
                )
            raise _Break(why, status)
        if self.lockstep:
            # how many of the unacknowledged steps did the server apply?
            for applied in range(self._applied, len(self._journal) + 1):
                counter, sim_time = self._expected(applied)
                if status["lockstep_counter"] == counter and (
                    abs(status["sim_time_s"] - sim_time) <= _TIME_TOLERANCE_S
                ):
                    self._applied = applied
                    self._gap(lost, "resumed", status)
                    return
            self._stop_if_time_pinned(status)
            raise _Break(_foreign(status["sim_time_s"] - self._expected(self._applied)[1]), status)
        if status["sim_time_s"] < self._row_server_time - _TIME_TOLERANCE_S:
            raise _Break("the server was reset (its time went back)", status)
        self._gap(lost, "reconnected", status)

    def _rebuild_under_step(self) -> bool:
        """A server restarted between two steps with no connection lost (a serial line: the
        new server took this step's advance before its status could show the new epoch):
        with the same set-up and a run begun on a fresh server, it is reset to its initial
        state (same seed, the faults' schedule again) and the journal is replayed on it
        with the step; False (a break) where it cannot be."""
        status = self._read_status()
        self._check_identity(status)
        if not self._replayable or "reset" not in self._points:
            return False
        self._exchange([self._write_request("reset", 1.0)])
        status = self._read_status()
        if not self._fresh(status):
            return False
        self._epoch_id = status["epoch_id"]
        self._applied = 0
        self._gap(
            "the server restarted (no connection lost: it took this run's step as a fresh "
            "plant, and was reset to its initial state)",
            "replayed",
            status,
        )
        return True

    def _step_again(self, dt_s: float) -> float:
        """The step once more on a server rebuilt under it (the journal replayed, this step
        too): what the attempt given up saw was the dead server's (its instruments'
        timeouts were noted as the row's, "gave no reading ... empty there", of a row the
        replay logged whole: a stranger's probe)."""
        self._step_failures.clear()
        self._step_events.clear()
        return self._step_lockstep(dt_s)

    @staticmethod
    def _timed_out(replies: list[Reply]) -> bool:
        return any(isinstance(r, NoReply) and r.reason == "timeout" for r in replies)

    def _rebuilt_under_timeouts(self) -> bool:
        """After instruments that timed out in a step, whether the server is still this
        run's: on a serial line a server killed and restarted under a step loses no
        connection, and its row was logged with every instrument empty before the next
        step found the new plant. True: a new server, rebuilt (reset, the journal to be
        replayed); False: the same plant; a :class:`_Break` where it cannot be rebuilt, and
        ConnectionLost while it is down (settled by :meth:`_recover`)."""
        status = self._read_status()
        reason = self._same_plant(status)
        if reason is None:
            return False
        if status["epoch_id"] != self._epoch_id and self._rebuild_under_step():
            return True
        raise _Break(reason, dict(status))

    def _fresh(self, status: dict[str, float]) -> bool:
        return status["lockstep_counter"] == 0 and status["sim_time_s"] == 0.0

    def _on_break(self, brk: _Break) -> None:
        """A break: stop (abort) or go on from the plant as it is, one epoch higher; stop
        too where another client has broken it :data:`FOREIGN_BREAKS_MAX` times within
        :data:`FOREIGN_WINDOW_STEPS` steps."""
        status = brk.status
        if self.on_restart == "abort":
            self._gap(brk.reason, "abort", status)
            raise RigError(
                f"{self.url}: {brk.reason} after time_s = {self.log_time_s:g} s; stopped "
                "(--on-restart abort; restart-phase or continue would go on, the break marked)"
            )
        if brk.foreign:
            self._foreign_breaks.append(self.rows_stepped)
        recent = [n for n in self._foreign_breaks if n > self.rows_stepped - FOREIGN_WINDOW_STEPS]
        self._foreign_breaks = recent
        if len(recent) >= FOREIGN_BREAKS_MAX:
            reason = (
                f"{brk.reason}, {len(recent)} times within {FOREIGN_WINDOW_STEPS} steps: "
                "another client is "
                "stepping this server too (two runs on one server are neither's plant; "
                "give each its own)"
            )
            self._gap(reason, "abort", status)
            raise RigError(f"{self.url}: {reason}; stopped after time_s = {self.log_time_s:g} s")
        self.epoch += 1
        self._gap(brk.reason, self.on_restart, status)
        same = status["epoch_id"] == self._epoch_id
        now = status["sim_time_s"]
        if same and now >= self._row_server_time:
            moved = now - self._row_server_time  # the plant lived on without this rig
        elif self.lockstep:
            moved = 0.0
        else:
            moved = (time.monotonic() - self._row_wall) * self.speed
        self._offset = self.log_time_s + moved - now
        self._epoch_id = status["epoch_id"]
        self._base_counter = int(status["lockstep_counter"])
        self._base_time = now
        self._row_server_time = now
        self._journal.clear()
        self._journal_time.clear()
        self._applied = self._logged = 0
        self._replayable = False  # another history: no fresh server can rebuild it
        self._written_switches = None

    # ------------------------------------------------------------------ rig interface
    def apply(self, command: RigCommand) -> None:
        """Take the step's commands; a setpoint its point cannot carry is refused
        (:class:`~rig_emulator.emulator.CommandError`), never clipped on the wire (a
        stranger's probe: 687 kg/h went out as 655.35 on a uint16 x0.01, the log saying 687)."""
        check_command(SETPOINTS[0], command.flow_setpoint_kg_h, self._accepted[SETPOINTS[0]])
        check_command(SETPOINTS[1], command.return_setpoint_C, self._accepted[SETPOINTS[1]])
        self._command = RigCommand(
            command.flow_setpoint_kg_h,
            command.return_setpoint_C,
            command.pump_on,
            command.boiler_on,
            command.return_heating,
        )

    def advance(self, dt_s: float) -> float:
        """Write the commands, let ``dt_s`` of simulated time pass, poll every instrument.

        Returns the log time that passed [s]: ``dt_s`` in lockstep, more in real time when
        the client fell behind, and more across a break (see the module docstring).
        """
        for _ in range(1000):
            self._step_failures.clear()  # (an attempt given up left its own)
            try:
                step = self._step_lockstep if self.lockstep else self._step_realtime
                passed = step(dt_s)
            except (ConnectionLost, OSError) as exc:
                try:
                    self._recover(str(exc), getattr(exc, "by_server", False))
                except _Break as brk:
                    self._on_break(brk)
                except (ConnectionLost, OSError):
                    pass  # lost again while settling: the next attempt reconnects
                continue
            except _Break as brk:
                self._on_break(brk)
                continue
            except ModbusExceptionResponse as exc:
                raise RigError(
                    f"{self.url}: {self._left_lockstep(exc) or exc}{_role_hint(self.url, exc)}"
                ) from None
            self._row_wall = time.monotonic()
            self._row_held_s = held_up_s()
            self._stepped = True
            for event in self._step_events:
                self.comm_events.append(
                    {"time_s": round(self.log_time_s, 3), "server_time_s": self.sim_time_s} | event
                )
            self._step_events.clear()
            self.rows_stepped += 1
            for unit, reasons in self._step_failures.items():
                self._failed_rows.setdefault(unit, {})[round(self.log_time_s, 3)] = None
                self._failure_reasons.setdefault(unit, {}).update(reasons)
            if self.gaps and self.gaps[-1]["end_time_s"] is None:
                for gap in self.gaps:
                    if gap["end_time_s"] is None:
                        gap["end_time_s"] = round(self.log_time_s, 3)
            return passed
        raise RigError(f"{self.url}: no progress after 1000 reconnections")

    def _left_lockstep(self, exc: ModbusExceptionResponse) -> str | None:
        """Why the simulation control refused this lockstep run's request where its clock
        is no longer in lockstep (another client switched it to real time: the advance is
        refused with 03, and the run stopped on "unit 100: function 16 refused with
        exception 03" alone: a stranger's probe); the gap says so too. None otherwise."""
        if not self.lockstep or exc.unit not in self._own_units:
            return None
        try:
            status = self._read_status()
        except (ConnectionLost, OSError, ModbusExceptionResponse):
            return None
        if status["clock_mode"] == 1.0:
            return None
        reason = (
            f"the server's clock left lockstep (now real time x{status['speed_factor']:g}: "
            "another client, through the simulation control), so it refused this run's "
            f"advance ({exc})"
        )
        self._gap(reason, "abort", status)
        return reason

    def _step_lockstep(self, dt_s: float) -> float:
        journal = self._journal
        if self._logged == len(journal):  # a new step (else: one not read yet)
            _, before = self._expected(self._applied)
            if journal and not self.checks:  # no journal: keep the step in flight only
                self._base_counter = (self._base_counter + len(journal)) % 65536
                self._base_time = before
                journal.clear()
                self._journal_time.clear()
                self._applied = self._logged = 0
            step = self._command_requests()
            step.append(self._write_request("lockstep_advance_s", dt_s))
            journal.append(step)
            self._journal_time.append(before + dt_s)
        # replay (a restarted server) in batches, then the last step with the reads
        last = len(journal) - 1
        while self._applied < last:
            batch: list[tuple[int, bytes]] = []
            size, k = 0, self._applied
            while k < last:
                step_bytes = sum(7 + len(pdu) for _, pdu in journal[k])  # MBAP + PDU
                if batch and size + step_bytes > _REPLAY_SEGMENT_BYTES:
                    break
                batch += journal[k]
                size += step_bytes
                k += 1
            self._exchange(batch, patient=True)
            self._applied = k
        pending = journal[self._applied :]
        requests = pending[0] if pending else []
        # (none pending: the server applied the step before the connection was lost)
        # the advance (the step's last request) and the simulation control's reads after it
        n_checks = len(self._check_plan) if self.checks else 0
        own = range(max(len(requests) - 1, 0), len(requests) + n_checks)
        clock = None if self._clock_index is None else len(requests) + self._clock_index
        replies = self._exchange_tolerant(
            requests + self._read_requests, own, patient=True, clock_read=clock
        )
        line = isinstance(self._conn, RtuConnection)  # one transaction at a time
        if any(isinstance(replies[i], NoReply) for i in own) and (self._head_own or line):
            # the rig's own request unanswered for --reconnect-timeout, no slow unit ahead
            # (on a serial line none can be: each transaction ends before the next): the
            # connection or the server died under it (never a fault: the emulator's units
            # have none), and the server is asked again (a server restarted under the
            # step's advance on a line stopped the run as "stalled")
            self._dead = True
        if not self._dead and any(isinstance(replies[i], NoReply) for i in own):
            # held more than --reconnect-timeout behind a slow unit: sending the step again
            # would meet the same wait for as long as the plant's time stands still (a dead
            # connection instead goes the way of any lost one: reconnect and settle)
            reason = (
                f"the server did not answer this run's own requests (the clock's advance) "
                f"within --reconnect-timeout {self.reconnect_timeout_s:g} s: a unit ahead of "
                "them was slower than that (a delay fault?), or the server stalled"
            )
            self._gap(reason, "abort", {})
            raise RigError(f"{self.url}: {reason}; stopped after time_s = {self.log_time_s:g} s")
        self._commands_tolerant(requests, replies[: len(requests)])
        self._applied = len(journal)
        values = self.values
        reads = self._in_pieces(replies[len(replies) - self._n_reads :])
        self._decode_tolerant(self._reads, reads, values)
        self._settle_refusals(reads)
        if self.checks:
            reason = self._same_plant(values)
            if reason is not None:
                if values["epoch_id"] != self._epoch_id and self._rebuild_under_step():
                    return self._step_again(dt_s)
                raise _Break(reason, dict(values))
            # (a serial line loses no connection: a server restarted under the step; over
            # TCP a restart loses it, and a unit that timed out is a fault, not asked about)
            timed_out = isinstance(self._conn, RtuConnection) and self._timed_out(reads)
            if timed_out and self._rebuilt_under_timeouts():
                return self._step_again(dt_s)
        self._check_overrides(values)
        self._logged = len(journal)
        server_time = self._journal_time[-1]
        self.sim_time_s = server_time
        self._row_server_time = server_time
        passed = server_time + self._offset - self.log_time_s
        self.log_time_s = server_time + self._offset
        return passed

    def _step_realtime(self, dt_s: float) -> float:
        commands = self._command_requests()
        # a read of the simulation control closes the batch: a dropped write shows at once
        sentinel = [(self._check_plan[0].unit, self._read_requests[0][1])] if commands else []
        if commands and self.checks:
            replies = self._exchange_tolerant(commands + sentinel)
            self._commands_tolerant(commands, replies[: len(commands)])
            if not isinstance(replies[-1], bytes):
                self._failed(sentinel[0][0], 4, replies[-1], [])
        elif commands:
            self._commands_tolerant(commands, self._exchange_tolerant(commands))
        self._wait_until(self.log_time_s + dt_s - self._offset)
        replies = self._in_pieces(
            self._exchange_tolerant(self._read_requests, clock_read=self._clock_index)
        )
        values = self.values
        self._decode_tolerant(self._reads, replies, values)
        self._settle_refusals(replies)
        if self.checks:
            reason = self._same_plant(values)
            if reason is not None:
                raise _Break(reason, dict(values))
            speed = values.get("speed_factor", self.speed)
            if speed != self.speed:  # (x100 -> x10000 by another client was blamed on
                gap = self._gap(  # this client falling behind, four times: a stranger's probe)
                    f"the server's speed changed from x{self.speed:g} to x{speed:g} (another "
                    "client, through the simulation control)",
                    "continue",
                    values,
                )
                gap["speed_before"], gap["speed_after"] = self.speed, speed  # no row lost
                self._new_speed(speed)
        self._check_overrides(values)
        server_time = values["sim_time_s"]
        self.sim_time_s = server_time
        self._row_server_time = server_time
        passed = server_time + self._offset - self.log_time_s
        self.log_time_s = server_time + self._offset
        return passed

    def _new_speed(self, speed: float) -> None:
        """The server's clock runs at ``speed`` now (:attr:`speeds` keeps every one)."""
        if speed != self.speed:
            self.speeds.append(speed)
        self.speed = speed

    def _wait_until(self, target: float) -> None:
        """Poll the server's time until it reaches ``target``, or it went back (a reset)."""
        requests = [(r.unit, read_pdu(r.function, r.start, r.count)) for r in self._check_plan]
        status: dict[str, float] = {}
        while True:
            self._decode(self._check_plan, self._exchange(requests), status)
            now = status["sim_time_s"]
            if now >= target - 1e-9 or now < self._row_server_time - _TIME_TOLERANCE_S:
                return
            self._stop_if_time_pinned(status)  # (else waited for ever)
            wait = (target - now) / max(self.speed, 1e-9)
            pause = min(max(wait * 0.5, 0.001), 0.25)
            time.sleep(pause)
            self._paced_s += pause

    def read(self) -> dict[str, float]:
        values = self.values
        return {key: values.get(key, math.nan) for key in READING_KEYS}

    def limit_note(self) -> str | None:
        """One line on the readings logged empty for standing at their register's limit,
        each limit named with its rows (+327.67 in 18 rows and -327.67 in 21 were told as
        "at -327.67, 39 rows": a stranger's probe), or None."""
        if not self.pinned:
            return None
        each = []
        for signal, (unit, point, rows) in self.pinned.items():
            at = ", and at ".join(f"{limit:g}, {n} rows" for limit, n in sorted(rows.items()))
            each.append(f"{signal} (unit {unit} point '{point}' at {at})")
        return (
            f"readings at their register's limit, logged empty: {'; '.join(each)}: the map's "
            "type and scale carry no more (a wider type or a coarser scale in the map does)"
        )

    def unit_signals(self, unit: int) -> list[str]:
        """The readings this rig reads from ``unit``, in the order of its reads (its
        commands read back aside: :data:`READ_BACK`)."""
        return list(
            dict.fromkeys(
                p.signal
                for r in self._reads
                if r.unit == unit
                for p in r.points
                if p.signal not in READ_BACK
            )
        )

    def end_notes(self) -> list[str]:
        """The lines a run's end tells (a warning each, and a note of the meta file), beside
        :attr:`notes`: each unit whose reads failed (no reply, a timeout, an exception),
        with the readings it never gave (a device whose every read of units 1 and 2 was
        refused left a run that looked clean, exit 0: a stranger's probe; so did an
        analyser that never answered, or stopped answering a minute in: the flue-gas
        columns empty in every row, and only the events file said why), and
        :meth:`limit_note`."""
        lines = []
        for unit, rows in sorted(self._failed_rows.items()):
            # the log's columns only (a status the rig reads is none: a re-probe)
            logged = [s for s in self._failed_signals[unit] if s in READING_KEYS]
            signals = ", ".join(logged)
            why = list(self._failure_reasons[unit])
            if not logged:
                continue
            if unit in self._answered_units:  # (some of its reads, or some of the rows)
                times = list(rows)
                lines.append(
                    f"unit {unit} gave no reading of {signals} in {len(rows)} of "
                    f"{self.rows_stepped} rows (from time_s = {times[0]:g} to {times[-1]:g} "
                    f"s: {'; '.join(why)}): empty there"
                )
            elif all(reason.startswith("exception ") for reason in why):
                how = ", ".join(sorted(reason.removeprefix("exception ") for reason in why))
                lines.append(
                    f"unit {unit} refused every read of this run (exception {how}): "
                    f"{signals} never read, empty in every row"
                )
            else:
                lines.append(
                    f"unit {unit} never answered a read of this run ({'; '.join(why)}): "
                    f"{signals} never read, empty in every row"
                )
        limits = self.limit_note()
        return [*lines, limits] if limits else lines


def _foreign(time_moved_s: float) -> str:
    """The reason of a break by another client, from how far the server's time moved."""
    if time_moved_s < 0:
        return "another client reset the server (time or counter not this run's)"
    return (
        f"another client advanced the server (by {time_moved_s:g} s more than this run; "
        "time or counter not this run's)"
    )
