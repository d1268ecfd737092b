"""Benchmarks of fault injection (issue 13), printed, never asserted.

1. FC4 throughput of the bench PLC block with 10 active faults (communication faults on
   other units, instrument faults on five of the PLC's own readings) against the same
   server with none, 1 and 16 connections, alternating rounds; target ratio >= 0.95. On
   a shared, loaded machine the ratio swings by tens of per cent between runs, so the
   in-process cost of the faults per request (the gate) and per tick (the readings) is
   printed too: that is what the ratio can lose at most.
2. Fault timing in lockstep, on the wire: dropouts at awkward ``at_s`` (not multiples of
   the step), each of its own reading, a client advancing 1 s and 7 s steps and reading
   them after each; a fault must read as NaN from the first step with ``t_sim >= at_s``
   (error in steps: 0 = exact). (The server's journal gave nothing to measure: it records
   the window's own times, ``at_s`` itself; a stranger's probe.)
3. Fault timing in real time (10 Hz tick, x1 and x20), on the wire: the first published
   tick whose reading is NaN, minus ``at_s``, in ticks of simulated time, and the ticks at
   or after ``at_s`` that did not show it (0 = exact), for faults after the first 3 s of
   wall time (while numba loads the kernels at start-up a tick may cover several periods).

``python bench/bench_faults.py [SECTION ...]`` runs the sections named (:data:`SECTIONS`).
Servers are ``rig-emulator serve`` subprocesses; load generators run in other processes.
"""

from __future__ import annotations

import asyncio
import math
import statistics
import struct
import tempfile
import time
from pathlib import Path

from bench_modbus import ROUND_S, ROUNDS, _rps, _server_step
from rawclient import RawClient
from stopping import bench_main, sections_asked

from hil_client.demo import rig_emulator_serve

TEN_FAULTS = """\
faults:
  - {kind: delay, unit: 3, delay_ms: 50, at_s: 0}
  - {kind: no_reply, unit: 7, at_s: 0}
  - {kind: exception, unit: 4, code: 6, at_s: 0}
  - {kind: exception, unit: 6, code: 11, at_s: 0}
  - {kind: delay, unit: 5, delay_ms: 20, at_s: 0}
  - {kind: stuck, signal: water_flow_kg_h, at_s: 0}
  - {kind: drift, signal: water_in_temp_C, rate_per_h: 1.0, at_s: 0}
  - {kind: offset, signal: water_out_temp_C, value: 0.5, at_s: 0}
  - {kind: dropout, signal: room_temp_C, at_s: 0}
  - {kind: spike, signal: relative_humidity_pct, value: 99.0, at_s: 0, for_s: 1000000}
"""


def bench_throughput(folder: Path) -> None:
    faults = folder / "ten.yaml"
    faults.write_text(TEN_FAULTS)
    with (
        rig_emulator_serve("windhager_12kw", "--speed", "1") as (plain, _),
        rig_emulator_serve("windhager_12kw", "--speed", "1", "--faults", str(faults)) as (
            faulty,
            _,
        ),
    ):
        time.sleep(1.0)  # the faults at at_s 0 start at the first tick
        probe = RawClient("127.0.0.1", faulty)
        reply = probe.read_input(4, 0, 3)  # the flue-gas probe: exception 06 while faulty
        probe.close()
        gated = reply[:2] == bytes([0x84, 6])
        print(f"faults act on the wire (unit 4 answers exception 06): {'yes' if gated else 'NO'}")
        for connections in (1, 16):
            a, b = [], []
            for _ in range(ROUNDS):
                a.append(_rps(faulty, connections))
                b.append(_rps(plain, connections))
            ma, mb = statistics.median(a), statistics.median(b)
            print(
                f"FC4 read of the bench PLC block, {connections:2d} connection(s): 10 active "
                f"faults {ma:7.0f} req/s, none {mb:7.0f} req/s, ratio {ma / mb:.3f} "
                f"(target >= 0.95; median of {ROUNDS} alternating {ROUND_S:.0f}-s rounds)"
            )


def bench_fault_cost() -> None:
    """In-process, free of the machine's load swings: what the faults add to a request
    (the gate) and to a publish (the readings), with the 10 faults and with none."""
    from types import SimpleNamespace

    import yaml

    from rig_emulator.boilers import load_boiler
    from rig_emulator.emulator import Emulator
    from rig_emulator.faults import faults_from_list
    from rig_emulator.instruments import load_profile
    from rig_emulator.modbus.fault_control import ServerFaults
    from rig_emulator.registers import load_map

    costs = {}
    for label, entries in (("none", []), ("10 faults", yaml.safe_load(TEN_FAULTS)["faults"])):
        emulator = Emulator(load_boiler("windhager_12kw"), load_profile("lab"), 1)
        faults = ServerFaults(emulator, load_map(), faults_from_list(entries))
        emulator.advance(2.0)
        emulator.values()
        info = SimpleNamespace(unit_id=1, function_code=4, peer="bench", role=None)
        n = 200_000
        t0 = time.perf_counter()
        for _ in range(n):
            faults.gate(info)
        gate_us = (time.perf_counter() - t0) / n * 1e6
        t0 = time.perf_counter()
        for _ in range(2000):
            out = emulator.values()
            faults.values(out)
        values_us = (time.perf_counter() - t0) / 2000 * 1e6
        costs[label] = (gate_us, values_us, len(faults.engine.active))
    (g0, v0, _), (g1, v1, active) = costs["none"], costs["10 faults"]
    step_s, publish_s = asyncio.run(_server_step())  # (was a fixed "30-45 us": a stranger)
    request_us = (step_s - publish_s) / 9 * 1e6
    print(
        f"fault cost in-process: gate per request {g1:.2f} us with {active} active faults, "
        f"{g0:.2f} us with none ({100 * (g1 - g0) / request_us:.2f} % of the {request_us:.0f}"
        f" us a request costs the server, measured now as bench_modbus's server_step); "
        f"published values per tick {v1:.1f} us vs {v0:.1f} us (a tick is 100 ms)"
    )


AT_S = (0.5, 3.25, 9.999, 14.0, 20.001, 33.3, 47.7, 61.0)
#: One float32 reading per fault (a dropout reads NaN), in the bench PLC's block and the
#: power meter's, so one fault's start never hides another's.
SIGNALS = (
    "water_flow_kg_h",
    "water_in_temp_C",
    "water_out_temp_C",
    "boiler_water_temp_C",
    "room_temp_C",
    "ambient_pressure_hPa",
    "relative_humidity_pct",
    "electric_power_W",
)
#: The blocks read for them: (unit, first register, count, the signals, in order).
BLOCKS = ((1, 0, 14, SIGNALS[:7]), (6, 0, 2, SIGNALS[7:]))


def _fault_file(folder: Path, name: str, at_s: tuple[float, ...]) -> Path:
    """Dropouts of :data:`SIGNALS` from each ``at_s`` on (long: each stays shown)."""
    path = folder / name
    path.write_text(
        "faults:\n"
        + "".join(
            f"  - {{kind: dropout, signal: {signal}, at_s: {at}, for_s: 100000}}\n"
            for signal, at in zip(SIGNALS, at_s, strict=False)
        )
    )
    return path


def _time(client: RawClient) -> float:
    """The server's simulated time (sim_control, unit 100, float64 at input 0)."""
    return struct.unpack(">d", client.read_input(100, 0, 4)[2:10])[0]


def _dropped(client: RawClient) -> set[str]:
    """The signals of :data:`SIGNALS` whose register reads NaN now."""
    dropped = set()
    for unit, address, count, signals in BLOCKS:
        reply = client.read_input(unit, address, count)
        values = struct.unpack(f">{count // 2}f", reply[2 : 2 + 2 * count])
        dropped.update(s for s, v in zip(signals, values, strict=False) if math.isnan(v))
    return dropped


def bench_lockstep_timing(folder: Path) -> None:
    """When each fault's register first reads NaN on the wire, in steps after the first
    step with ``t_sim >= at_s`` (0 = exact). The journal gave nothing to measure: it
    records the window's own times (``at_s`` itself; a stranger's probe)."""
    for step_s in (1, 7):
        faults = _fault_file(folder, f"lockstep_{step_s}.yaml", AT_S)
        with rig_emulator_serve("windhager_12kw", "--lockstep", "--faults", str(faults)) as (
            port,
            _,
        ):
            client = RawClient("127.0.0.1", port)
            first: dict[str, float] = {}
            while _time(client) < max(AT_S) + 2 * step_s:
                client.write_registers(
                    100, 4, list(struct.unpack(">2H", struct.pack(">I", step_s)))
                )
                t = _time(client)
                for signal in _dropped(client) - first.keys():
                    first[signal] = t
            client.close()
        errors = []
        for signal, at in zip(SIGNALS, AT_S, strict=True):
            expected = math.ceil(at / step_s - 1e-9) * step_s  # the first step at or after
            errors.append(round((first[signal] - expected) / step_s) if signal in first else None)
        print(
            f"fault timing on the wire, lockstep {step_s} s steps: {len(first)}/{len(AT_S)} "
            f"faults read as NaN; first step reading it, against the first step with t_sim >= "
            f"at_s, in steps: {errors} (0 = exact; None = never read)"
        )


def bench_realtime_timing(folder: Path) -> None:
    """When each fault's register first reads NaN on the wire in real time, against its
    ``at_s``: a client reads the time, the readings and the time again, ~200 times a
    second, and keeps the reads whose two times agree (one published tick)."""
    for speed in (1, 20):
        # after 3 s of wall time: at start-up numba loads the kernels in the background, and
        # the first ticks may each cover several periods
        warm_s = 3.0 * speed
        at_s = tuple(warm_s + a for a in (AT_S[:5] if speed == 1 else AT_S))
        faults = _fault_file(folder, f"realtime_{speed}.yaml", at_s)
        tick_sim_s = 0.1 * speed  # 10 Hz tick
        first: dict[str, float] = {}
        missed = dict.fromkeys(SIGNALS[: len(at_s)], 0)  # ticks at/after at_s not showing it
        with rig_emulator_serve(
            "windhager_12kw", "--speed", str(speed), "--faults", str(faults)
        ) as (port, _):
            client = RawClient("127.0.0.1", port)
            deadline = time.monotonic() + max(at_s) / speed + 5.0
            seen_ticks: set[float] = set()
            while len(first) < len(at_s) and time.monotonic() < deadline:
                before, dropped, after = _time(client), _dropped(client), _time(client)
                if before != after or before in seen_ticks:
                    continue
                seen_ticks.add(before)
                for signal, at in zip(SIGNALS, at_s, strict=False):
                    if signal in first or before < at:
                        continue
                    if signal in dropped:
                        first[signal] = before
                    else:
                        missed[signal] += 1
                time.sleep(0.005)
            client.close()
        late = [
            (first[signal] - at) / tick_sim_s
            for signal, at in zip(SIGNALS, at_s, strict=False)
            if signal in first
        ]
        print(
            f"fault timing on the wire, real time x{speed} (10 Hz tick = {tick_sim_s:g} "
            f"simulated s): {len(first)}/{len(at_s)} faults read as NaN; the first tick reading"
            f" it, after at_s, in ticks: max {max(late, default=math.nan):.2f}, mean "
            f"{statistics.mean(late) if late else math.nan:.2f}, each "
            f"{[round(x, 2) for x in late]}; ticks at or after at_s that did not show it: "
            f"{list(missed.values())} (0 = shown from the first tick at or after at_s)"
        )


#: The sections, in the order they run: ``python bench/bench_faults.py [SECTION ...]`` runs
#: those named (all without a name).
SECTIONS = ("cost", "lockstep_timing", "realtime_timing", "throughput")


def main(argv: list[str] | None = None) -> int:
    chosen = sections_asked(argv, SECTIONS, __doc__.splitlines()[0])
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name in chosen:
            {
                "cost": bench_fault_cost,
                "lockstep_timing": lambda: bench_lockstep_timing(folder),
                "realtime_timing": lambda: bench_realtime_timing(folder),
                "throughput": lambda: bench_throughput(folder),
            }[name]()
    return 0


if __name__ == "__main__":
    bench_main(main)
