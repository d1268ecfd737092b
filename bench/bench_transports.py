"""Benchmarks of the transports (issue 15), printed, never asserted.

1. Modbus/TCP Security: FC4 requests per second (14 registers of the bench PLC, one
   request at a time per connection) over TLS against plain TCP on the same server
   (``serve --tls-* --tcp-port``), with 1 and 8 connections, measured alternately
   (median of rounds), reported as the ratio TLS / TCP.
2. Modbus RTU on a pty: the same FC4 request back to back for a few seconds at 19,200 and
   115,200 baud; achieved transactions per second against the wire's limit
   1 / (request + reply characters x 11 bits / baud + 2 x t3.5) (target >= 90 %).

Servers run as ``rig-emulator serve`` subprocesses (lockstep: no tick competes), load
generators in another process (the machine has 2 cores).
"""

from __future__ import annotations

import asyncio
import multiprocessing as mp
import os
import select
import socket
import ssl
import statistics
import struct
import subprocess
import sys
import tempfile
import time
import tty
from contextlib import contextmanager
from pathlib import Path

from stopping import bench_main, quiet_child, result_of

from hil_client.wait_for_port import free_port, wait_for_port
from rig_emulator.certs import make_lab_certificates
from rig_emulator.modbus.rtu_wire import frame, transaction_s

PLC_BLOCK = (1, 0, 14)
ROUND_S = 2.0
ROUNDS = 3
RTU_SECONDS = 4.0
BOILER = ("--boiler", "windhager_12kw")
ROOT = Path(__file__).resolve().parents[1]


def _fc4() -> bytes:
    _, address, count = PLC_BLOCK
    return struct.pack(">BHH", 4, address, count)


@contextmanager
def _serve(*extra: str):
    """``rig-emulator serve --lockstep`` with ``extra``; yields the process (stdout piped)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "rig_emulator.cli", "serve", *BOILER, "--lockstep", *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    try:
        yield proc
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()


# ---------------------------------------------------------------------- TLS against TCP
async def _hammer(port: int, connections: int, seconds: float, certs: str | None) -> int:
    ctx = None
    if certs is not None:
        ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
        ctx.load_verify_locations(cafile=f"{certs}/ca.pem")
        ctx.load_cert_chain(f"{certs}/observer.pem", f"{certs}/observer.key")
    unit = PLC_BLOCK[0]
    pdu = _fc4()
    done = 0
    stop = time.monotonic() + seconds

    async def one() -> None:
        nonlocal done
        reader, writer = await asyncio.open_connection(
            "127.0.0.1", port, ssl=ctx, server_hostname="127.0.0.1" if ctx else None
        )
        raw = writer.get_extra_info("socket")
        raw.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        tid = 0
        while time.monotonic() < stop:
            tid = (tid + 1) & 0xFFFF
            writer.write(struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu)
            header = await reader.readexactly(7)
            await reader.readexactly(struct.unpack(">HHHB", header)[2] - 1)
            done += 1
        writer.close()

    await asyncio.gather(*(one() for _ in range(connections)))
    return done


def _hammer_process(port: int, connections: int, certs: str | None, out) -> None:
    out.put(asyncio.run(_hammer(port, connections, ROUND_S, certs)))


def _rps(port: int, connections: int, certs: str | None) -> float:
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(
        target=quiet_child, args=(_hammer_process, port, connections, certs, queue), daemon=True
    )
    proc.start()
    done = result_of(proc, queue)
    proc.join()
    return done / ROUND_S


def bench_tls() -> None:
    with tempfile.TemporaryDirectory() as certs:
        make_lab_certificates(Path(certs))
        tls_port, tcp_port = free_port(), free_port()
        tls_args = [f"--tls-{k}" for k in ("cert", "key", "ca")]
        files = [f"{certs}/server.pem", f"{certs}/server.key", f"{certs}/ca.pem"]
        options = [x for pair in zip(tls_args, files, strict=True) for x in pair]
        with _serve("--port", str(tls_port), "--tcp-port", str(tcp_port), *options):
            for port in (tls_port, tcp_port):
                if not wait_for_port("127.0.0.1", port, 60.0):
                    raise RuntimeError(f"no server on port {port}")
            print("1. Modbus/TCP Security: FC4 of 14 registers, one request at a time")
            for connections in (1, 8):
                tls, tcp = [], []
                for _ in range(ROUNDS):  # alternate, so both see the same machine load
                    tls.append(_rps(tls_port, connections, certs))
                    tcp.append(_rps(tcp_port, connections, None))
                a, b = statistics.median(tls), statistics.median(tcp)
                print(
                    f"   {connections} connection(s): TLS {a:8.0f} req/s, plain TCP {b:8.0f} "
                    f"req/s, ratio TLS/TCP {a / b:.2f}"
                )


# ---------------------------------------------------------------------- RTU
def _rtu_rate(path: str, seconds: float) -> tuple[int, float]:
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    request = frame(PLC_BLOCK[0], _fc4())
    reply_bytes = 5 + 2 * PLC_BLOCK[2]
    done = 0
    start = time.monotonic()
    try:
        while time.monotonic() - start < seconds:
            os.write(fd, request)
            got = b""
            while len(got) < reply_bytes:
                if not select.select([fd], [], [], 2.0)[0]:
                    raise RuntimeError(f"no reply on {path}")
                got += os.read(fd, reply_bytes - len(got))
            done += 1
    finally:
        os.close(fd)
    return done, time.monotonic() - start


def bench_rtu() -> None:
    print("2. Modbus RTU on a pty: FC4 of 14 registers back to back (request 8, reply 33 bytes)")
    for baud in (19200, 115200):
        with _serve("--port", str(free_port()), "--serial", "pty", "--baud", str(baud)) as proc:
            line = proc.stdout.readline() if proc.stdout else ""
            if not line.startswith("serial: "):
                raise RuntimeError(f"serve printed {line!r}")
            path = line.split(": ", 1)[1].strip()
            _rtu_rate(path, 0.5)  # warm-up: the first requests load the kernels
            done, elapsed = _rtu_rate(path, RTU_SECONDS)
        achieved = done / elapsed
        limit = 1.0 / transaction_s(8, 5 + 2 * PLC_BLOCK[2], baud)
        print(
            f"   {baud:6d} baud: {achieved:6.1f} transactions/s, wire limit {limit:6.1f}/s: "
            f"{100 * achieved / limit:5.1f} % (target >= 90 %)"
        )


def main() -> int:
    bench_tls()
    bench_rtu()
    return 0


if __name__ == "__main__":
    bench_main(main)
