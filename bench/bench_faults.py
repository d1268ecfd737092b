"""Benchmarks of fault injection (issue 13), printed, never asserted.

1. FC4 throughput of the bench PLC block with 10 active faults (communication faults on
   other units, instrument faults on five of the PLC's own readings) against the same
   server with none, 1 and 16 connections, alternating rounds; target ratio >= 0.95. On
   a shared, loaded machine the ratio swings by tens of per cent between runs, so the
   in-process cost of the faults per request (the gate) and per tick (the readings) is
   printed too: that is what the ratio can lose at most.
2. Fault timing in lockstep: faults at awkward ``at_s`` (not multiples of the step), a
   client advancing 1 s and 7 s steps; a fault must start at the first step with
   ``t_sim >= at_s`` (error in steps: 0 = exact).
3. Fault timing in real time (10 Hz tick, x1 and x20): journalled start minus ``at_s``,
   in ticks of simulated time, for faults after the first 3 s of wall time (while numba
   loads the kernels at start-up a tick may cover several periods); target <= 1 tick.

Servers are ``rig-emulator serve`` subprocesses; load generators run in other processes.
"""

from __future__ import annotations

import json
import statistics
import struct
import sys
import tempfile
import time
from pathlib import Path

from bench_modbus import ROUND_S, ROUNDS, _rps
from rawclient import RawClient

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
    print(
        f"fault cost in-process: gate per request {g1:.2f} us with {active} active faults, "
        f"{g0:.2f} us with none; published values per tick {v1:.1f} us vs {v0:.1f} us "
        "(a request costs the server 30-45 us, a tick 100 ms)"
    )


def _starts(journal: Path) -> dict[int, float]:
    out = {}
    for line in journal.read_text().splitlines():
        event = json.loads(line)
        if event["event"] == "start":
            out[event["id"]] = event["t_sim_s"]
    return out


AT_S = (0.5, 3.25, 9.999, 14.0, 20.001, 33.3, 47.7, 61.0)


def _fault_file(folder: Path, name: str, at_s: tuple[float, ...] = AT_S) -> Path:
    path = folder / name
    path.write_text(
        "faults:\n"
        + "".join(
            f"  - {{kind: dropout, signal: room_temp_C, at_s: {at}, for_s: 0.001}}\n" for at in at_s
        )
    )
    return path


def bench_lockstep_timing(folder: Path) -> None:
    for step_s in (1, 7):
        journal = folder / f"lockstep_{step_s}.jsonl"
        faults = _fault_file(folder, f"lockstep_{step_s}.yaml")
        with rig_emulator_serve(
            "windhager_12kw", "--lockstep", "--faults", str(faults), "--fault-log", str(journal)
        ) as (port, _):
            client = RawClient("127.0.0.1", port)
            t = 0
            times = []
            while t < 70:
                client.write_registers(
                    100, 4, list(struct.unpack(">2H", struct.pack(">I", step_s)))
                )
                t += step_s
                times.append(float(t))
            client.close()
            time.sleep(0.2)
        starts = sorted(_starts(journal).values())
        errors = []
        for at, started in zip(AT_S, starts, strict=True):
            expected = next(x for x in times if x >= at - 1e-9)
            errors.append(round((started - expected) / step_s))
        print(
            f"fault timing, lockstep {step_s} s steps: {len(starts)} faults, start error in "
            f"steps {errors} (0 = at the first step with t_sim >= at_s: exact)"
        )


def bench_realtime_timing(folder: Path) -> None:
    for speed in (1, 20):
        # after 3 s of wall time: at start-up numba loads the kernels in the background, and
        # the first ticks may each cover several periods (printed separately below)
        warm_s = 3.0 * speed
        at_s = tuple(warm_s + a for a in (AT_S[:5] if speed == 1 else AT_S))
        journal = folder / f"realtime_{speed}.jsonl"
        faults = _fault_file(folder, f"realtime_{speed}.yaml", at_s)
        tick_sim_s = 0.1 * speed  # 10 Hz tick
        with rig_emulator_serve(
            "windhager_12kw",
            "--speed",
            str(speed),
            "--faults",
            str(faults),
            "--fault-log",
            str(journal),
        ):
            time.sleep(max(at_s) / speed + 2.0)
        starts = sorted(_starts(journal).values())
        late = [(s - at) / tick_sim_s for at, s in zip(at_s, starts, strict=True)]
        print(
            f"fault timing, real time x{speed} (10 Hz tick = {tick_sim_s:g} simulated s): "
            f"{len(starts)}/{len(at_s)} faults started, lateness in ticks max "
            f"{max(late):.2f}, mean {statistics.mean(late):.2f}, min {min(late):.2f} "
            f"(target: within one tick); each: {[round(x, 2) for x in late]}"
        )


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        bench_fault_cost()
        bench_lockstep_timing(folder)
        bench_realtime_timing(folder)
        bench_throughput(folder)
    return 0


if __name__ == "__main__":
    sys.exit(main())
