"""Modbus TCP framing: the MBAP header of the Messaging on TCP/IP Implementation Guide V1.0b.

An MBAP header is 7 bytes: transaction identifier (2), protocol identifier (2, 0 = MODBUS),
length (2: the number of following bytes, unit identifier and PDU) and unit identifier (1).
A PDU is at most 253 bytes (Application Protocol Specification V1.1b3, 4.1: the size limit
inherited from the serial line's 256-byte ADU; quoted from memory, the text was not found
with the search tool, but the 260-byte TCP ADU is what every implementation found uses), so
a TCP ADU is at most 260 bytes and the length field at most 254.

The parser takes a byte stream cut anywhere (one byte at a time, many frames in one TCP
segment, segments of any size) and returns every complete frame in order. A header it cannot
trust (protocol identifier other than 0, a length below 2 or above 254) ends the stream:
without a trustworthy length there is no way to find where the next frame starts, so the
caller answers the frames before it and closes the connection with one log line.
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


def split_frames(buffer: bytearray) -> tuple[list[MbapFrame], str | None]:
    """Remove every complete frame from the front of ``buffer``; return them in order, and
    why the stream cannot go on (a header that cannot be trusted), or None.

    What is left in ``buffer`` is the start of a frame not yet complete (less than 260
    bytes), or, after a bad header, the bytes from that header on (the caller answers the
    frames before it, then closes the connection)."""
    frames: list[MbapFrame] = []
    start = 0
    end = len(buffer)
    error: str | None = None
    while end - start >= MBAP_HEADER_BYTES:
        tid, protocol, length, unit = MBAP_HEADER.unpack_from(buffer, start)
        if protocol != MODBUS_PROTOCOL_ID:
            error = f"protocol identifier {protocol} (MODBUS is 0)"
        elif length < MIN_LENGTH_FIELD:
            error = f"length field {length} leaves no function code"
        elif length > MAX_LENGTH_FIELD:
            error = (
                f"length field {length} exceeds {MAX_LENGTH_FIELD} "
                f"(a Modbus TCP ADU is at most {MAX_ADU_BYTES} bytes)"
            )
        if error is not None:
            break
        frame_end = start + 6 + length
        if frame_end > end:
            break
        frames.append(MbapFrame(tid, unit, bytes(buffer[start + MBAP_HEADER_BYTES : frame_end])))
        start = frame_end
    del buffer[:start]
    return frames, error


def frame_bytes(transaction_id: int, unit_id: int, pdu: bytes) -> bytes:
    """The ADU of a response: MBAP header (protocol id 0) and ``pdu``."""
    return MBAP_HEADER.pack(transaction_id, MODBUS_PROTOCOL_ID, len(pdu) + 1, unit_id) + pdu
