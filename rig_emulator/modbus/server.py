"""The thin, declarative Modbus TCP adapter: a register map over the emulator.

Built on pymodbus 3.16's datastore, one ``SimDevice`` per map device (its own
unit ID, separate coil, discrete, holding and input address spaces) and a catch-all device
for unknown unit IDs. Values are published with ``server.async_setValues`` (the runs that
changed) on every tick or advance, and by an accepted write that changed a command, before
it is answered: every point of that command (an alias in another type, scale, word order or
table) reads the new value in the next request. Client writes are checked in the devices'
action callback before pymodbus stores them:

- only points declared ``rw`` accept writes (else exception 02, illegal data address);
- a write that covers part of a multi-register value, or whose value is NaN, infinite,
  outside the point's range or, for a command that takes whole numbers (a switch, a mode,
  a code), not a whole number, or that gives one command two values through two of its
  points, gets exception 03 (illegal data value) and changes nothing;
- unmapped addresses get exception 02 (pymodbus marks gaps invalid);
- an unknown unit ID gets exception 0B (gateway target device failed to respond) at once.

Framing, the spec's checks and exception codes, in-order answers per connection, the idle
timeout and the connection limit are :mod:`rig_emulator.modbus.handler`'s. Everything runs
in one asyncio loop: the tick never waits for a client, and a client that stops reading
only fills its own socket buffer.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import secrets
import socket
import ssl
import struct
import threading
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pymodbus.constants import ExcCodes
from pymodbus.simulator import DataType, SimData, SimDevice

from rig_emulator import __version__
from rig_emulator.clock import LOCKSTEP, REALTIME, LatenessStats, RealTimeTicks, SimClock
from rig_emulator.emulator import CommandError, Emulator, check_command
from rig_emulator.faults import Entry
from rig_emulator.modbus.conformance import DeviceIdentity
from rig_emulator.modbus.connections import DASHBOARD_CONNECTIONS
from rig_emulator.modbus.fault_control import FAULT_COMMANDS, ServerFaults
from rig_emulator.modbus.handler import (
    DEFAULT_IDLE_TIMEOUT_S,
    DEFAULT_MAX_CONNECTIONS,
    BenchModbusServer,
)
from rig_emulator.registers import (
    Device,
    Point,
    RegisterMap,
    emulator_units,
    encode,
    map_identity,
    precision,
    reading_range,
    run_encoder,
    written_value,
)
from rig_emulator.registers.codec import accepted_range
from rig_emulator.registers.datatypes import DATATYPES

log = logging.getLogger("rig_emulator.serve")

_WRITE_FC = {5: "coil", 15: "coil", 6: "holding", 16: "holding", 23: "holding"}
_READ_FC = {1: "coil", 2: "discrete", 3: "holding", 4: "input"}
_PUBLISH_FC = {"input": 4, "holding": 16, "discrete": 2, "coil": 15}
_TABLE_INDEX = {"coil": 0, "discrete": 1, "holding": 2, "input": 3}
CLOCK_COMMANDS = ("speed_factor", "clock_mode", "lockstep_advance_s", "reset")
TICK_BUDGET_FRACTION = 0.5  # share of a tick period the physics of one tick may take
CHUNK_STEPS = 64  # physics steps between two looks at the clock (~1-2 ms with the lab profile)
ADVANCE_SLICE_S = 0.005  # wall time a lockstep advance runs before it lets others in [s]
#: Moments inside one lockstep advance :attr:`BenchServer.on_advance_sample` is called at,
#: at most (evenly spaced: the dashboard's trend shows what the plant did within an hour's
#: advance, a start-up and a cut-out, not a straight line between its ends: a probe)
ADVANCE_SAMPLES = 200
#: Why a clock or fault command is refused with exception 01 (Modbus and dashboard alike)
CONTROL_REFUSAL = "the server runs in real time without --allow-control"


@dataclass(frozen=True, slots=True)
class _Run:
    """A contiguous run of registers (or bits) of one table, published in one call."""

    table: str
    start: int
    points: tuple[Point, ...]
    encode: Callable[[Mapping[str, float]], list[int]]  # signal values -> the run's registers
    #: per scaled integer point: (point, lowest, highest value it serves, half a step wider)
    limits: tuple[tuple[Point, float, float], ...] = ()


_WritePlan = tuple[tuple[Point, int], ...] | ExcCodes


def _limits(points: list[Point]) -> tuple[tuple[Point, float, float], ...]:
    """Where the integer points of a run saturate: beyond these a value is served as its
    type's limit (half a step inside them it only rounds to it)."""
    out = []
    for p in points:
        lo, hi = reading_range(p)
        if math.isfinite(lo) and math.isfinite(hi) and p.datatype != "bool":
            half = abs(p.scale) / 2.0
            out.append((p, lo - half, hi + half))
    return tuple(out)


def carried_range(point: Point) -> tuple[float, float]:
    """The lowest and highest value a write of ``point`` can set: of what its registers
    carry, what lies in :func:`accepted_range` (a re-probe: an int32 x0.05 +0.025 offered
    10..90 carries 9.975 and 10.025, not 10, so a write of 10 was refused). A float point:
    its range (a bound its type cannot carry exactly is read as that bound,
    :func:`written_value`); empty (low above high) where no step lies in the range."""
    lo, hi = accepted_range(point)
    datatype = DATATYPES[point.datatype]
    if datatype.is_float or datatype.is_bit or lo > hi:
        return lo, hi
    raw_lo, raw_hi = datatype.int_range
    near_ends = {
        r
        for end in (lo, hi)
        for r in range(
            math.floor((end - point.offset) / point.scale) - 1,
            math.ceil((end - point.offset) / point.scale) + 2,
        )
        if raw_lo <= r <= raw_hi
    }
    # the values the raw integers near each end decode to (decode's own arithmetic, which
    # the server's range check sees), those in the range
    inside = [v for v in (r * point.scale + point.offset for r in near_ends) if lo <= v <= hi]
    return (min(inside), max(inside)) if inside else (hi, lo)


def _number(value: float) -> str:
    """A value a point carries, as a message shows it: its digits, not the binary
    remainder of its scale (10.025, not 10.025000000000000355)."""
    return f"{value:.12g}"


def _steps(point: Point) -> str:
    """A point's encoding as a message names it: its type and its step (int32 x0.05
    +0.025)."""
    offset = f" {point.offset:+g}" if point.offset else ""
    return f"{point.datatype} x{point.scale:g}{offset}"


def _run(table: str, points: list[Point]) -> _Run:
    return _Run(table, points[0].address, tuple(points), run_encoder(points), _limits(points))


def _runs(device: Device, table: str) -> list[_Run]:
    runs: list[_Run] = []
    current: list[Point] = []
    for point in device.table(table):
        if current and point.address != current[-1].address + current[-1].width:
            runs.append(_run(table, current))
            current = []
        current.append(point)
    if current:
        runs.append(_run(table, current))
    return runs


def _simdata(runs: list[_Run], bits: bool) -> list[SimData]:
    if bits:
        blocks = [
            SimData(p.address, values=[False], datatype=DataType.BITS)
            for run in runs
            for p in run.points
        ]
        return blocks or [SimData(0, values=[False], datatype=DataType.BITS)]
    blocks = [
        SimData(
            run.start, values=[0] * sum(p.width for p in run.points), datatype=DataType.REGISTERS
        )
        for run in runs
    ]
    return blocks or [SimData(0, count=1, datatype=DataType.INVALID)]


def device_layout(device: Device) -> tuple[list[SimData], ...]:
    """The four tables (coils, discrete, holding, input) of a map device as pymodbus blocks;
    gaps between runs stay invalid (exception 02)."""
    return (
        _simdata(_runs(device, "coil"), True),
        _simdata(_runs(device, "discrete"), True),
        _simdata(_runs(device, "holding"), False),
        _simdata(_runs(device, "input"), False),
    )


def _refusal(code: ExcCodes, why: str | None = None) -> str:
    """A write the server refused, as :meth:`BenchServer.write_signal` says it."""
    return f"refused with Modbus exception {int(code):02X} ({code.name})" + (
        f": {why}" if why else ""
    )


def _catch_all_device() -> SimDevice:
    """Device id 0 answers every unknown unit ID with exception 0B."""

    async def refuse(*_args) -> ExcCodes:
        return ExcCodes.GATEWAY_NO_RESPONSE

    regs = SimData(0, count=65536, values=0, datatype=DataType.REGISTERS)
    bit = SimData(0, values=[False] * 16, datatype=DataType.BITS)
    return SimDevice(0, simdata=([bit], [bit], [regs], [regs]), action=refuse)


def _listen_error(host: str, port: int) -> str:
    """Why listening on ``host:port`` fails, as the OS says it."""
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
        with socket.socket(infos[0][0], socket.SOCK_STREAM) as probe:
            probe.bind(infos[0][4])
    except OSError as exc:
        return exc.strerror or str(exc)
    return "the address was refused"


class BenchServer:
    """The emulator published over Modbus TCP, paced in real time or in lockstep.

    Args:
        emulator: the bench to publish.
        register_map: which signal goes where.
        host, port: where to listen (port 0: any free port; see :attr:`port` after start).
        speed: simulated seconds per wall second in real-time mode.
        lockstep: start in lockstep mode (time moves only on ``lockstep_advance``).
        tick_hz: rate of the real-time tick and of the register updates.
        allow_control: let clients write the clock commands (speed, mode, reset, advance) and
            the fault command block of a real-time server; without it they get exception 01
            (a server started in lockstep always accepts them, also once a client switched
            it to real time: else that one write would lock every client out for good).
        faults: faults to schedule (``FAULTS.yaml`` entries; the profile's come too).
        fault_log: the JSONL journal of fault starts and ends (None: none).
        idle_timeout_s: close client connections that sent no whole request this long (0: never).
        max_connections: client connections open at once (the next ones are closed); at
            most what the process's open-file limit holds, from :meth:`start` on.
        ssl_context: serve Modbus/TCP Security (TLS) on ``host:port`` instead of plain TCP
            (:mod:`rig_emulator.modbus.transports` adds more listeners and lines).
        dashboard: a dashboard will serve beside it (``serve --http``): its connections
            get their share of the process's descriptors (without one, none is kept for it).
    """

    def __init__(
        self,
        emulator: Emulator,
        register_map: RegisterMap,
        host: str = "127.0.0.1",
        port: int = 5020,
        speed: float = 1.0,
        lockstep: bool = False,
        tick_hz: float = 10.0,
        allow_control: bool = False,
        faults: Iterable[Entry] = (),
        fault_log: str | Path | None = None,
        idle_timeout_s: float = DEFAULT_IDLE_TIMEOUT_S,
        max_connections: int = DEFAULT_MAX_CONNECTIONS,
        ssl_context: ssl.SSLContext | None = None,
        dashboard: bool = False,
    ) -> None:
        check_command("speed_factor", speed)
        self.idle_timeout_s = idle_timeout_s
        self.max_connections = max_connections
        self.ssl_context = ssl_context
        self.dashboard = dashboard
        self.emulator = emulator
        self.map = register_map
        self.map_id = float(map_identity(register_map))
        self.host = host
        self.port = port
        self.tick_period_s = 1.0 / tick_hz
        self.clock = SimClock(speed=speed, mode=LOCKSTEP if lockstep else REALTIME)
        self.lateness = LatenessStats()
        self.lockstep_counter = 0
        #: plant resets since the start (a reset write): what tells a history that the plant
        #: started over (its time going back alone does not: a look published before an
        #: advance is older than the samples taken inside it, a re-probe), and the count
        #: the last :meth:`publish` saw, which :attr:`published_values` belong to
        self.resets = 0
        self.published_resets = 0
        #: random per start: a client that sees it change knows the plant is a new one
        self.epoch_id = secrets.randbits(32)
        self.last_advance_s = 0.0
        self.allow_control = allow_control or lockstep
        self._kernels_ready = threading.Event()
        self.achieved_speed = speed
        self.tick_overrun_ms = 0.0
        self._clock_lock = asyncio.Lock()  # one write at a time, an advance's whole length
        self._refusals_logged: set[tuple[str, str]] = set()
        self._clamps_logged: set[tuple[int, str]] = set()  # (unit, point): warned once
        self._internal = False
        self._server: BenchModbusServer | None = None
        self._tick_task: asyncio.Task | None = None
        self._runs: dict[int, list[_Run]] = {}
        self._points: dict[tuple[int, str], dict[int, Point]] = {}
        # what publish last wrote: (unit, table) -> {address: registers or [bit]}
        self._published: dict[tuple[int, str], dict[int, list]] = {}
        self._write_plans: dict[tuple[int, str, int, int], _WritePlan] = {}
        self.on_tick: Callable[[], None] | None = None
        #: called with False inside a lockstep advance, at most :data:`ADVANCE_SAMPLES` times,
        #: the plant part way (nothing is published then: read it with
        #: :meth:`sample_values`), and with True once the advance is published
        self.on_advance_sample: Callable[[bool], None] | None = None
        #: what :meth:`publish` last encoded: what the wire serves (the dashboard shows it)
        self.published_values: dict[str, float] = {}
        #: fault injection (CONTRACT section 5): engine, gate, command and truth blocks
        self.faults = ServerFaults(
            emulator, register_map, faults, fault_log, epoch_id=self.epoch_id
        )
        self._loop: asyncio.AbstractEventLoop | None = None
        self._tasks: set[asyncio.Task] = set()

    # ------------------------------------------------------------------ building
    def _devices(self) -> list[SimDevice]:
        devices = [_catch_all_device()]
        for dev in self.map.devices:
            runs = {t: _runs(dev, t) for t in _TABLE_INDEX}
            self._runs[dev.unit_id] = [
                r for t in ("input", "discrete", "holding", "coil") for r in runs[t]
            ]
            for table in ("holding", "coil"):
                index: dict[int, Point] = {}
                for p in dev.table(table):
                    for a in range(p.address, p.address + p.width):
                        index[a] = p
                self._points[(dev.unit_id, table)] = index
            simdata = device_layout(dev)
            tables_used = {t for t in _TABLE_INDEX if runs[t]}
            devices.append(
                SimDevice(dev.unit_id, simdata=simdata, action=self._action(dev, tables_used))
            )
        return devices

    # ------------------------------------------------------------------ lifecycle
    async def start(self, begin_journal: bool = True) -> None:
        """Listen, publish the initial state and start the tick; the fault journal begins
        once listening (``begin_journal`` False: the caller begins it, when every other
        port it serves is open too: :meth:`ServerFaults.begin_journal`)."""
        loop = asyncio.get_running_loop()
        identity = DeviceIdentity(
            vendor_name="boiler-rig-emulator",
            product_code={d.unit_id: d.name for d in self.map.devices},
            revision=__version__,
        )
        self._server = BenchModbusServer(
            self._devices(),
            address=(self.host, self.port),
            identity=identity,
            idle_timeout_s=self.idle_timeout_s,
            max_connections=self.max_connections,
            ssl=self.ssl_context,
            dashboard_connections=DASHBOARD_CONNECTIONS if self.dashboard else 0,
            own_units=emulator_units(self.map),
            bits={
                dev.unit_id: {
                    fc: frozenset(p.address for p in dev.table(_READ_FC[fc])) for fc in (1, 2)
                }
                for dev in self.map.devices
            },
        )
        try:
            await self._server.serve_forever(background=True)
        except RuntimeError:  # pymodbus hides the reason: ask the OS for it
            raise OSError(
                f"cannot listen on {self.host}:{self.port}: {_listen_error(self.host, self.port)}"
            ) from None
        self.max_connections = self._server.max_connections  # fitted to the descriptors
        self._server.write_check = self.check_write  # a unit failing (04) checks writes
        self.faults.attach(self._server)
        if begin_journal:
            self.faults.begin_journal()
        self._loop = loop
        sock = self._server.transport.sockets[0] if self._server.transport else None
        if sock is not None:
            self.port = sock.getsockname()[1]
        threading.Thread(
            target=self._compile_kernels, name="compile kernels", daemon=True
        ).start()  # listening already; the kernels load meanwhile, replies go on
        now = loop.time()
        self.clock.anchor(now, self.emulator.sim_time_s)
        await self.publish()
        self._tick_task = asyncio.create_task(self._tick_loop(now), name="rig tick")

    @property
    def modbus_server(self) -> BenchModbusServer | None:
        """The Modbus server once started (other transports share its datastore and gates)."""
        return self._server

    async def stop(self) -> None:
        if self._tick_task is not None:
            self._tick_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._tick_task
        if self._server is not None:
            await self._server.shutdown()
        self.faults.close()

    def _compile_kernels(self) -> None:
        """Compile (or load) numba's kernels off the event loop: a cold cache takes tens of
        seconds, during which the loop must go on answering. Until they are ready the
        clock stands (published as overrun) and lockstep advances wait, without blocking."""
        try:
            self.emulator.compile_kernels()
        finally:  # a failure shows on the first step, which then compiles by itself
            self._kernels_ready.set()

    async def _kernels(self) -> None:
        while not self._kernels_ready.is_set():
            await asyncio.sleep(0.02)

    # ------------------------------------------------------------------ time
    async def _tick_loop(self, start: float) -> None:
        """The real-time tick. Every tick awaits (so replies and signals are served however
        far behind it is) and spends at most ``TICK_BUDGET_FRACTION`` of a period on physics;
        what it could not simulate in that budget, and the time a tick a whole period late
        (a stopped process, an overloaded machine) lost, are dropped by re-anchoring the
        clock, never chased (:class:`RealTimeTicks`). :attr:`achieved_speed` and
        :attr:`tick_overrun_ms` say how far it fell short."""
        loop = asyncio.get_running_loop()
        ticks = RealTimeTicks(self.clock, self.tick_period_s, start)
        budget_s = TICK_BUDGET_FRACTION * self.tick_period_s
        while True:
            deadline = ticks.next_deadline()
            await asyncio.sleep(max(deadline - loop.time(), 0.0))  # yields even when late
            tick = ticks.begin(loop.time(), self.emulator.sim_time_s)
            if self.clock.mode != REALTIME or self._clock_lock.locked():
                continue  # lockstep: time and registers move only on client writes
            self.lateness.add(tick.lateness_s)
            missing_s = await self._advance_for(tick.due_s, tick.began_s + budget_s)
            ticks.finish(tick, missing_s)
            self.tick_overrun_ms = tick.overrun_ms
            self.achieved_speed = tick.achieved_speed
            await self.publish()
            if self.on_tick is not None:
                self.on_tick()

    async def _advance_for(self, seconds: float, until_s: float) -> float:
        """Advance by up to ``seconds``, in chunks, until the loop clock passes ``until_s``,
        letting clients in every ``ADVANCE_SLICE_S``; returns the simulated seconds undone."""
        if seconds <= 0.0:
            return 0.0
        if not self._kernels_ready.is_set():
            return seconds  # the kernels still load: nothing simulated, nothing blocked
        loop = asyncio.get_running_loop()
        n, dt = self.emulator.substeps(seconds)
        slice_end_s = loop.time() + ADVANCE_SLICE_S
        while n > 0:
            chunk = min(n, CHUNK_STEPS)
            self.emulator.advance_steps(chunk, dt)
            n -= chunk
            now_s = loop.time()
            if n and now_s >= until_s:
                break
            if n and now_s >= slice_end_s:
                await asyncio.sleep(0)
                slice_end_s = loop.time() + ADVANCE_SLICE_S
        return n * dt

    def _reanchor(self) -> None:
        self.clock.anchor(asyncio.get_running_loop().time(), self.emulator.sim_time_s)

    async def advance(self, seconds: float) -> None:
        """Lockstep: advance the simulation and publish the new state before returning.

        A long advance runs in chunks of about ``ADVANCE_SLICE_S`` of wall time with an
        ``await`` between them, so other clients are answered meanwhile; the registers keep
        the state before the advance until it is done."""
        if seconds > 0:
            await self._kernels()
            loop = asyncio.get_running_loop()
            n, dt = self.emulator.substeps(seconds)
            # steps between two samples for on_advance_sample (chunks end on them: the
            # same physics, chunked differently, :meth:`Emulator.substeps`)
            every = math.ceil(n / ADVANCE_SAMPLES) if self.on_advance_sample else n
            done = 0
            while n > 0:
                until_s = loop.time() + ADVANCE_SLICE_S
                while n > 0 and loop.time() < until_s:
                    chunk = min(n, CHUNK_STEPS, every - done % every)
                    self.emulator.advance_steps(chunk, dt)
                    n -= chunk
                    done += chunk
                    if n > 0 and done % every == 0 and self.on_advance_sample is not None:
                        self.on_advance_sample(False)
                if n > 0:  # a short advance never awaits: its reply keeps its place in line
                    await asyncio.sleep(0)
        self.last_advance_s = seconds
        self.lockstep_counter += 1
        await self.publish()
        if self.on_advance_sample is not None:
            self.on_advance_sample(True)

    # ------------------------------------------------------------------ publishing
    def sample_values(self) -> dict[str, float]:
        """The instruments' readings and the commands now, without the side effects of
        :meth:`values` (the balance's stable flag, the faults' schedule and journal): a look
        inside an advance, before instrument faults (a fault acts at publication)."""
        return self.emulator.reading_by_name() | self.emulator.commands

    def values(self) -> dict[str, float]:
        out = self.emulator.values()
        realtime = self.clock.mode == REALTIME
        out["tick_lateness_ms"] = self.lateness.last_s * 1000.0 if realtime else 0.0
        out["achieved_speed"] = self.achieved_speed if realtime else 0.0
        out["tick_overrun_ms"] = self.tick_overrun_ms if realtime else 0.0
        out["lockstep_counter"] = float(self.lockstep_counter % 65536)
        out["map_id"] = self.map_id
        out["epoch_id"] = float(self.epoch_id)
        out["speed_factor"] = self.clock.speed
        out["clock_mode"] = float(self.clock.mode)
        out["lockstep_advance_s"] = self.last_advance_s
        out["reset"] = 0.0
        self.faults.values(out)
        return out

    # ------------------------------------------------------------------ faults (Python API)
    def inject(self, fault: Mapping[str, Any] | Entry, source: str = "python") -> None:
        """Set a fault (a dict as in ``FAULTS.yaml``, e.g. ``{"kind": "no_reply", "unit":
        2, "for_s": 30}``); without ``at_s`` it starts now. ``source`` names who set it in
        the journal and :meth:`active_faults` (the dashboard's: ``dashboard``). Safe from
        any thread."""
        self.faults.inject(fault, source)
        self._republish()

    def clear_faults(self) -> None:
        """End every active fault and drop the scheduled ones."""
        self.faults.engine.clear()
        self._republish()

    def truth(self, signal: str) -> float:
        """The plant's true value of a measured signal (not the reading)."""
        return self.faults.truth(signal)

    def active_faults(self) -> list[dict[str, Any]]:
        """The active faults (kind, unit or signal, parameter, since_s, until_s, source)."""
        return self.faults.engine.active_faults()

    def _republish(self) -> None:
        """Publish the readings the faults changed, from this or another thread."""
        loop = self._loop
        if loop is None or loop.is_closed() or self._server is None:
            return
        try:
            running = asyncio.get_running_loop()
        except RuntimeError:
            running = None
        if running is loop:
            task = loop.create_task(self.publish())
        else:
            loop.call_soon_threadsafe(lambda: loop.create_task(self.publish()))
            return
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def publish(self) -> None:
        """Encode every point and write the registers that changed since the last publish
        (one call per contiguous run of registers, one per bit)."""
        assert self._server is not None
        values = self.values()
        self.published_values, self.published_resets = values, self.resets
        self._internal = True
        try:
            for unit_id, runs in self._runs.items():
                for run in runs:
                    function = _PUBLISH_FC[run.table]
                    published = self._published.setdefault((unit_id, run.table), {})
                    if run.table in ("coil", "discrete"):
                        for p in run.points:
                            bit = [values[p.signal] >= 0.5]
                            if published.get(p.address) != bit:
                                await self._server.async_setValues(
                                    unit_id, function, p.address, bit
                                )
                                published[p.address] = bit
                        continue
                    for p, lo, hi in run.limits:
                        value = values[p.signal]
                        if (value < lo or value > hi) and (unit_id, p.name) not in (
                            self._clamps_logged
                        ):
                            self._clamped(unit_id, p, value)
                    regs = run.encode(values)
                    if published.get(run.start) != regs:
                        await self._server.async_setValues(unit_id, function, run.start, regs)
                        published[run.start] = regs
        finally:
            self._internal = False

    def _clamped(self, unit_id: int, point: Point, value: float) -> None:
        """Warn, once per point, that a value its type cannot carry is served as the type's
        limit (a stranger's probe: a balance as int16 x0.001 read 32.767 kg of 250 kg, a
        sim_time as int16 stood at 32767 s, and nothing said so)."""
        self._clamps_logged.add((unit_id, point.name))
        lo, hi = reading_range(point)
        limit = hi if value > hi else lo
        log.warning(
            "unit %d point '%s' (%s) publishes %g %s, out of the range %s%s carries: "
            "saturated at %g %s, its limit, while it stays out (widen the point's type or "
            "scale; not logged again for this point)",
            unit_id,
            point.name,
            point.signal,
            value,
            point.unit,
            point.datatype,
            f" x{point.scale:g}" if point.scale != 1.0 else "",
            limit,
            point.unit,
        )

    # ------------------------------------------------------------------ writes
    def _action(self, device: Device, tables_used: set[str]):
        async def action(fc, _start, address, count, _registers, set_values):
            if self._internal:
                return None
            if set_values is None:
                read_table = _READ_FC.get(fc)
                if read_table is not None and read_table not in tables_used:
                    return ExcCodes.ILLEGAL_ADDRESS
                return None
            table = _WRITE_FC.get(fc)
            if table is None:
                return ExcCodes.ILLEGAL_FUNCTION
            return await self._write(device, table, address, set_values)

        return action

    def _write_plan(self, unit_id: int, table: str, address: int, count: int) -> _WritePlan:
        """The points a write of ``count`` registers (or bits) at ``address`` sets, each with
        its offset in the write; or the exception the write gets whatever its values."""
        key = (unit_id, table, address, count)
        plan = self._write_plans.get(key)
        if plan is not None:
            return plan
        index = self._points[(unit_id, table)]
        touched: dict[str, Point] = {}
        for i in range(count):
            point = index.get(address + i)
            if point is None or not point.writable:
                plan = ExcCodes.ILLEGAL_ADDRESS
                break
            touched[point.name] = point
        else:
            end = address + count
            parts = tuple((p, p.address - address) for p in touched.values())
            if any(first < 0 or p.address + p.width > end for p, first in parts):
                plan = ExcCodes.ILLEGAL_VALUE  # part of a multi-register value
            else:
                plan = parts
                self._write_plans[key] = plan  # valid writes only: few, whatever clients send
        return plan

    async def _write(self, device: Device, table: str, address: int, values) -> ExcCodes | None:
        """Check a client write of ``values`` at ``address`` (:meth:`_checked_write`); apply
        it or refuse it whole. The dashboard's controls come this way too
        (:meth:`write_signal`), the guard of the clock commands included (a stranger's
        probe: the dashboard set the speed of a real-time server started without
        --allow-control, which Modbus refused with 01)."""
        new = self._checked_write(device.unit_id, table, address, values)
        if isinstance(new, ExcCodes):
            return new
        refused = await self._apply(new)
        # the client's registers are stored after this returns (a trigger such as the fault
        # command's over the 0 published): publish them again next time
        self._published.pop((device.unit_id, table), None)
        return refused

    async def check_write(
        self, unit_id: int, function_code: int, address: int, values: list
    ) -> int | None:
        """The exception code a client write (FC 5, 6, 15, 16 or 23) of ``values`` at
        ``address`` would get from the write rules, changing nothing; None: it would be
        carried out. The Modbus server asks it for a unit whose operation fails (a fault's
        04), which answers an illegal write what it always gets and a legal one 04, nothing
        written (:class:`rig_emulator.modbus.conformance.FailingOperation`). The clock and
        fault commands' own refusals at their application are not asked: their devices are
        never faulted (:func:`rig_emulator.registers.emulator_units`)."""
        checked = self._checked_write(unit_id, _WRITE_FC[function_code], address, values)
        return int(checked) if isinstance(checked, ExcCodes) else None

    def _checked_write(
        self, unit_id: int, table: str, address: int, values: list
    ) -> dict[str, float] | ExcCodes:
        """The commands a client write of ``values`` at ``address`` sets, each checked, or
        the exception the write gets; changes nothing. The points written first (02 for an
        address no writable point has, as the datastore answers an unmapped one before
        asking this; 03 for part of a multi-register value), then the clock guard
        (:meth:`_control_refused`: 01 whatever the values), then each value (03)."""
        plan = self._write_plan(unit_id, table, address, len(values))
        if isinstance(plan, ExcCodes):
            return plan
        if self._control_refused(point.signal for point, _ in plan):
            return ExcCodes.ILLEGAL_FUNCTION
        new: dict[str, float] = {}
        step: dict[str, float] = {}  # the encoding precision the value of ``new`` came with
        for point, first in plan:
            if table == "coil":
                value = 1.0 if values[first] else 0.0
            else:
                value = written_value(point, values[first : first + point.width])
            try:  # finite, in range, a whole number for a switch, a mode or a code
                checked = check_command(point.signal, value, within=(point.minimum, point.maximum))
            except CommandError:
                return ExcCodes.ILLEGAL_VALUE
            # two points of one command given two values: whichever the server took, the
            # other point would hold what the client wrote, disagreeing with it; the same
            # value in two encodings (500.3 as uint16 x0.1 and float32) is one (a re-probe),
            # taken from the finer of the two
            here = precision(point, checked)
            if point.signal in new:
                if abs(new[point.signal] - checked) > step[point.signal] + here:
                    return ExcCodes.ILLEGAL_VALUE
                if here >= step[point.signal]:
                    continue
            new[point.signal], step[point.signal] = checked, here
        return new

    async def write_signal(self, signal: str, value: float) -> str | None:
        """Write one command signal as a Modbus client would: encoded into its registers
        and through the same checks (:meth:`_write`); None when applied, else why not
        (without the signal's name: the caller names it, once), with the nearest value the
        point can set where it cannot set this one."""
        # through its finest point (a float before a uint16 x2: 501 went out as 500)
        writable = [
            (d, p) for d in self.map.devices for p in d.points if p.signal == signal and p.writable
        ]
        if not writable:
            return f"no writable point carries '{signal}'"
        device, point = min(writable, key=lambda dp: precision(dp[1], value))
        guard = self.control_refusal([signal])
        if guard is not None:  # the server's state, before the value, as on Modbus
            return _refusal(ExcCodes.ILLEGAL_FUNCTION, guard)
        lo, hi = accepted_range(point)  # (encode clips: 687 went out as 655.35)
        low, high = carried_range(point)
        try:  # before encoding: a uint16 switch took 0.5 as 0, rounded, and applied "off"
            value = check_command(signal, value, within=(lo, hi))
        except CommandError as exc:
            why = str(exc).removeprefix(f"{signal}: ")
            if math.isfinite(value) and not lo <= value <= hi and low <= high:
                nearest = _number(low if value < lo else high)
                why += (
                    f" (the nearest value point '{point.name}' ({_steps(point)}) sets: {nearest})"
                )
            return f"{why}: Modbus exception 03"
        if point.table == "coil":
            if value not in (0.0, 1.0):  # FC5 takes FF00 or 0000, nothing else
                return f"{value!r} is not 0 or 1 (a switch): Modbus exception 03"
            registers: list = [value == 1.0]
        else:
            try:
                registers = encode(point, value)
            except (ValueError, OverflowError, struct.error):
                return f"{value!r} cannot be encoded as {point.datatype}"
            carried = written_value(point, registers)
            if not lo <= carried <= hi:  # its step's nearest lies outside the range
                nearest = _number(low if abs(value - low) <= abs(value - high) else high)
                return (
                    f"{value!r} is carried by point '{point.name}' ({_steps(point)}) as "
                    f"{_number(carried)}, outside {lo:g}..{hi:g} (the nearest value it sets: "
                    f"{nearest}): Modbus exception 03"
                )
        refused = await self._write(device, point.table, point.address, registers)
        if refused is None:  # published, its own point too (no client stores it)
            return None
        return _refusal(refused)

    def control_refusal(self, signals: Iterable[str]) -> str | None:
        """Why a write of ``signals`` would be refused with exception 01 now (clock or fault
        commands to a real-time server without --allow-control), or None. The dashboard
        asks it to show a control it cannot use as such, and why."""
        if self._control_allowed:
            return None
        if not any(s in CLOCK_COMMANDS or s in FAULT_COMMANDS for s in signals):
            return None
        return CONTROL_REFUSAL

    @property
    def _control_allowed(self) -> bool:
        """Whether clients may write the clock and fault commands now (``allow_control``)."""
        return self.allow_control or self.clock.mode == LOCKSTEP

    def _control_refused(self, signals: Iterable[str]) -> bool:
        """Whether a write of ``signals`` is refused for touching a clock or fault command
        on a real-time server without --allow-control: 01 before its values are looked at
        ("the server is in the wrong state to process a request of this type", spec
        section 7; a stranger's probe got 01 for an advance of 5 s and 03 for one of 0, 01
        for a speed of 2 and 03 for 0.001). Logged once per command name and server mode,
        not once per request."""
        if self._control_allowed:
            return False
        commands = sorted({s for s in signals if s in CLOCK_COMMANDS or s in FAULT_COMMANDS})
        if not commands:
            return False
        new_names = [n for n in commands if (n, "realtime") not in self._refusals_logged]
        if new_names:  # one line for a write, however many commands it holds (a fault
            self._refusals_logged.update((n, "realtime") for n in new_names)  # block's six
            log.warning(  # wrote six lines: a re-probe)
                "refused a write of %s (exception 01): %s (further refusals of these not logged)",
                ", ".join(new_names),
                CONTROL_REFUSAL,
            )
        return True

    async def _apply(self, new: dict[str, float]) -> ExcCodes | None:
        # every write waits for a clock command under way (a long advance runs in slices,
        # answering reads meanwhile): another client's setpoint lands between two advances,
        # never at a point inside one that the machine's load would choose
        async with self._clock_lock:
            return await self._apply_now(new)

    async def _apply_now(self, new: dict[str, float]) -> ExcCodes | None:
        plant = {
            k: v for k, v in new.items() if k not in CLOCK_COMMANDS and k not in FAULT_COMMANDS
        }
        fault_block = {k: v for k, v in new.items() if k in FAULT_COMMANDS}
        # every refusal before anything is applied: a write covering the fault block and an
        # advance refused in real time had set its fault, then answered 03 (a review)
        if (
            "lockstep_advance_s" in new
            and self.clock.mode != LOCKSTEP
            and (new.get("clock_mode", float(self.clock.mode)) != LOCKSTEP)
        ):
            return ExcCodes.ILLEGAL_VALUE  # time moves by itself in real-time mode
        if "reset" in new and new["reset"] not in (0.0, 1.0):
            return ExcCodes.ILLEGAL_VALUE
        if fault_block:
            refused = self.faults.write(fault_block)
            if refused is not None:
                return refused
            await self.publish()  # the readings the new fault changes now; the block (a
            for key in [k for k in self._published if k[1] == "holding"]:  # trigger: 0)
                del self._published[key]  # again once the client's registers are stored
            self._republish()
        # a write that changes no plant command (the setpoints a client writes every lockstep
        # step) needs no publish: every point of the command reads that value already
        commands = self.emulator.commands
        changed = len(plant) < len(new) or any(commands[k] != v for k, v in plant.items())
        if plant:
            self.emulator.set_checked_commands(plant)
        if "speed_factor" in new:
            self.clock.speed = new["speed_factor"]
            self._reanchor()
        if "clock_mode" in new:
            self.clock.mode = int(new["clock_mode"])
            self._reanchor()
        if new.get("reset") == 1.0:
            self.emulator.reset()
            self.resets += 1
            self.lockstep_counter = 0
            self._reanchor()
            await self.publish()
        if "lockstep_advance_s" in new:
            await self.advance(new["lockstep_advance_s"])  # publishes once done
        elif changed:  # part of the accepted write: every point of a written command (its
            await self.publish()  # aliases in other types, scales, word orders, tables)
        return None  # reads the new value in the next request, not after the next tick
