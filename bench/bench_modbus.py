"""Benchmarks of the Modbus emulator (issue 3), printed, never asserted.

1. Requests per second for FC4 reads of a whole instrument block (bench PLC, 14 registers)
   with 1 and 16 connections, against ``rig-emulator serve`` (real time, 10 Hz tick) and
   against a bare pymodbus SimDevice server of the same layout, measured alternately in the
   same run (median of rounds); target ratio >= 0.9.
2. Tick lateness p50/p99/max at a 10 Hz tick while 16 clients poll every device at 10 Hz;
   target p99 < 5 ms.
3. Lockstep speed: one client advancing 1 s steps and reading every device each step.
4. The server's own work per lockstep step, in-process (no sockets): the segment a
   ``hil-client`` step sends (setpoint write, advance, seven reads), and the publishing of
   the new state alone.
5. The whole load-cycle test through Modbus in lockstep with ``hil-client run`` (issue 4).
6. What the restart guard costs on that whole test (issue 12): the rig with its journal and
   its per-step check of epoch, counter and time, against the rig without them, in
   alternating rounds.
7. Fairness: the first answer to a new connection while another client pipelines 200,000
   reads without waiting for their answers.

Servers and load generators run in separate processes (the machine has 2 cores).
``python bench/bench_modbus.py [SECTION ...]`` runs the sections named (see
:data:`SECTIONS`), all without a name.
"""

from __future__ import annotations

import asyncio
import multiprocessing as mp
import socket
import statistics
import struct
import subprocess
import sys
import time
from pathlib import Path

from stopping import bench_main, quiet_child, require_exit_zero, result_of, sections_asked

from hil_client.wait_for_port import free_port, wait_for_port

HERE = Path(__file__).resolve().parent
PLC_BLOCK = (1, 0, 14)
ROUND_S = 2.0
ROUNDS = 3


async def _connection(port: int) -> tuple[asyncio.StreamReader, asyncio.StreamWriter]:
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    writer.get_extra_info("socket").setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return reader, writer


async def _request(reader, writer, tid: int, unit: int, pdu: bytes) -> bytes:
    writer.write(struct.pack(">HHHB", tid & 0xFFFF, 0, len(pdu) + 1, unit) + pdu)
    header = await reader.readexactly(7)
    return await reader.readexactly(struct.unpack(">HHHB", header)[2] - 1)


def _fc4(address: int, count: int) -> bytes:
    return struct.pack(">BHH", 4, address, count)


async def _hammer(port: int, connections: int, seconds: float) -> int:
    unit, address, count = PLC_BLOCK
    pdu = _fc4(address, count)
    done = 0
    stop = time.monotonic() + seconds

    async def one() -> None:
        nonlocal done
        reader, writer = await _connection(port)
        tid = 0
        while time.monotonic() < stop:
            tid += 1
            await _request(reader, writer, tid, unit, pdu)
            done += 1
        writer.close()

    await asyncio.gather(*(one() for _ in range(connections)))
    return done


def _hammer_process(port: int, connections: int, seconds: float, out) -> None:
    out.put(asyncio.run(_hammer(port, connections, seconds)))


def _rps(port: int, connections: int) -> float:
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(
        target=quiet_child,
        args=(_hammer_process, port, connections, ROUND_S, queue),
        daemon=True,  # (ended with the script)
    )
    proc.start()
    done = result_of(proc, queue)
    proc.join()
    return done / ROUND_S


DEVICE_BLOCKS = (
    (1, 0, 14),
    (2, 0, 11),
    (3, 0, 1),
    (4, 0, 3),
    (5, 0, 2),
    (6, 0, 4),
    (7, 0, 4),
    (100, 0, 7),
)


async def _poll_all(port: int, clients: int, seconds: float, period: float) -> int:
    done = 0
    start = time.monotonic()

    async def one(k: int) -> None:
        nonlocal done
        reader, writer = await _connection(port)
        tick = 0
        tid = 0
        while time.monotonic() - start < seconds:
            tick += 1
            for unit, address, count in DEVICE_BLOCKS:
                tid += 1
                await _request(reader, writer, tid, unit, _fc4(address, count))
                done += 1
            await asyncio.sleep(max(0.0, start + k * 0.005 + tick * period - time.monotonic()))
        writer.close()

    await asyncio.gather(*(one(k) for k in range(clients)))
    return done


def _poll_process(port: int, clients: int, seconds: float, out) -> None:
    out.put(asyncio.run(_poll_all(port, clients, seconds, 0.1)))


def bench_throughput() -> None:
    from hil_client.demo import rig_emulator_serve

    bare_port = free_port()
    bare = subprocess.Popen([sys.executable, str(HERE / "bare_server.py"), str(bare_port)])
    try:
        with rig_emulator_serve("windhager_12kw", "--speed", "1") as (ours_port, _):
            if not wait_for_port("127.0.0.1", bare_port, 60.0):
                raise RuntimeError(f"no server on port {bare_port}")
            for connections in (1, 16):
                a, b = [], []
                for _ in range(ROUNDS):  # alternate, so both see the same machine load
                    a.append(_rps(ours_port, connections))
                    b.append(_rps(bare_port, connections))
                ma, mb = statistics.median(a), statistics.median(b)
                print(
                    f"FC4 read of the bench PLC block, {connections:2d} connection(s): emulator "
                    f"{ma:7.0f} req/s, bare SimDevice server {mb:7.0f} req/s, ratio "
                    f"{ma / mb:.2f} (target >= 0.90; median of {ROUNDS} alternating "
                    f"{ROUND_S:.0f}-s rounds)"
                )
    finally:
        bare.terminate()
        bare.wait(timeout=30)


async def _lateness() -> None:
    from rig_emulator.boilers import load_boiler
    from rig_emulator.emulator import Emulator
    from rig_emulator.instruments import load_profile
    from rig_emulator.modbus import BenchServer
    from rig_emulator.registers import load_map

    emulator = Emulator(load_boiler("windhager_12kw"), load_profile("lab"))
    emulator.set_commands(
        {"water_flow_setpoint_kg_h": 687.0, "return_setpoint_C": 55.0, "boiler_command": 1.0}
    )
    server = BenchServer(emulator, load_map(), port=0, speed=1.0, tick_hz=10.0)
    await server.start()
    seconds = 20.0
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(
        target=quiet_child, args=(_poll_process, server.port, 16, seconds, queue), daemon=True
    )
    proc.start()
    await asyncio.sleep(1.0)
    server.lateness.samples.clear()
    while proc.is_alive():
        await asyncio.sleep(0.2)
    done = result_of(proc, queue)
    await server.stop()
    s = server.lateness.summary_ms()
    print(
        f"tick lateness at 10 Hz with 16 clients polling all 8 devices at 10 Hz "
        f"({done / seconds:.0f} req/s served): p50 {s['p50_ms']:.2f} ms, p99 {s['p99_ms']:.2f} "
        f"ms, max {s['max_ms']:.2f} ms over {s['ticks']:.0f} ticks (target p99 < 5 ms)"
    )


def bench_lockstep() -> None:
    sys.path.insert(0, str(HERE))
    from rawclient import RawClient

    from hil_client.demo import rig_emulator_serve

    with rig_emulator_serve("windhager_12kw", "--lockstep") as (port, _):
        client = RawClient("127.0.0.1", port)
        steps = 0
        start = time.perf_counter()
        while time.perf_counter() - start < 5.0:
            client.write_registers(100, 4, [0, 1])  # lockstep_advance = 1 s
            for unit, address, count in DEVICE_BLOCKS:
                client.read_input(unit, address, count)
            steps += 1
        wall = time.perf_counter() - start
        client.close()
        print(
            f"lockstep: {steps / wall:.0f} simulated s per wall s (1-s advance + 8 device "
            f"reads per step, {wall / steps * 1000:.2f} ms per step, raw-socket client)"
        )


class _NullTransport:
    """Stands in for the socket of :func:`bench_server_step`: replies are dropped."""

    def write(self, data: bytes) -> None:
        pass

    def pause_reading(self) -> None:
        pass

    def resume_reading(self) -> None:
        pass


async def _server_step() -> tuple[float, float]:
    from hil_client.modbus_client import read_pdu, write_registers_pdu
    from hil_client.protocol.rig import READING_KEYS
    from hil_client.rigs.modbus import _read_plan
    from rig_emulator.boilers import load_boiler
    from rig_emulator.emulator import Emulator
    from rig_emulator.instruments import load_profile
    from rig_emulator.modbus import BenchServer
    from rig_emulator.registers import encode, load_map

    register_map = load_map()
    emulator = Emulator(load_boiler("windhager_12kw"), load_profile("clean"))  # as serve
    server = BenchServer(emulator, register_map, port=0, lockstep=True)
    await server.start()
    handler = server._server.callback_new_connection()
    handler.transport = _NullTransport()
    flow_dev, flow = register_map.point("water_flow_setpoint_kg_h")
    _, ret = register_map.point("return_setpoint_C")
    adv_dev, adv = register_map.point("lockstep_advance_s")
    requests = [
        (flow_dev.unit_id, write_registers_pdu(flow.address, encode(flow, 600) + encode(ret, 55))),
        (adv_dev.unit_id, write_registers_pdu(adv.address, encode(adv, 1.0))),
    ] + [
        (r.unit, read_pdu(r.function, r.start, r.count))
        for r in _read_plan(register_map, READING_KEYS)
    ]
    segment = b"".join(
        struct.pack(">HHHB", i + 1, 0, len(pdu) + 1, unit) + pdu
        for i, (unit, pdu) in enumerate(requests)
    )
    emulator.set_commands({"boiler_command": 1.0})
    n = 2000
    rounds_step, rounds_publish = [], []
    for _ in range(5):
        start = time.perf_counter()
        for _ in range(n):
            handler.datagram_received(segment, None)
            while handler.waiting:  # a request that waited (a slice of an advance) finishes
                await asyncio.sleep(0)
        rounds_step.append((time.perf_counter() - start) / n)
        start = time.perf_counter()
        for _ in range(n):
            await server.publish()
        rounds_publish.append((time.perf_counter() - start) / n)
    await server.stop()
    return statistics.median(rounds_step), statistics.median(rounds_publish)


def bench_server_step() -> None:
    step_s, publish_s = asyncio.run(_server_step())
    print(
        f"server work per lockstep step, in-process: {step_s * 1e6:.0f} us for the 9 requests "
        f"of a hil-client step (about {(step_s - publish_s) / 9 * 1e6:.0f} us per request "
        f"besides publishing); publishing the new state alone {publish_s * 1e6:.0f} us "
        f"(median of 5 rounds of 2000)"
    )


def bench_load_cycle() -> None:
    """Issue 4: the whole load-cycle test (preheat, t0..t4) through Modbus in lockstep."""
    import tempfile

    from hil_client.cli import main as client
    from hil_client.demo import rig_emulator_serve

    with rig_emulator_serve("windhager_12kw", "--lockstep") as (port, _):
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            code = client(
                [
                    "run",
                    "load_cycle",
                    "--boiler",
                    "windhager_12kw",
                    "--rig",
                    f"modbus://127.0.0.1:{port}",
                    "--out",
                    f"{tmp}/lc.csv",
                    "--quiet",
                ]
            )
            wall = time.perf_counter() - start
            # (an interrupted run returns 1: its rows are no figure of the whole test)
            require_exit_zero("hil-client run load_cycle", code)
            rows = Path(f"{tmp}/lc.csv").read_text().count("\n") - 1
        print(
            f"load cycle through Modbus, lockstep (hil-client run, exit {code}): {rows} steps "
            f"({rows / 3600:.2f} h simulated) in {wall:.1f} s wall = {rows / wall:.0f} x real "
            f"time (target 1000)"
        )


def _load_cycle_steps_per_s(checks: bool) -> tuple[int, float]:
    """Rows and wall seconds of the load cycle through a fresh lockstep server."""
    from hil_client.demo import rig_emulator_serve
    from hil_client.protocol.definition import load_protocol
    from hil_client.protocol.runner import run_protocol
    from hil_client.rigs.modbus import ModbusRig
    from rig_emulator.boilers import load_boiler
    from rig_emulator.registers import load_map

    params = load_boiler("windhager_12kw")
    with rig_emulator_serve("windhager_12kw", "--lockstep") as (port, _):
        rig = ModbusRig(f"modbus://127.0.0.1:{port}", load_map(), checks=checks)
        start = time.perf_counter()
        result = run_protocol(load_protocol("load_cycle"), params.p_nom_kW, rig, lambda row: None)
        wall = time.perf_counter() - start
        rig.close()
    return result.rows, wall


#: Rounds of each case in :func:`bench_restart_guard` (a whole load cycle each, about 40 s).
GUARD_ROUNDS = 2


def bench_restart_guard() -> None:
    """Issue 12: the journal and the per-step checks on the whole lockstep load cycle,
    with and without, in alternating rounds (without, with, with, without, ...): one after
    the other, the machine's load moved between the two and the cost came out negative
    (-154 us per step, a stranger's run)."""
    walls: dict[bool, list[float]] = {False: [], True: []}
    order = [
        checks for r in range(GUARD_ROUNDS) for checks in ((False, True), (True, False))[r % 2]
    ]
    for checks in order:
        rows, wall = _load_cycle_steps_per_s(checks)
        walls[checks].append(wall / rows)
    per_step = {checks: statistics.median(w) for checks, w in walls.items()}
    print(
        f"load cycle through Modbus, lockstep, no log file, {GUARD_ROUNDS} alternating rounds "
        f"each: with the restart guard (journal, epoch/counter/time read and checked every "
        f"step) {1 / per_step[True]:.0f} x real time, without {1 / per_step[False]:.0f} x real"
        f" time (medians; rounds {[round(1 / w) for w in walls[True]]} and "
        f"{[round(1 / w) for w in walls[False]]}; {rows} steps); cost "
        f"{(per_step[True] - per_step[False]) * 1e6:.0f} us per step; target >= 1000"
    )


def bench_burst_fairness() -> None:
    """A client pipelining 200,000 reads without waiting for the answers, and beside it
    new connections, one request each: how long their first answer takes."""
    import threading

    from hil_client.demo import rig_emulator_serve

    unit, address, count = PLC_BLOCK
    request = struct.pack(">HHHB", 1, 0, 6, unit) + _fc4(address, count)
    n = 200_000
    with rig_emulator_serve("windhager_12kw", "--lockstep") as (port, _):
        burst = socket.create_connection(("127.0.0.1", port))
        answered = [0]

        def drain() -> None:  # takes the burst's answers, slowly at first
            time.sleep(0.5)
            reply_bytes = 7 + 2 + 2 * count
            while answered[0] < n * reply_bytes:
                data = burst.recv(1 << 16)
                if not data:
                    break
                answered[0] += len(data)

        reader = threading.Thread(target=drain, daemon=True)
        sender = threading.Thread(target=burst.sendall, args=(request * n,), daemon=True)
        reader.start()
        sender.start()
        time.sleep(0.2)
        waits = []
        for _ in range(20):
            t0 = time.perf_counter()
            with socket.create_connection(("127.0.0.1", port), timeout=30) as s:
                s.sendall(request)
                s.recv(64)
            waits.append((time.perf_counter() - t0) * 1e3)
            time.sleep(0.05)
        sender.join(timeout=120)
        reader.join(timeout=120)
        burst.close()
    print(
        f"first answer to a new connection while another pipelines {n:,} reads: median "
        f"{statistics.median(waits):.1f} ms, max {max(waits):.1f} ms over {len(waits)} "
        f"connections (target max < 50 ms; 64 requests of a connection answered per turn)"
    )


#: The sections, in the order they run: ``python bench/bench_modbus.py [SECTION ...]``
#: runs those named (all without a name).
SECTIONS = {
    "fairness": bench_burst_fairness,
    "throughput": bench_throughput,
    "lateness": lambda: asyncio.run(_lateness()),
    "lockstep": bench_lockstep,
    "server_step": bench_server_step,
    "load_cycle": bench_load_cycle,
    "restart_guard": bench_restart_guard,
}


def main(argv: list[str] | None = None) -> int:
    for name in sections_asked(argv, SECTIONS, __doc__.splitlines()[0]):
        SECTIONS[name]()
    return 0


if __name__ == "__main__":
    bench_main(main)
