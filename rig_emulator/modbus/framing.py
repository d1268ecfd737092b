"""Modbus TCP framing: the MBAP header of the Messaging on TCP/IP Implementation Guide V1.0b.

An MBAP header is 7 bytes: transaction identifier (2), protocol identifier (2, 0 = MODBUS),
length (2: the number of following bytes, unit identifier and PDU) and unit identifier (1).
A PDU is at most 253 bytes (Application Protocol Specification V1.1b3, 4.1: the size limit
inherited from the serial line's 256-byte ADU; quoted from memory, the text was not found
with the search tool, but the 260-byte TCP ADU is what every implementation found uses), so
a TCP ADU is at most 260 bytes and the length field at most 254.

The parser takes a byte stream cut anywhere (one byte at a time, many frames in one TCP
segment, segments of any size) and returns every complete frame in order. A frame whose
header is wrong but whose length can be trusted (protocol identifier other than 0; a length
of 0 or 1, which leaves no function code) is discarded, and the frames after it are
answered: "If an error is detected on the MBAP, the indication is discarded" (the guide's
4.4.2.2 and its Figure 16: "The Protocol Identifier field has to be checked: If it is
different from MODBUS protocol type, the indication is simply discarded"). A length above
254 ends the stream: the frame is larger than any Modbus TCP ADU, so its length cannot be
trusted to find where the next frame starts, and the caller answers the frames before it
and closes the connection with one log line. Six bytes of header decide either way.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

MBAP_HEADER = struct.Struct(">HHHB")  # transaction id, protocol id, length, unit id
MBAP_HEADER_BYTES = 7
MAX_PDU_BYTES = 253
MAX_ADU_BYTES = MBAP_HEADER_BYTES + MAX_PDU_BYTES  # 260
MIN_LENGTH_FIELD = 2  # unit identifier and a function code
MAX_LENGTH_FIELD = 1 + MAX_PDU_BYTES  # 254
MODBUS_PROTOCOL_ID = 0


class MbapFrame(NamedTuple):
    """One request as it arrived: its transaction id, unit id and PDU (function code first)."""

    transaction_id: int
    unit_id: int
    pdu: bytes


class Split(NamedTuple):
    """What :func:`split_frames` took from the front of a buffer."""

    frames: list[MbapFrame]  # the complete requests, in order
    discarded: list[str]  # why each frame with a wrong header was discarded, in order
    error: str | None  # why the stream cannot go on (a length above 254), or None


_LENGTH_PREFIX = struct.Struct(">HHH")  # transaction id, protocol id, length
_LENGTH_PREFIX_BYTES = 6


def frame_ready(buffer: bytes | bytearray) -> bool:
    """Whether ``buffer`` begins with a whole frame, or a header that ends the stream."""
    if len(buffer) < _LENGTH_PREFIX_BYTES:
        return False
    length = _LENGTH_PREFIX.unpack_from(buffer)[2]
    return length > MAX_LENGTH_FIELD or _LENGTH_PREFIX_BYTES + length <= len(buffer)


def split_frames(buffer: bytearray, most: int | None = None) -> Split:
    """Remove every complete frame (at ``most`` this many, discarded ones included) from
    the front of ``buffer``, the requests and the discarded ones (see the module
    docstring), and stop at a length above 254.

    What is left in ``buffer`` is the start of a frame not yet complete (less than 260
    bytes), or, after a length above 254, the bytes from that header on (the caller answers
    the frames before it, then closes the connection)."""
    frames: list[MbapFrame] = []
    discarded: list[str] = []
    start = 0
    end = len(buffer)
    error: str | None = None
    while end - start >= _LENGTH_PREFIX_BYTES and (
        most is None or len(frames) + len(discarded) < most
    ):
        tid, protocol, length = _LENGTH_PREFIX.unpack_from(buffer, start)
        if length > MAX_LENGTH_FIELD:
            error = (
                f"length field {length} exceeds {MAX_LENGTH_FIELD} "
                f"(a Modbus TCP ADU is at most {MAX_ADU_BYTES} bytes)"
            )
            break
        frame_end = start + _LENGTH_PREFIX_BYTES + length
        if frame_end > end:
            break
        if protocol != MODBUS_PROTOCOL_ID:
            discarded.append(f"transaction {tid}: protocol identifier {protocol} (MODBUS is 0)")
        elif length < MIN_LENGTH_FIELD:
            discarded.append(f"transaction {tid}: length field {length} leaves no function code")
        else:
            unit = buffer[start + _LENGTH_PREFIX_BYTES]
            frames.append(
                MbapFrame(tid, unit, bytes(buffer[start + MBAP_HEADER_BYTES : frame_end]))
            )
        start = frame_end
    del buffer[:start]
    return Split(frames, discarded, error)


def frame_bytes(transaction_id: int, unit_id: int, pdu: bytes) -> bytes:
    """The ADU of a response: MBAP header (protocol id 0) and ``pdu``."""
    return MBAP_HEADER.pack(transaction_id, MODBUS_PROTOCOL_ID, len(pdu) + 1, unit_id) + pdu
