"""RTU wire arithmetic against references the project did not write: the CRC against
pymodbus's RTU framer and the textbook frame of the Modbus over Serial Line guide, the
timing against the figures of the specification."""

from __future__ import annotations

import random

import pytest
from pymodbus.framer.rtu import FramerRTU

from rig_emulator.modbus.rtu_wire import (
    character_s,
    crc16,
    frame,
    reply_length,
    silence_s,
    transaction_s,
    unframe,
)


def test_crc_of_the_textbook_read_request():
    # read 10 holding registers of unit 1 from 0: the frame ends in C5 CD (CRC low byte
    # first), the example most Modbus RTU references print
    assert frame(1, bytes.fromhex("030000000A")) == bytes.fromhex("01030000000AC5CD")


def test_frames_equal_pymodbus_framer_for_random_pdus():
    rng = random.Random(7)
    for _ in range(200):
        unit = rng.randrange(0, 248)
        pdu = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 253)))
        assert frame(unit, pdu) == FramerRTU.encode(None, pdu, unit, 0)  # type: ignore[arg-type]


def test_unframe_rejects_any_single_bit_error():
    good = frame(5, bytes.fromhex("0400000002"))
    assert unframe(good) == (5, bytes.fromhex("0400000002"))
    for i in range(len(good) * 8):
        bad = bytearray(good)
        bad[i // 8] ^= 1 << (i % 8)
        assert unframe(bytes(bad)) is None, i
    assert unframe(good[:3]) is None


def test_crc_of_empty_is_the_initial_value():
    assert crc16(b"") == 0xFFFF


@pytest.mark.parametrize(
    ("baud", "char_us", "silence_us"),
    [
        # 11 bits per character; t3.5 = 3.5 characters up to 19,200 baud, 1.75 ms above
        # (Modbus over Serial Line V1.02, sections 2.5.1 and 2.5.1.1)
        (9600, 1145.8, 4010.4),
        (19200, 572.9, 2005.2),
        (115200, 95.5, 1750.0),
    ],
)
def test_timing_figures_of_the_specification(baud, char_us, silence_us):
    assert character_s(baud) * 1e6 == pytest.approx(char_us, abs=0.1)
    assert silence_s(baud) * 1e6 == pytest.approx(silence_us, abs=0.1)


def test_transaction_is_both_frames_and_two_silences():
    # FC4 of 14 registers: request 8 bytes, reply 5 + 28 bytes
    expected = (8 + 33) * 11 / 19200 + 2 * 3.5 * 11 / 19200
    assert transaction_s(8, 33, 19200) == pytest.approx(expected, rel=1e-12)


def test_reply_length_from_the_head():
    assert reply_length(b"\x01") is None
    assert reply_length(b"\x01\x84") == 5  # exception
    assert reply_length(b"\x01\x04") is None  # byte count still missing
    assert reply_length(b"\x01\x04\x1c") == 5 + 28
    assert reply_length(b"\x01\x10") == 8
    assert reply_length(b"\x01\x05") == 8
