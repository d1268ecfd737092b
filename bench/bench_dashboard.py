"""``make bench``: what the live dashboard costs the real-time server (issue 16).

One ``rig-emulator serve --speed 60 --http`` in its own process, measured twice for
:data:`WINDOW_S` of wall time each: alone, then with the page fetched and
:data:`STREAMS` server-sent-event streams open (as ten browsers would hold them). Printed:
the server's CPU time per tick (from /proc) in both, the difference as a share of the tick
budget (the tick period; target < 5 %), and the tick lateness p99 of both windows (target:
unchanged within noise). Figures only, never asserted: the machine is shared.
"""

from __future__ import annotations

import json
import os
import socket
import threading
import time
import urllib.request

from stopping import bench_main

from hil_client.demo import rig_emulator_serve
from hil_client.wait_for_port import free_port, wait_for_port

WINDOW_S = 20.0
STREAMS = 10
TICK_HZ = 10.0


def _cpu_s(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as fh:
        fields = fh.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _p99(http: int) -> float:
    with urllib.request.urlopen(f"http://127.0.0.1:{http}/api/state?window=0", timeout=10) as r:
        return json.loads(r.read())["clock"]["tick_lateness_ms"]["p99_recent"]


def _window(pid: int, http: int) -> tuple[float, float]:
    """(CPU seconds per tick, lateness p99 [ms]) over one window."""
    cpu0, t0 = _cpu_s(pid), time.monotonic()
    time.sleep(WINDOW_S)
    cpu1, t1 = _cpu_s(pid), time.monotonic()
    return (cpu1 - cpu0) / ((t1 - t0) * TICK_HZ), _p99(http)


def _reader(http: int, stop: threading.Event, events: list[int], i: int) -> None:
    with socket.create_connection(("127.0.0.1", http), timeout=10) as s:
        s.sendall(b"GET /api/stream HTTP/1.1\r\nHost: bench\r\n\r\n")
        while not stop.is_set():
            data = s.recv(65536)
            if not data:
                break
            events[i] += data.count(b"\n\ndata: ") + data.startswith(b"data: ")


def main() -> None:
    http = free_port()
    options = ("--speed", "60", "--tick-hz", f"{TICK_HZ:g}", "--http", str(http))
    with rig_emulator_serve("windhager_12kw", *options) as (_, server):
        wait_for_port("127.0.0.1", http, 30.0)
        time.sleep(3.0)  # kernels compiled, clock settled
        alone_cpu, alone_p99 = _window(server.pid, http)
        urllib.request.urlopen(f"http://127.0.0.1:{http}/", timeout=10).read()
        stop, events = threading.Event(), [0] * STREAMS
        readers = [
            threading.Thread(target=_reader, args=(http, stop, events, i), daemon=True)
            for i in range(STREAMS)
        ]
        for r in readers:
            r.start()
        busy_cpu, busy_p99 = _window(server.pid, http)
        stop.set()
    budget = 1.0 / TICK_HZ
    print(
        f"dashboard cost ({STREAMS} streams, {WINDOW_S:.0f} s windows, tick {budget * 1e3:.0f} ms):"
    )
    print(
        f"  server CPU per tick: alone {alone_cpu * 1e3:.2f} ms, with streams "
        f"{busy_cpu * 1e3:.2f} ms; difference {100 * (busy_cpu - alone_cpu) / budget:.2f} % "
        "of the tick budget (target < 5 %)"
    )
    print(f"  tick lateness p99: alone {alone_p99:.2f} ms, with streams {busy_p99:.2f} ms")
    print(f"  events received per stream: min {min(events)}, max {max(events)}")


if __name__ == "__main__":
    bench_main(main)
