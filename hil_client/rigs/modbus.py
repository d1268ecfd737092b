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

A lost connection is retried with exponential backoff (0.1 s doubling to 5 s, up to
``reconnect_timeout_s``); commands are written again, a lockstep advance that may not have
happened is settled by the server's simulated time, and the outage is recorded in
:attr:`gaps`. Nothing already acquired is touched.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from urllib.parse import urlparse

from hil_client.modbus_client import (
    Connection,
    ConnectionLost,
    ModbusExceptionResponse,
    bits_of,
    read_pdu,
    registers_of,
    write_coils_pdu,
    write_registers_pdu,
)
from hil_client.protocol.rig import READING_KEYS, RigCommand, RigError
from rig_emulator.registers import Point, RegisterMap, decode, encode, run_decoder

_READ_FUNCTION = {"coil": 1, "discrete": 2, "holding": 3, "input": 4}


@dataclass(frozen=True, slots=True)
class _Read:
    """One read request: a contiguous run of points of one table of one unit."""

    unit: int
    function: int
    start: int
    count: int
    points: tuple[Point, ...]
    decode: Callable[[Sequence[int]], list[float]]  # the run's registers -> its values


def parse_url(url: str) -> tuple[str, int]:
    """(host, port) of ``modbus://HOST:PORT``."""
    parsed = urlparse(url)
    if parsed.scheme != "modbus" or not parsed.hostname:
        raise ValueError(f"'{url}' is not modbus://HOST:PORT")
    try:
        port = parsed.port or 502
    except ValueError:
        raise ValueError(f"'{url}' has a bad port") from None
    return parsed.hostname, port


def _read_plan(register_map: RegisterMap, signals: tuple[str, ...]) -> list[_Read]:
    """The fewest requests that read every signal (contiguous runs only: gaps answer 02)."""
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
        run: list[Point] = []
        for p in table_points:
            if run and p.address != run[-1].address + run[-1].width:
                if any(q in points for q in run):
                    plan.append(_make_read(unit, table, run))
                run = []
            run.append(p)
        if run and any(q in points for q in run):
            plan.append(_make_read(unit, table, run))
    return plan


def _make_read(unit: int, table: str, run: list[Point]) -> _Read:
    start = run[0].address
    count = run[-1].address + run[-1].width - start
    return _Read(unit, _READ_FUNCTION[table], start, count, tuple(run), run_decoder(run))


class ModbusRig:
    """A remote bench reached over Modbus TCP (see the module docstring)."""

    def __init__(
        self,
        url: str,
        register_map: RegisterMap,
        timeout_s: float = 5.0,
        reconnect_timeout_s: float = 60.0,
    ) -> None:
        try:
            self.host, self.port = parse_url(url)
        except ValueError as exc:
            raise RigError(str(exc)) from None
        self.url = url
        self.map = register_map
        self.timeout_s = timeout_s
        self.reconnect_timeout_s = reconnect_timeout_s
        self.gaps: list[dict[str, float | str]] = []
        plan = _read_plan(register_map, READING_KEYS)  # a map without a reading fails here
        clock_plan = _read_plan(register_map, ("sim_time_s",))
        self._points = {
            s: register_map.point(s)
            for s in (
                "water_flow_setpoint_kg_h",
                "return_setpoint_C",
                "pump_on",
                "return_heating",
                "boiler_command",
                "lockstep_advance_s",
                "clock_mode",
                "speed_factor",
                "sim_time_s",
            )
        }
        self._conn: Connection | None = None
        self._command: RigCommand | None = None
        self._written_switches: tuple[bool, bool, bool] | None = None
        self.values: dict[str, float] = {}
        try:
            self._connect()
        except ConnectionLost as exc:
            raise RigError(f"cannot reach {url}: {exc}") from None
        self.lockstep = self._read_point("clock_mode") == 1.0
        self.speed = self._read_point("speed_factor")
        self.sim_time_s = self._read_point("sim_time_s")
        # in lockstep the rig knows the time it advanced to; otherwise it polls the clock too
        self._reads = plan if self.lockstep else plan + clock_plan
        self._read_requests = [
            (r.unit, read_pdu(r.function, r.start, r.count)) for r in self._reads
        ]

    # ------------------------------------------------------------------ connections
    def _connect(self) -> None:
        self.close()
        self._conn = Connection(self.host, self.port, self.timeout_s)

    def _reconnect(self, reason: str) -> None:
        started = time.monotonic()
        sim_before = self.sim_time_s
        delay = 0.1
        while True:
            try:
                self._connect()
                self._written_switches = None
                self.sim_time_s = self._read_point("sim_time_s")
                break
            except ConnectionLost:
                if time.monotonic() - started > self.reconnect_timeout_s:
                    raise RigError(
                        f"{self.url}: connection lost ({reason}) and not back within "
                        f"{self.reconnect_timeout_s:g} s"
                    ) from None
                time.sleep(delay)
                delay = min(delay * 2, 5.0)
        self.gaps.append(
            {
                "reason": reason,
                "sim_time_lost_s": sim_before,
                "sim_time_back_s": self.sim_time_s,
                "outage_wall_s": round(time.monotonic() - started, 3),
            }
        )

    def close(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None

    # ------------------------------------------------------------------ primitives
    def _exchange(self, requests: list[tuple[int, bytes]]) -> list[bytes]:
        """Send ``(unit, pdu)`` requests pipelined; their replies, in order."""
        assert self._conn is not None
        if not requests:
            return []
        self._conn.send(requests)
        return [self._conn.receive() for _ in requests]

    def _read_point(self, signal: str) -> float:
        device, point = self._points[signal]
        (reply,) = self._exchange(
            [(device.unit_id, read_pdu(_READ_FUNCTION[point.table], point.address, point.width))]
        )
        if point.table in ("coil", "discrete"):
            return 1.0 if bits_of(reply, 1)[0] else 0.0
        return decode(point, registers_of(reply))

    def _write_request(self, signal: str, value: float) -> tuple[int, bytes]:
        device, point = self._points[signal]
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
        if flow_dev is ret_dev and ret.address == flow.address + flow.width:
            words = encode(flow, cmd.flow_setpoint_kg_h) + encode(ret, cmd.return_setpoint_C)
            requests = [(flow_dev.unit_id, write_registers_pdu(flow.address, words))]
        else:
            requests = [
                self._write_request("water_flow_setpoint_kg_h", cmd.flow_setpoint_kg_h),
                self._write_request("return_setpoint_C", cmd.return_setpoint_C),
            ]
        switches = (cmd.pump_on, cmd.return_heating, cmd.boiler_on)
        if switches != self._written_switches:  # a lost connection resets this to None
            requests += [
                self._write_request("pump_on", float(cmd.pump_on)),
                self._write_request("return_heating", float(cmd.return_heating)),
                self._write_request("boiler_command", float(cmd.boiler_on)),
            ]
            self._written_switches = switches
        return requests

    def _store(self, replies: list[bytes]) -> None:
        """Decode the replies to :attr:`_read_requests` into :attr:`values`."""
        values = self.values
        for read, reply in zip(self._reads, replies, strict=True):
            words = bits_of(reply, read.count) if read.function in (1, 2) else registers_of(reply)
            for p, value in zip(read.points, read.decode(words), strict=True):
                values[p.signal] = value

    # ------------------------------------------------------------------ rig interface
    def apply(self, command: RigCommand) -> None:
        self._command = RigCommand(
            command.flow_setpoint_kg_h,
            command.return_setpoint_C,
            command.pump_on,
            command.boiler_on,
            command.return_heating,
        )

    def advance(self, dt_s: float) -> float:
        """Write the commands, let ``dt_s`` of simulated time pass, poll every instrument.

        Returns the simulated time that actually passed [s] (more than ``dt_s`` in real-time
        mode when the client fell behind or the connection was down).
        """
        before = self.sim_time_s
        target = before + dt_s
        for _ in range(1000):
            try:
                commands = self._command_requests()
                if self.lockstep:
                    if self.sim_time_s < target - 1e-6:  # not yet advanced before a reconnect
                        step = target - self.sim_time_s
                        commands.append(self._write_request("lockstep_advance_s", step))
                    replies = self._exchange(commands + self._read_requests)
                    self.sim_time_s = target
                else:
                    self._exchange(commands)
                    self._wait_until(target)
                    replies = self._exchange(self._read_requests)
                self._store(replies[len(replies) - len(self._reads) :])
                if not self.lockstep:
                    self.sim_time_s = self.values["sim_time_s"]
                return self.sim_time_s - before
            except (ConnectionLost, OSError) as exc:
                self._reconnect(str(exc))
            except ModbusExceptionResponse as exc:
                raise RigError(f"{self.url}: {exc}") from None
        raise RigError(f"{self.url}: no progress after 1000 reconnections")

    def _wait_until(self, target: float) -> None:
        while True:
            now = self._read_point("sim_time_s")
            if now >= target - 1e-9:
                return
            wait = (target - now) / max(self.speed, 1e-9)
            time.sleep(min(max(wait * 0.5, 0.001), 0.25))

    def read(self) -> tuple[float, ...]:
        values = self.values
        return tuple(values.get(key, math.nan) for key in READING_KEYS)
