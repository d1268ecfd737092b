"""Modbus TCP framing: the MBAP header of the Messaging on TCP/IP Implementation Guide V1.0b.

An MBAP header is 7 bytes: transaction identifier (2), protocol identifier (2, 0 = MODBUS),
length (2: the number of following bytes, unit identifier and PDU) and unit identifier (1).
A PDU is at most 253 bytes (Application Protocol Specification V1.1b3, 4.1: the size limit
inherited from the serial line's 256-byte ADU; quoted from memory, the text was not found
with the search tool, but the 260-byte TCP ADU is what every implementation found uses), so
a TCP ADU is at most 260 bytes and the length field 2 to 254 (the guide's 3.1.3: "a byte
count of the following fields, including the Unit Identifier and data fields"; 1 leaves no
function code, 0 not even the unit identifier).

The parser takes a byte stream cut anywhere (one byte at a time, many frames in one TCP
segment, segments of any size) and returns every complete frame in order. A frame with a
length of 2 to 254 but a protocol identifier other than 0 is discarded, and the frames
after it are answered: "If an error is detected on the MBAP, the indication is discarded"
(the guide's 4.4.2.2 and its Figure 16: "The Protocol Identifier field has to be checked:
If it is different from MODBUS protocol type, the indication is simply discarded").

The stream ends (the caller answers the frames before the header and closes the connection
with one log line saying why) where the header shows it is out of step, so that no later
frame can be found in it: a length above 254 (a frame larger than any Modbus TCP ADU), a
length below 2 (impossible in a frame: a client whose length left out a byte, say the unit
identifier, puts every later header a byte off, and each 6 bytes then read as a "frame" of
length 0 that discarding one by one never resynchronised, so its well-formed requests went
unanswered until the idle timeout: a stranger's probe), or
:data:`MAX_DISCARDED_IN_ROW` frames in a row with a wrong protocol identifier and no valid
frame between them. Six bytes of header decide a length; a protocol identifier, the whole
frame its length delimits.
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
#: Frames with a wrong protocol identifier in a row, no valid frame between them, that end
#: the stream as out of step. A stream out of step reads its headers from inside frames,
#: and what it finds there is seldom a valid header: a length outside 2..254 ends it at
#: once; a length inside with a protocol identifier other than 0 swallows up to 260 bytes of
#: well-formed requests, unanswered while the client waits. A client in step sends such a
#: frame now and then at most (a conformance test of the guide's 4.4.2.2; this project's
#: tests send two in a row), so three in a row end the stream within 780 bytes; a larger
#: bound would only keep an out-of-step client waiting longer.
MAX_DISCARDED_IN_ROW = 3


class MbapFrame(NamedTuple):
    """One request as it arrived: its transaction id, unit id and PDU (function code first)."""

    transaction_id: int
    unit_id: int
    pdu: bytes


class Split(NamedTuple):
    """What :func:`split_frames` took from the front of a buffer."""

    frames: list[MbapFrame]  # the complete requests, in order
    #: why each frame with a wrong protocol identifier was discarded, in order (those of
    #: the run that ended the stream left out: ``error`` names them)
    discarded: list[str]
    error: str | None  # why the stream cannot go on (out of step), or None
    #: frames with a wrong protocol identifier at the end of what was taken, in a row (the
    #: caller passes it to the next :func:`split_frames` of the same stream)
    in_row: int


_LENGTH_PREFIX = struct.Struct(">HHH")  # transaction id, protocol id, length
_LENGTH_PREFIX_BYTES = 6


def frame_ready(buffer: bytes | bytearray) -> bool:
    """Whether ``buffer`` begins with a whole frame, or a header that ends the stream."""
    if len(buffer) < _LENGTH_PREFIX_BYTES:
        return False
    length = _LENGTH_PREFIX.unpack_from(buffer)[2]
    return _length_error(length) is not None or _LENGTH_PREFIX_BYTES + length <= len(buffer)


def _length_error(length: int) -> str | None:
    """Why a length field shows the stream out of step (see the module docstring), or None."""
    if length > MAX_LENGTH_FIELD:
        return (
            f"length field {length} exceeds {MAX_LENGTH_FIELD} "
            f"(a Modbus TCP ADU is at most {MAX_ADU_BYTES} bytes)"
        )
    if length < MIN_LENGTH_FIELD:
        return (
            f"length field {length}, below {MIN_LENGTH_FIELD}: it counts the unit identifier "
            "and the PDU, so no frame has it; the stream is out of step"
        )
    return None


def split_frames(buffer: bytearray, most: int | None = None, in_row: int = 0) -> Split:
    """Remove every complete frame (at ``most`` this many, discarded ones included) from
    the front of ``buffer``, the requests and the discarded ones (see the module
    docstring), and stop where the stream is out of step. ``in_row``: the frames with a
    wrong protocol identifier the last call of this stream ended with (its ``in_row``).

    What is left in ``buffer`` is the start of a frame not yet complete (less than 260
    bytes), or, out of step, the bytes from the header that showed it on (the caller
    answers the frames before it, then closes the connection)."""
    frames: list[MbapFrame] = []
    discarded: list[str] = []
    start = 0
    end = len(buffer)
    error: str | None = None
    while end - start >= _LENGTH_PREFIX_BYTES and (
        most is None or len(frames) + len(discarded) < most
    ):
        tid, protocol, length = _LENGTH_PREFIX.unpack_from(buffer, start)
        error = _length_error(length)
        if error is not None:
            error = f"transaction {tid}: {error}"
            break
        frame_end = start + _LENGTH_PREFIX_BYTES + length
        if frame_end > end:
            break
        if protocol != MODBUS_PROTOCOL_ID:
            why = f"transaction {tid}: protocol identifier {protocol} (MODBUS is 0)"
            in_row += 1
            if in_row >= MAX_DISCARDED_IN_ROW:
                # the run's frames of this call are named here, not as discarded ones
                del discarded[max(len(discarded) - (in_row - 1), 0) :]
                error = (
                    f"{in_row} frames in a row with a wrong protocol identifier and no valid "
                    f"frame between them, the last {why}; the stream is out of step"
                )
                break
            discarded.append(why)
        else:
            in_row = 0
            unit = buffer[start + _LENGTH_PREFIX_BYTES]
            frames.append(
                MbapFrame(tid, unit, bytes(buffer[start + MBAP_HEADER_BYTES : frame_end]))
            )
        start = frame_end
    del buffer[:start]
    return Split(frames, discarded, error, in_row)


def frame_bytes(transaction_id: int, unit_id: int, pdu: bytes) -> bytes:
    """The ADU of a response: MBAP header (protocol id 0) and ``pdu``."""
    return MBAP_HEADER.pack(transaction_id, MODBUS_PROTOCOL_ID, len(pdu) + 1, unit_id) + pdu
