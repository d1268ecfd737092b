"""Modbus RTU on the wire: CRC-16, frames and timing (Modbus over Serial Line V1.02).

- A frame is ``address, PDU, CRC`` with the CRC-16 (polynomial 0xA001 reflected, initial
  0xFFFF) sent low byte first (section 2.5.1.2).
- A character is 11 bits: start, 8 data, parity, stop; without parity a second stop bit
  takes the parity bit's place, so it stays 11 bits (section 2.5.1).
- Frames are delimited by a silence of 3.5 character times; above 19,200 baud the
  specification fixes it at 1.75 ms (section 2.5.1.1, remark on baud rates above 19,200).
- Broadcast: unit (slave address) 0; only writes, and nobody replies (section 2.1).

A transaction on a line is therefore at least: request characters, 3.5 characters of
silence, reply characters, 3.5 characters of silence before the next request.
"""

from __future__ import annotations

BITS_PER_CHARACTER = 11
FIXED_SILENCE_S = 0.00175  # t3.5 above 19,200 baud
FIXED_SILENCE_ABOVE_BAUD = 19200
PARITIES = ("E", "N", "O")
BROADCAST_UNIT = 0


def _table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
        table.append(crc)
    return table


_CRC_TABLE = _table()


def crc16(data: bytes) -> int:
    """The Modbus RTU CRC-16 of ``data``."""
    crc = 0xFFFF
    for byte in data:
        crc = (crc >> 8) ^ _CRC_TABLE[(crc ^ byte) & 0xFF]
    return crc


def frame(unit_id: int, pdu: bytes) -> bytes:
    """An RTU frame: address, PDU, CRC (low byte first)."""
    body = bytes([unit_id]) + pdu
    return body + crc16(body).to_bytes(2, "little")


def unframe(data: bytes) -> tuple[int, bytes] | None:
    """(unit, PDU) of an RTU frame; None if too short or the CRC is wrong."""
    if len(data) < 4 or crc16(data[:-2]) != int.from_bytes(data[-2:], "little"):
        return None
    return data[0], data[1:-2]


def character_s(baud: int) -> float:
    """On-wire time of one character [s]."""
    return BITS_PER_CHARACTER / baud


def silence_s(baud: int) -> float:
    """The 3.5-character inter-frame silence t3.5 [s]."""
    if baud > FIXED_SILENCE_ABOVE_BAUD:
        return FIXED_SILENCE_S
    return 3.5 * character_s(baud)


def transaction_s(request_bytes: int, reply_bytes: int, baud: int) -> float:
    """The least time a request-reply transaction occupies a line [s]: both frames, each
    followed by its silence."""
    return (request_bytes + reply_bytes) * character_s(baud) + 2.0 * silence_s(baud)


def reply_length(frame_head: bytes) -> int | None:
    """The whole length of an RTU reply frame (address to CRC) from its first bytes
    (address, function, and the byte count where there is one); None if more are needed."""
    if len(frame_head) < 2:
        return None
    function = frame_head[1]
    if function & 0x80:
        return 5
    if function in (1, 2, 3, 4, 23):
        return None if len(frame_head) < 3 else 5 + frame_head[2]
    if function in (5, 6, 15, 16):
        return 8
    return None
