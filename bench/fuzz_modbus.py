"""Fuzz of the Modbus TCP server over real sockets (issue 11), bounded and seeded; printed,
never asserted.

``rig-emulator serve`` (real time, clean profile) runs in its own process on 127.0.0.1. The
fuzz sends batches of 1,000 frames until 200,000 frames or 60 s, whichever comes first:

- framed batches, on one long-lived connection: valid MBAP headers around random, mutated
  and truncated PDUs (any function code, any unit). Each frame must get exactly one reply,
  in order, and the right one (:func:`_answered_correctly`): the exception code the spec
  requires where the request is illegal in a way the fuzz can tell (a unit the map lacks
  0B, a function not implemented 01, a quantity or structure wrong 03), else the reply of
  its function with the spec's length and shape (a read's byte count and data for the
  quantity asked, a write's echo) or a refusal it can get (02; 03 from a write's rules;
  01 for a clock command on a real-time server);
- garbage batches, on throwaway connections: random bytes, bad MBAP headers, frames cut
  short; the client then half-closes, and the server must close the connection too (a
  connection still open 5 s later counts as left hanging).

After every batch a fresh client writes the flow setpoint and reads it back (the health
check). Printed: frames/s, correct replies, the largest health-check latency, the server's
RSS and open file descriptors before and after, and the connections left hanging.

Usage: python bench/fuzz_modbus.py [--frames N] [--seconds S] [--seed K]
"""

from __future__ import annotations

import argparse
import os
import random
import socket
import struct
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from stopping import bench_main

from hil_client.demo import rig_emulator_serve
from rig_emulator.registers import load_map

BATCH_FRAMES = 1000
UNITS = (1, 2, 3, 4, 5, 6, 7, 100)
FLOW_SETPOINT = (1, 0)  # unit, holding address of the bench PLC's flow setpoint (float32 ABCD)


def _mbap(tid: int, unit: int, pdu: bytes) -> bytes:
    return struct.pack(">HHHB", tid & 0xFFFF, 0, len(pdu) + 1, unit) + pdu


def _valid_pdu(rng: random.Random) -> bytes:
    fc = rng.choice((1, 2, 3, 4, 5, 6, 15, 16, 23, 43))
    address = rng.choice((0, 1, 2, 4, 6, rng.randrange(65536)))
    if fc in (1, 2, 3, 4):
        return struct.pack(">BHH", fc, address, rng.choice((1, 2, 4, 14, 125, 2000, 0)))
    if fc == 5:
        return struct.pack(">BHH", fc, address, rng.choice((0, 0xFF00, rng.randrange(65536))))
    if fc == 6:
        return struct.pack(">BHH", fc, address, rng.randrange(65536))
    if fc == 15:
        n = rng.randint(1, 40)
        data = bytes(rng.randrange(256) for _ in range((n + 7) // 8))
        return struct.pack(">BHHB", fc, address, n, len(data)) + data
    if fc == 16:
        n = rng.randint(1, 10)
        return struct.pack(f">BHHB{n}H", fc, address, n, 2 * n, *(rng.randrange(65536),) * n)
    if fc == 23:
        n = rng.randint(1, 4)
        return struct.pack(f">BHHHHB{n}H", fc, 0, rng.randint(1, 8), address, n, 2 * n, *[0] * n)
    return bytes([43, 14, rng.randint(0, 5), rng.randint(0, 3)])


def _fuzzed_pdu(rng: random.Random) -> bytes:
    """A random, mutated or truncated request PDU (1 to 253 bytes)."""
    kind = rng.random()
    if kind < 0.2:
        return bytes(rng.randrange(256) for _ in range(rng.randint(1, 40)))
    pdu = bytearray(_valid_pdu(rng))
    if kind < 0.5:
        for _ in range(rng.randint(1, 3)):
            pdu[rng.randrange(len(pdu))] = rng.randrange(256)
    elif kind < 0.65 and len(pdu) > 1:
        del pdu[rng.randint(1, len(pdu) - 1) :]
    elif kind < 0.75:
        pdu += bytes(rng.randrange(256) for _ in range(rng.randint(1, 20)))
    return bytes(pdu[:253])


def _garbage(rng: random.Random, frames: int) -> bytes:
    """A stream of ``frames`` pieces: frames with bad headers, frames cut short, noise."""
    out = bytearray()
    for tid in range(frames):
        frame = bytearray(_mbap(tid, rng.choice(UNITS), _fuzzed_pdu(rng)))
        kind = rng.random()
        if kind < 0.3:
            frame[rng.randrange(7)] = rng.randrange(256)  # header byte
        elif kind < 0.6:
            del frame[rng.randint(1, len(frame) - 1) :]  # cut short
        elif kind < 0.7:
            frame = bytearray(rng.randrange(256) for _ in range(rng.randint(1, 300)))
        out += frame
    return bytes(out)


#: The units of the register map (the instruments', the clock's and the plant's truth).
MAP_UNITS = {device.unit_id for device in load_map().devices}
#: The functions the server implements (everything else: 01).
FUNCTIONS = {1, 2, 3, 4, 5, 6, 15, 16, 23, 43}
#: Read quantities the spec allows (6.1-6.4), and write quantities (6.11, 6.12, 6.17).
READ_LIMITS = {1: 2000, 2: 2000, 3: 125, 4: 125}
ILLEGAL_FUNCTION, ILLEGAL_ADDRESS, ILLEGAL_VALUE, NO_SUCH_UNIT = 0x01, 0x02, 0x03, 0x0B
#: The clock's unit: a write there on a real-time server is refused with 01 whatever it is.
SIM_CONTROL = 100


def _spec_exception(unit: int, pdu: bytes) -> int | None:
    """The exception code the spec (and the README's order of checks: unit, function,
    quantity and structure, then address) requires for a request illegal in a way this
    fuzz can tell from the request alone; None for one that may be legal."""
    fc = pdu[0]
    if unit not in MAP_UNITS:
        return NO_SUCH_UNIT
    if fc not in FUNCTIONS:
        return ILLEGAL_FUNCTION
    if fc in READ_LIMITS:
        if len(pdu) != 5:
            return ILLEGAL_VALUE
        quantity = struct.unpack(">H", pdu[3:5])[0]
        return None if 1 <= quantity <= READ_LIMITS[fc] else ILLEGAL_VALUE
    if fc in (5, 6):
        if len(pdu) != 5:
            return ILLEGAL_VALUE
        if fc == 5 and pdu[3:5] not in (b"\xff\x00", b"\x00\x00"):
            return ILLEGAL_VALUE
        return None
    if fc in (15, 16):
        if len(pdu) < 6:
            return ILLEGAL_VALUE
        quantity, count = struct.unpack(">H", pdu[3:5])[0], pdu[5]
        if fc == 15:
            right = 1 <= quantity <= 1968 and count == (quantity + 7) // 8
        else:
            right = 1 <= quantity <= 123 and count == 2 * quantity
        return None if right and len(pdu) == 6 + count else ILLEGAL_VALUE
    if fc == 23:
        if len(pdu) < 10:
            return ILLEGAL_VALUE
        read_q, write_q = struct.unpack(">H", pdu[3:5])[0], struct.unpack(">H", pdu[7:9])[0]
        count = pdu[9]
        right = 1 <= read_q <= 125 and 1 <= write_q <= 121 and count == 2 * write_q
        return None if right and len(pdu) == 10 + count else ILLEGAL_VALUE
    return None  # 43: its sub-functions are not modelled here


def _refusals(unit: int, fc: int) -> set[int]:
    """The exception codes a request that may be legal can still get (no faults run):
    an address the unit lacks (02), a value its write rules refuse (03), a clock command
    on a real-time server (01)."""
    if fc in READ_LIMITS:
        return {ILLEGAL_ADDRESS}
    if fc == 43:
        return {ILLEGAL_FUNCTION, ILLEGAL_ADDRESS, ILLEGAL_VALUE}
    return {ILLEGAL_ADDRESS, ILLEGAL_VALUE} | ({ILLEGAL_FUNCTION} if unit == SIM_CONTROL else set())


def _answered_correctly(unit: int, pdu: bytes, reply: bytes) -> bool:
    """Whether ``reply`` is the spec's to ``pdu`` sent to ``unit``: the exception code it
    requires where the fuzz can tell the request is illegal; else a refusal the request
    can get, or the reply of its function with the length and shape the spec gives (a
    read's byte count and data for the quantity asked, a write's echo). Before, any reply
    with the request's function byte passed, and any of 01-04 and 0B (a stranger's
    review)."""
    fc = pdu[0]
    required = _spec_exception(unit, pdu)
    if required is not None:
        return reply == bytes([fc | 0x80, required])
    if reply[:1] == bytes([fc | 0x80]):
        return len(reply) == 2 and reply[1] in _refusals(unit, fc)
    if fc in READ_LIMITS:
        quantity = struct.unpack(">H", pdu[3:5])[0]
        size = (quantity + 7) // 8 if fc in (1, 2) else 2 * quantity
        return reply[:2] == bytes([fc, size]) and len(reply) == 2 + size
    if fc in (5, 6):
        return reply == pdu
    if fc in (15, 16):
        return reply == pdu[:5]
    if fc == 23:
        size = 2 * struct.unpack(">H", pdu[3:5])[0]
        return reply[:2] == bytes([fc, size]) and len(reply) == 2 + size
    return reply[:2] == bytes([43, 14]) and len(reply) >= 7  # device identification


class _Reader:
    def __init__(self, sock: socket.socket) -> None:
        self.sock, self.data = sock, b""

    def reply(self) -> tuple[int, bytes] | None:
        while len(self.data) < 6 or len(self.data) < 6 + struct.unpack(">H", self.data[4:6])[0]:
            try:
                chunk = self.sock.recv(65536)
            except (TimeoutError, ConnectionResetError):
                return None
            if not chunk:
                return None
            self.data += chunk
        tid, _, length = struct.unpack(">HHH", self.data[:6])
        pdu = self.data[7 : 6 + length]
        self.data = self.data[6 + length :]
        return tid, pdu


def _connect(port: int) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", port), timeout=10)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return sock


def _framed_batch(port: int, sock: socket.socket | None, rng: random.Random, first_tid: int):
    """Send one framed batch; returns (socket to reuse, frames, correct replies)."""
    if sock is None:
        sock = _connect(port)
    requests = [
        (first_tid + i, rng.choice(UNITS) if rng.random() < 0.8 else rng.randrange(256))
        for i in range(BATCH_FRAMES)
    ]
    pdus = [_fuzzed_pdu(rng) for _ in requests]
    stream = b"".join(_mbap(t, u, p) for (t, u), p in zip(requests, pdus, strict=True))
    sender = threading.Thread(target=sock.sendall, args=(stream,), daemon=True)
    sender.start()
    reader = _Reader(sock)
    correct = 0
    for (tid, unit), pdu in zip(requests, pdus, strict=True):
        got = reader.reply()
        if got is None:
            sock.close()
            return None, correct
        reply_tid, reply = got
        if reply_tid == tid & 0xFFFF and _answered_correctly(unit, pdu, reply):
            correct += 1
    sender.join(timeout=10)
    return sock, correct


def _garbage_batch(port: int, rng: random.Random) -> int:
    """Garbage on 10 throwaway connections, each half-closed; returns how many the server
    left open 5 s later."""
    hanging = 0
    for _ in range(10):
        sock = _connect(port)
        try:
            sock.sendall(_garbage(rng, BATCH_FRAMES // 10))
            sock.shutdown(socket.SHUT_WR)
        except OSError:  # closed by the server already (a bad header)
            sock.close()
            continue
        sock.settimeout(5)
        try:
            while sock.recv(65536):
                pass
        except ConnectionResetError:
            pass
        except TimeoutError:
            hanging += 1
        sock.close()
    return hanging


def _health(port: int, rng: random.Random) -> tuple[bool, float]:
    """A fresh client writes the flow setpoint and reads it back: (correct, latency [s])."""
    value = float(rng.randint(100, 1500))
    unit, address = FLOW_SETPOINT
    words = struct.unpack(">HH", struct.pack(">f", value))
    start = time.perf_counter()
    with _connect(port) as sock:
        sock.sendall(
            _mbap(1, unit, struct.pack(">BHHB2H", 16, address, 2, 4, *words))
            + _mbap(2, unit, struct.pack(">BHH", 3, address, 2))
        )
        reader = _Reader(sock)
        first, second = reader.reply(), reader.reply()
    latency = time.perf_counter() - start
    ok = (
        first is not None
        and first[1][0] == 16
        and second is not None
        and second[1][:2] == b"\x03\x04"
        and struct.unpack(">f", second[1][2:6])[0] == value
    )
    return ok, latency


def _status(pid: int) -> tuple[float, int]:
    """RSS [MiB] and open file descriptors of process ``pid``."""
    rss_kib = 0
    with open(f"/proc/{pid}/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                rss_kib = int(line.split()[1])
    return rss_kib / 1024.0, len(os.listdir(f"/proc/{pid}/fd"))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200_000)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    rng = random.Random(args.seed)
    with rig_emulator_serve("windhager_12kw", "--speed", "1") as (port, proc):
        time.sleep(1.0)  # let the first ticks (numba's kernels) settle
        ok, _ = _health(port, rng)
        rss_before, fds_before = _status(proc.pid)
        frames = correct = framed = hanging = batches = health_failures = 0
        worst_health_s = 0.0
        sock = None
        start = time.perf_counter()
        while frames < args.frames and time.perf_counter() - start < args.seconds:
            if batches % 5 == 4:
                hanging += _garbage_batch(port, rng)
            else:
                sock, good = _framed_batch(port, sock, rng, frames)
                correct += good
                framed += BATCH_FRAMES
            frames += BATCH_FRAMES
            batches += 1
            healthy, latency = _health(port, rng)
            health_failures += not healthy
            worst_health_s = max(worst_health_s, latency)
        wall = time.perf_counter() - start
        if sock is not None:
            sock.close()
        time.sleep(0.5)  # let the server see the last closes
        rss_after, fds_after = _status(proc.pid)
        alive = proc.poll() is None
    print(
        f"fuzz: {frames} frames in {wall:.1f} s ({frames / wall:.0f} frames/s, seed "
        f"{args.seed}); framed {framed}: {correct} correct replies ({correct / max(framed, 1):.2%})"
    )
    print(
        f"fuzz: {batches} health checks, {health_failures} failed (first before fuzzing: "
        f"{'ok' if ok else 'FAILED'}), largest latency {worst_health_s * 1000:.1f} ms"
    )
    print(
        f"fuzz: server RSS {rss_before:.1f} -> {rss_after:.1f} MiB, open fds {fds_before} -> "
        f"{fds_after}, connections left hanging {hanging}, server "
        f"{'alive' if alive else 'DEAD'}"
    )
    return 0


if __name__ == "__main__":
    bench_main(main)
