"""pytest plugin: a real emulator for the users' own test suites (CONTRACT section 5).

Installed with the package (entry point ``pytest11``), it gives every test suite a fixture
``rig_emulator`` (function scope) that starts ``rig-emulator serve --lockstep`` on a free
port of 127.0.0.1 in a subprocess and yields a :class:`RigEmulator` with ``host``, ``port``,
``advance(seconds)``, ``inject(fault)``, ``clear_faults()`` and ``truth(signal)`` (and
``read(signal)``, ``write(signal, value)`` by name for set-up and checks). The server
stops when the test ends, passed or failed, and on Linux when the pytest process dies
however it dies (SIGTERM, SIGKILL). Options per test::

    @pytest.mark.rig_emulator(boiler="windhager_12kw", profile="lab", seed=1, faults="F.yaml")
    def test_my_logger_survives_a_silent_analyser(rig_emulator):
        rig_emulator.inject({"kind": "no_reply", "unit": 2, "for_s": 30})
        rig_emulator.advance(10)
        ...

Everything goes over the wire, as the test's own client would: ``advance`` writes the
simulation control's ``lockstep_advance``, ``inject``/``clear_faults`` its fault command
block, ``truth`` reads the truth unit (101).
"""

from __future__ import annotations

import contextlib
import decimal
import math
import numbers
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import pytest

DEFAULTS = {"boiler": "windhager_12kw", "profile": "clean", "seed": 0, "faults": None}
START_TIMEOUT_S = 120.0  # the first start may compile numba's kernels
MAX_ADVANCE_S = 86_400  # the server's limit for one lockstep advance (a day)
#: The most one ``advance`` call may ask for [s]: a year of the plant, over a minute of the
#: machine's time (a simulated day takes about 0.2 s); ``advance(10**12)``, a count of
#: milliseconds given as seconds, ran for days without a word (a stranger's probe).
MAX_ADVANCE_CALL_S = 366 * 86_400
#: How long ``read``, ``write`` and the fault calls wait for a reply [s]: a lockstep server
#: answers at once but for a ``delay`` fault (a few seconds at most in practice); a
#: ``no_reply`` fault costs this long, then :class:`RigEmulatorError` (it cost 60 s and
#: ended in pymodbus's own exception: a stranger's probe). ``reply_timeout_s`` sets it.
REPLY_TIMEOUT_S = 5.0
#: The longest ``reply_timeout_s`` taken [s]: a day (the socket library's own limit, the
#: platform's time_t, is far beyond any test's patience)
REPLY_TIMEOUT_MAX_S = 86400.0
#: How long an advance may take to answer [s]: a day of the lab profile takes seconds on a
#: loaded machine.
ADVANCE_TIMEOUT_S = 300.0
#: How long :meth:`RigEmulator.stop` waits for the last lines of a stopped server's
#: standard error [s]: they are in the pipe when it exits, so this is a bound, not a wait.
STDERR_DRAIN_S = 10.0
_LISTENING = re.compile(r"serving .* on ([^\s:]+):(\d+) ")


_PR_SET_PDEATHSIG = 1  # linux/prctl.h


def _stop_with_parent() -> None:
    """In the server's process before it runs (Linux): SIGTERM it when the process that
    started it dies, however that dies (a CI job cancelled with SIGTERM, pytest killed
    with -9, a timeout's hard exit), so no server outlives its test run."""
    import ctypes

    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)


#: the servers this process started and has not stopped (for :func:`_watch_controller`)
_LIVE: set[subprocess.Popen] = set()
_WATCHING: list[threading.Thread] = []


def _watch_controller() -> None:
    """Under pytest-xdist (a worker, ``PYTEST_XDIST_WORKER``), stop this worker's servers
    once the controlling pytest is gone (the worker's parent changes). The parent-death
    signal ties a server to the worker that started it, and a worker outlives a killed
    controller until its test ends: a test that never ends kept its server and its port
    for good (a stranger's probe with ``pytest -n 2`` killed)."""
    if not os.environ.get("PYTEST_XDIST_WORKER") or _WATCHING:
        return
    controller = os.getppid()

    def watch() -> None:
        while os.getppid() == controller:
            time.sleep(0.5)
        for process in list(_LIVE):
            with contextlib.suppress(OSError):
                process.send_signal(signal.SIGTERM)

    thread = threading.Thread(target=watch, name="rig_emulator-controller-watch", daemon=True)
    thread.start()
    _WATCHING.append(thread)


def _no_reply(exc: Exception) -> bool:
    """Whether pymodbus's ``exc`` says the request went out and no reply came in time (a
    reset or closed connection says otherwise: a ``disconnect`` fault's, read as "no
    reply" at first: a re-probe)."""
    return "No response received" in str(exc) and not isinstance(exc.__cause__, OSError)


#: The Modbus exception codes by their names in the Application Protocol Specification
#: (section 7)
EXCEPTION_NAMES = {
    1: "illegal function",
    2: "illegal data address",
    3: "illegal data value",
    4: "server device failure",
    5: "acknowledge",
    6: "server device busy",
    8: "memory parity error",
    10: "gateway path unavailable",
    11: "gateway target device failed to respond",
}


def _refusal(reply: Any) -> str:
    """A refused request's reply as the spec names it: "exception 04 (server device
    failure)" (pymodbus's repr, "ExceptionResponse(dev_id=1, function_code=144, ...)", was
    the message: a stranger's probe)."""
    code = getattr(reply, "exception_code", None)
    if not isinstance(code, int):
        return str(reply)
    return f"exception {code:02X} ({EXCEPTION_NAMES.get(code, 'not in the spec')})"


def _switch(signal_name: str, value: object) -> bool:
    """``value`` as a coil carries it: 0 or 1, False or True (numpy's too), nothing else."""
    import numpy as np

    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, numbers.Real) and value in (0, 1):
        return bool(value)
    raise ValueError(
        f"write({signal_name!r}, {value!r}): {signal_name} is a switch (a coil):"
        " expected 0 or 1, False or True"
    )


class RigEmulatorError(RuntimeError):
    """The emulator did not start or refused a request."""


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "rig_emulator(boiler='windhager_12kw', profile='clean', seed=0, faults=None): "
        "options of the rig_emulator fixture's server",
    )


class RigEmulator:
    """A running lockstep emulator (a subprocess) and the calls a test needs.

    Attributes:
        host, port: where it listens (Modbus TCP).
        journal: the fault journal it writes (JSONL, one line per fault start and end).
        stderr_lines: what the server logged so far.
        reply_timeout_s: how long a read or write waits for its reply
            (:data:`REPLY_TIMEOUT_S`).
    """

    reply_timeout_s: float = REPLY_TIMEOUT_S

    def __init__(
        self,
        boiler: str = "windhager_12kw",
        profile: str = "clean",
        seed: int = 0,
        faults: str | os.PathLike | None = None,
        workdir: str | os.PathLike | None = None,
    ) -> None:
        self.options = {"boiler": boiler, "profile": profile, "seed": seed, "faults": faults}
        self._tmp = tempfile.TemporaryDirectory(prefix="rig_emulator_") if workdir is None else None
        folder = Path(workdir if workdir is not None else self._tmp.name)  # type: ignore[union-attr]
        self.journal = folder / "fault_journal.jsonl"
        command = [
            sys.executable,
            "-m",
            "rig_emulator.cli",
            "serve",
            "--boiler",
            str(boiler),
            "--profile",
            str(profile),
            "--seed",
            str(int(seed)),
            "--lockstep",
            "--host",
            "127.0.0.1",
            "--port",
            "0",
            "--fault-log",
            str(self.journal),
        ]
        if faults is not None:
            command += ["--faults", str(faults)]
        self.stderr_lines: list[str] = []
        self._client = None
        self._drain: threading.Thread | None = None
        try:
            self.process = subprocess.Popen(
                command,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
                text=True,
                preexec_fn=_stop_with_parent if sys.platform == "linux" else None,
            )
        except BaseException:
            self._remove_workdir()
            raise
        _LIVE.add(self.process)
        _watch_controller()
        self._listening: tuple[str, int] | None = None
        self._started = threading.Event()  # listening, or its standard error ended
        try:  # a start that fails (or is interrupted) leaves no process, pipe or folder
            self._drain = threading.Thread(target=self._read_stderr, daemon=True)
            self._drain.start()
            self.host, self.port = self._wait_listening()
            from rig_emulator.registers import load_map

            self.map = load_map()
        except BaseException:
            self.stop()
            raise

    def __repr__(self) -> str:
        return (
            f"<RigEmulator {self.host}:{self.port} boiler={self.options['boiler']!s} "
            f"profile={self.options['profile']!s} seed={self.options['seed']}>"
        )

    # ------------------------------------------------------------------ lifecycle
    def _wait_listening(self) -> tuple[str, int]:
        """The server's host and port once it says it serves, at most
        :data:`START_TIMEOUT_S` later: a server that hung without a word hung the fixture,
        the bound never applied while a read of its standard error waited (a review)."""
        self._started.wait(START_TIMEOUT_S)
        if self._listening is not None:
            return self._listening
        if self._started.is_set():  # (its standard error ended: it stopped)
            why = "did not start"
        else:
            why = f"said nothing of serving in {START_TIMEOUT_S:g} s"
        raise RigEmulatorError(f"rig-emulator serve {why}: " + " | ".join(self.stderr_lines[-5:]))

    def _read_stderr(self) -> None:
        """Keep the server's standard error (:attr:`stderr_lines`) to its end, noting the
        line that says where it serves."""
        assert self.process.stderr is not None
        try:
            for line in self.process.stderr:
                self.stderr_lines.append(line.rstrip("\n"))
                match = _LISTENING.search(line) if self._listening is None else None
                if match:
                    self._listening = (match.group(1), int(match.group(2)))
                    self._started.set()
        finally:
            self._started.set()

    def stop(self) -> None:
        """Stop the server (SIGTERM, then SIGKILL after 10 s) and close what talked to it.

        Its standard error is read to the end and closed: left open, the pipe was an
        "unclosed file" ResourceWarning in the user's test, which a suite run with
        ``filterwarnings = error`` (or ``-W error``) reported as an error of the next test,
        and ``PYTHONDEVMODE=1`` showed for every test, a server that failed to start too
        (a stranger's probe). Stopping twice does nothing more."""
        self._reconnect()
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(timeout=10)
        _LIVE.discard(self.process)
        self._close_stderr()
        self._remove_workdir()

    def _close_stderr(self) -> None:
        """Close the server's standard error once the reader thread has taken its last
        lines (the end of the pipe comes with the server's exit). A pipe another process
        still holds open (nothing the server starts does) keeps its thread and stays open:
        closing a file that a thread is reading waits for that read."""
        stderr = self.process.stderr
        if stderr is None or stderr.closed:
            return
        if self._drain is not None:
            self._drain.join(timeout=STDERR_DRAIN_S)
            if self._drain.is_alive():
                return
        stderr.close()

    def _remove_workdir(self) -> None:
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    def __enter__(self) -> RigEmulator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # ------------------------------------------------------------------ the wire
    @property
    def client(self):
        """A pymodbus client connected to the server (reconnected when needed)."""
        from pymodbus.client import ModbusTcpClient

        __tracebackhide__ = True
        timeout = self._timeout_s()
        if self._client is None:
            self._client = ModbusTcpClient(self.host, port=self.port, timeout=timeout, retries=0)
        if not self._client.connected and not self._client.connect():
            raise RigEmulatorError(f"cannot connect to {self.host}:{self.port}")
        return self._client

    def _timeout_s(self) -> float:
        """:attr:`reply_timeout_s` as a float, or ``ValueError`` naming it (pymodbus said
        "Timeout value out of range", naming nothing; numpy's float32 and a Fraction were
        a TypeError in the socket library, 1e12 an OverflowError: probes)."""
        __tracebackhide__ = True
        timeout = self.reply_timeout_s
        number = isinstance(timeout, numbers.Real | decimal.Decimal)  # (Decimal: not Real)
        try:  # (an int of 400 digits: OverflowError from float(), a re-probe)
            seconds = float(timeout) if number else math.nan
        except OverflowError:
            seconds = math.inf
        except ValueError:  # (Decimal("sNaN"))
            seconds = math.nan
        if isinstance(timeout, bool) or not 0 < seconds <= REPLY_TIMEOUT_MAX_S:
            raise ValueError(
                f"reply_timeout_s = {timeout!r}: expected a number of seconds > 0 and at "
                f"most {REPLY_TIMEOUT_MAX_S:g}"
            )
        return seconds

    def _call(self, request: Callable[[Any], Any], what: str) -> Any:
        """``request(client)`` within :attr:`reply_timeout_s`; once more on a new connection
        if the server closed this one (a ``disconnect`` fault closes the fixture's
        connection too). No reply in time is :class:`RigEmulatorError` naming ``what``."""
        from pymodbus.exceptions import ConnectionException, ModbusIOException

        client = self.client
        client.comm_params.timeout_connect = self._timeout_s()
        try:
            return request(client)
        except ModbusIOException as exc:
            if _no_reply(exc):  # the connection stands, nothing came back in time: the
                self._reconnect()  # next call goes on a new one (a late reply on this
                late = " (a write delayed is still carried out when its delay ends)"
                raise RigEmulatorError(  # one answered the calls after it: a re-probe)
                    f"{what}: no reply within {self._timeout_s():g} s (a no_reply fault, "
                    "or a delay longer than that; reply_timeout_s sets the wait)"
                    + (late if what.startswith("write") else "")
                ) from exc
        except (ConnectionException, OSError):
            pass  # the server closed the connection (a disconnect): once more on a new one
        self._reconnect()
        try:
            return request(self.client)
        except (ConnectionException, ModbusIOException, OSError) as exc:
            raise RigEmulatorError(f"{what}: {exc}") from exc

    def _reconnect(self) -> None:
        if self._client is not None:
            with contextlib.suppress(Exception):
                self._client.close()
            self._client = None

    def _write(self, signal_name: str | None, registers: list[int], address: int | None = None):
        device, point = self.map.point(signal_name) if signal_name else (None, None)
        unit = device.unit_id if device else self.map.point("fault_kind")[0].unit_id
        start = point.address if point else int(address or 0)
        reply = self._call(
            lambda c: c.write_registers(start, registers, device_id=unit),
            f"write at {unit}:{start}",
        )
        if reply.isError():
            raise RigEmulatorError(f"write at {unit}:{start} refused: {_refusal(reply)}")

    def advance(self, seconds: float) -> None:
        """Advance the simulation by ``seconds`` and return once the new state is readable.

        Whole seconds (the register is a uint32 of seconds); 0 does nothing; more than a
        day goes as several writes of at most a day each. A fraction, a negative number,
        one that is not finite or more than a year (:data:`MAX_ADVANCE_CALL_S`) is refused
        with ``ValueError`` before anything moves. A
        connection lost meanwhile is settled by the lockstep counter: each write happens
        exactly once."""
        __tracebackhide__ = True  # a bad duration fails the user's line, not the plugin's
        if isinstance(seconds, bool) or not isinstance(seconds, numbers.Real):
            raise ValueError(f"advance({seconds!r}): expected a number of seconds")
        seconds = float(seconds)  # numpy's numbers too
        if not math.isfinite(seconds) or seconds < 0 or seconds != int(seconds):
            raise ValueError(
                f"advance({seconds!r}): the emulator advances whole seconds, 0 or more "
                "(the lockstep_advance register is a uint32 of seconds)"
            )
        if seconds > MAX_ADVANCE_CALL_S:
            raise ValueError(
                f"advance({int(seconds)}): more than a year ({MAX_ADVANCE_CALL_S} s) in one call"
                " (milliseconds given as seconds?); call it again for longer"
            )
        left = int(seconds)
        while left > 0:
            chunk = min(left, MAX_ADVANCE_S)
            self._advance_once(chunk)
            left -= chunk

    def _advance_once(self, seconds: int) -> None:
        from pymodbus.exceptions import ConnectionException, ModbusIOException

        from rig_emulator.registers import encode

        device, point = self.map.point("lockstep_advance_s")
        registers = encode(point, float(seconds))
        before = self.read("lockstep_counter")
        client = self.client
        client.comm_params.timeout_connect = ADVANCE_TIMEOUT_S
        try:
            reply = client.write_registers(point.address, registers, device_id=device.unit_id)
        except (ConnectionException, ModbusIOException, OSError):
            self._reconnect()
            if self.read("lockstep_counter") != before:
                return  # it was applied; only its reply was lost
            client = self.client
            client.comm_params.timeout_connect = ADVANCE_TIMEOUT_S
            reply = client.write_registers(point.address, registers, device_id=device.unit_id)
        if reply.isError():
            raise RigEmulatorError(f"advance by {seconds} s refused: {_refusal(reply)}")

    def inject(self, fault: Mapping[str, Any]) -> None:
        """Set a fault, a dict as in ``FAULTS.yaml`` (e.g. ``{"kind": "dropout", "signal":
        "flue_gas_CO_ppm", "for_s": 60}``); without ``at_s`` it starts now. A fault that is
        none (a field missing or wrong, a unit the bench does not have) raises
        :class:`~rig_emulator.faults.FaultError` naming the field, and nothing is set."""
        from rig_emulator.faults.spec import FaultError, check_spikes, check_units
        from rig_emulator.faults.wire import block_values, fault_dict_to_spec
        from rig_emulator.modbus.fault_control import reading_ranges
        from rig_emulator.registers import emulator_units, encode

        __tracebackhide__ = True  # a bad fault fails the user's line, not the plugin's
        if not isinstance(fault, Mapping):
            raise FaultError(
                f"inject({fault!r}): expected a dict as in FAULTS.yaml, e.g. "
                '{"kind": "no_reply", "unit": 2, "for_s": 30}'
            )
        try:
            spec = fault_dict_to_spec(fault)
            # the server's own checks (the emulator's units are refused with the spec above)
            units = {d.unit_id for d in self.map.devices}
            check_units([spec], units, "fault", emulator_units(self.map))
            check_spikes([spec], reading_ranges(self.map), "fault")
        except FaultError as exc:
            raise FaultError(str(exc)) from None
        values = block_values(spec)
        _, first = self.map.point("fault_kind")
        registers: list[int] = []
        for name in ("fault_kind", "fault_target", "fault_parameter", "fault_duration_s"):
            registers += encode(self.map.point(name)[1], values[name])
        registers += encode(self.map.point("fault_at_s")[1], values["fault_at_s"])
        registers += encode(self.map.point("fault_command")[1], values["fault_command"])
        self._write(None, registers, first.address)

    def clear_faults(self) -> None:
        """End every fault (active or scheduled)."""
        from rig_emulator.faults.wire import COMMAND_CLEAR
        from rig_emulator.registers import encode

        _, point = self.map.point("fault_command")
        self._write("fault_command", encode(point, float(COMMAND_CLEAR)))

    def read(self, signal_name: str) -> float:
        """A signal's published value (reading, status or command) by name."""
        from rig_emulator.registers import decode, invalid_value

        __tracebackhide__ = True  # a wrong name fails the user's line, not the plugin's
        device, point = self._point("read", signal_name)
        method = {
            "input": "read_input_registers",
            "holding": "read_holding_registers",
            "discrete": "read_discrete_inputs",
            "coil": "read_coils",
        }[point.table]
        unit = device.unit_id
        reply = self._call(
            lambda c: getattr(c, method)(point.address, count=point.width, device_id=unit),
            f"read of {signal_name}",
        )
        if reply.isError():
            raise RigEmulatorError(f"read of {signal_name} refused: {_refusal(reply)}")
        words = reply.bits[:1] if point.table in ("coil", "discrete") else reply.registers
        value = decode(point, list(words))
        # an integer at its invalid code is no reading, as a float's NaN is
        return math.nan if value == invalid_value(point) else value

    def write(self, signal_name: str, value: float) -> None:
        """Write a command (a setpoint, a switch) by signal name, e.g.
        ``write("boiler_command", 1)``, as the map encodes it.

        A switch (a coil) takes 0 or 1, False or True; anything else is refused with
        ``ValueError`` before anything is sent, as a value that is no number is for any
        command (a stranger's probe: 2, 0.5 and -1 were sent as on or off, NaN as off, where
        the server refuses such values with 03; ``"off"`` was a TypeError)."""
        from rig_emulator.registers import encode

        __tracebackhide__ = True  # a bad value fails the user's line, not the plugin's
        device, point = self._point("write", signal_name)
        if not point.writable or point.table not in ("holding", "coil"):
            # (an FC16 at a reading's address wrote the holding register there: "writing"
            # water_flow_kg_h set the flow setpoint, without a word: a stranger's probe)
            raise ValueError(
                f"write({signal_name!r}, ...): {signal_name} is no command (unit "
                f"{device.unit_id} point '{point.name}', {point.table} table, access "
                f"{point.access}); read() reads it"
            )
        if point.table == "coil":
            on = _switch(signal_name, value)
            reply = self._call(
                lambda c: c.write_coil(point.address, on, device_id=device.unit_id),
                f"write of {signal_name}",
            )
        else:
            if not isinstance(value, numbers.Real):  # (a bool is 0 or 1)
                raise ValueError(f"write({signal_name!r}, {value!r}): expected a number")
            words = encode(point, float(value))
            reply = self._call(
                lambda c: c.write_registers(point.address, words, device_id=device.unit_id),
                f"write of {signal_name}",
            )
        if reply.isError():
            raise RigEmulatorError(f"write of {signal_name} = {value} refused: {_refusal(reply)}")

    def _point(self, call: str, signal_name: str) -> tuple[Any, Any]:
        """The device and point of ``signal_name``, or ``ValueError`` naming the signals
        there are (a bare ``KeyError: 'nope'`` was the message: a stranger's probe)."""
        __tracebackhide__ = True
        try:
            return self.map.point(signal_name)
        except KeyError:
            names = dict.fromkeys(  # (write: its commands only, all it takes: a re-probe)
                p.signal
                for d in self.map.devices
                for p in d.points
                if call != "write" or (p.writable and p.table in ("holding", "coil"))
            )
            raise ValueError(
                f"{call}({signal_name!r}): no point of the register map publishes it (one "
                f"of {', '.join(names)})"
            ) from None

    def truth(self, signal_name: str) -> float:
        """The plant's true value of a measured signal (not the reading), from the truth
        unit."""
        from rig_emulator.signals import MEASURED

        __tracebackhide__ = True
        if signal_name not in MEASURED:
            raise ValueError(
                f"truth({signal_name!r}): not a measured signal (one of {', '.join(MEASURED)})"
            )
        return self.read("true_" + signal_name)

    def active_fault_count(self) -> int:
        return int(self.read("active_fault_count"))


def marker_options(request: pytest.FixtureRequest) -> dict[str, Any]:
    """The fixture's options from the test's ``rig_emulator`` marker, checked: each wrong
    one fails the test with one line naming it. A relative ``faults`` path is taken from
    the working directory, or else from the test file's folder."""
    options = dict(DEFAULTS)
    marker = request.node.get_closest_marker("rig_emulator")
    if marker is None:
        return options
    usage = f"@pytest.mark.rig_emulator takes only the keywords {', '.join(DEFAULTS)}"
    if marker.args:
        pytest.fail(f"{usage}; got positional {marker.args!r}", pytrace=False)
    unknown = sorted(set(marker.kwargs) - set(DEFAULTS))
    if unknown:
        pytest.fail(f"{usage}; got {', '.join(unknown)}", pytrace=False)
    options.update(marker.kwargs)
    for key in ("boiler", "profile"):
        if not isinstance(options[key], str | os.PathLike) or not str(options[key]):
            pytest.fail(f"@pytest.mark.rig_emulator: {key}={options[key]!r} is no name or path",
                        pytrace=False)  # fmt: skip
    seed = options["seed"]
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or not 0 <= seed < 2**32:
        pytest.fail(f"@pytest.mark.rig_emulator: seed={seed!r} is not an integer 0..2**32-1",
                    pytrace=False)  # fmt: skip
    faults = options["faults"]
    if faults is not None:
        if not isinstance(faults, str | os.PathLike):
            pytest.fail(f"@pytest.mark.rig_emulator: faults={faults!r} is no path",
                        pytrace=False)  # fmt: skip
        path = Path(faults)
        beside = Path(request.node.path).parent / path
        if not path.is_absolute() and not path.exists() and beside.exists():
            options["faults"] = beside
    return options


@pytest.fixture
def rig_emulator(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[RigEmulator]:
    """A lockstep ``rig-emulator serve`` on a free port, stopped when the test ends; its
    fault journal (:attr:`RigEmulator.journal`) in a folder of its own, so the test's
    ``tmp_path`` holds only what the test writes."""
    options = marker_options(request)
    try:
        emulator = RigEmulator(workdir=tmp_path_factory.mktemp("rig_emulator"), **options)
    except RigEmulatorError as exc:  # the server's own one line, not the plugin's insides
        failed = str(exc)
    else:
        failed = None
    if failed is not None:
        pytest.fail(failed, pytrace=False)
    try:
        yield emulator
    finally:
        emulator.stop()
