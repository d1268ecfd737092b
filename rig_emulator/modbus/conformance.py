"""Modbus request processing written from the MODBUS Application Protocol Specification V1.1b3.

Every function follows the spec's state diagram (section 6): function code supported? (else
exception 01) -> quantity and structure of the request valid? (else 03) -> starting address
and address + quantity valid? (else 02) -> the operation itself (its own refusal: 02, 03 or
04). Every check is made before anything is written, so a refused request changes nothing.

Exception codes (section 7): 01 ILLEGAL FUNCTION, 02 ILLEGAL DATA ADDRESS, 03 ILLEGAL DATA
VALUE ("a fault in the structure of the remainder of a complex request, such as that the
implied length is incorrect"), 04 SERVER DEVICE FAILURE, 0B GATEWAY TARGET DEVICE FAILED TO
RESPOND (answered for unit identifiers no instrument of the bench has). A unit whose device
fails (a fault's 04: "an unrecoverable error occurred while the server was attempting to
perform the requested action") fails at the operation, after the checks
(:func:`process_failing`).

Implemented: 01, 02, 03, 04 (reads), 05, 06, 15, 16 (writes), 23 (read/write multiple
registers) and 43/14 (read device identification, basic objects). Everything else gets 01.
"""

from __future__ import annotations

import struct
from collections.abc import Awaitable, Callable, Mapping
from dataclasses import dataclass
from typing import Protocol

ILLEGAL_FUNCTION = 0x01
ILLEGAL_DATA_ADDRESS = 0x02
ILLEGAL_DATA_VALUE = 0x03
SERVER_DEVICE_FAILURE = 0x04
GATEWAY_TARGET_FAILED = 0x0B

#: largest quantity per read function (spec 6.1-6.4: 0x7D0 bits, 0x7D registers)
READ_LIMITS = {1: 0x7D0, 2: 0x7D0, 3: 0x7D, 4: 0x7D}
MAX_WRITE_COILS = 0x7B0  # 6.11: 1 to 1968
MAX_WRITE_REGISTERS = 0x7B  # 6.12: 1 to 123
MAX_RW_READ = 0x7D  # 6.17: read 1 to 125
MAX_RW_WRITE = 0x79  # 6.17: write 1 to 121
ADDRESS_SPACE = 0x10000
COIL_ON, COIL_OFF = 0xFF00, 0x0000
ENCAPSULATED_INTERFACE = 0x2B  # 6.19: FC 43, its MEI type in the next byte
MEI_READ_DEVICE_ID = 0x0E


class Datastore(Protocol):
    """What the processing needs of a datastore (pymodbus's ``SimCore`` is one): values
    or an exception code (an ``int``), nothing written when it refuses."""

    async def async_getValues(
        self, device_id: int, func_code: int, address: int, count: int = 1
    ) -> list: ...

    async def async_setValues(
        self, device_id: int, func_code: int, address: int, values: list
    ) -> int | None: ...


class DocumentedBits:
    """A datastore whose bit tables answer only the bits each unit documents.

    A datastore that keeps bits 16 to a register (pymodbus's) would answer a read of coil 2
    of a unit whose coils are 0 and 1 with data; the spec's 6.1 and 6.2 ask "Starting
    Address == OK AND Starting Address + Quantity of Outputs == OK", else 02. ``bits`` maps
    a unit to the bit addresses it has per read function (1: coils, 2: discrete inputs);
    units and functions it does not name are passed through, as are writes (checked by
    the datastore's own rules)."""

    def __init__(self, store: Datastore, bits: Mapping[int, Mapping[int, frozenset[int]]]):
        self.store = store
        self.bits = bits

    async def async_getValues(
        self, device_id: int, func_code: int, address: int, count: int = 1
    ) -> list | int:
        documented = self.bits.get(device_id, {}).get(func_code)
        if documented is not None and not documented.issuperset(range(address, address + count)):
            return ILLEGAL_DATA_ADDRESS
        return await self.store.async_getValues(device_id, func_code, address, count)

    async def async_setValues(
        self, device_id: int, func_code: int, address: int, values: list
    ) -> int | None:
        return await self.store.async_setValues(device_id, func_code, address, values)


@dataclass(frozen=True)
class DeviceIdentity:
    """The basic objects of read device identification (spec 6.21, objects 0x00-0x02)."""

    vendor_name: str
    product_code: Mapping[int, str]  # unit id -> the instrument's name
    revision: str


class Refused(Exception):
    """A request answered with exception ``code``."""

    def __init__(self, code: int) -> None:
        super().__init__(code)
        self.code = code


def exception_pdu(function_code: int, code: int) -> bytes:
    """Exception response: the request's function code with its top bit set, then the code."""
    return bytes([(function_code | 0x80) & 0xFF, code])


def _fields(pdu: bytes, fmt: str, exact: bool = True) -> tuple[int, ...]:
    layout = struct.Struct(">" + fmt)
    if len(pdu) - 1 < layout.size or (exact and len(pdu) - 1 != layout.size):
        raise Refused(ILLEGAL_DATA_VALUE)  # the implied length is incorrect
    return layout.unpack_from(pdu, 1)


def _check_range(address: int, quantity: int) -> None:
    if address + quantity > ADDRESS_SPACE:
        raise Refused(ILLEGAL_DATA_ADDRESS)


def _values(result: list | int) -> list:
    if not isinstance(result, list):
        raise Refused(int(result))
    return result


def _pack_bits(bits: list) -> bytes:
    out = bytearray((len(bits) + 7) // 8)
    for i, bit in enumerate(bits):
        if bit:
            out[i // 8] |= 1 << (i % 8)
    return bytes(out)


def _unpack_bits(data: bytes, count: int) -> list[bool]:
    return [bool(data[i // 8] >> (i % 8) & 1) for i in range(count)]


Handler = Callable[["Datastore", int, bytes, DeviceIdentity | None], Awaitable[bytes]]


async def _read_bits_or_registers(store: Datastore, unit: int, pdu: bytes, _id) -> bytes:
    fc = pdu[0]
    address, quantity = _fields(pdu, "HH")
    if not 1 <= quantity <= READ_LIMITS[fc]:
        raise Refused(ILLEGAL_DATA_VALUE)
    _check_range(address, quantity)
    values = _values(await store.async_getValues(unit, fc, address, quantity))
    if fc in (1, 2):
        data = _pack_bits(values[:quantity])
    else:
        data = struct.pack(f">{quantity}H", *values[:quantity])
    return bytes([fc, len(data)]) + data


async def _write_single_coil(store: Datastore, unit: int, pdu: bytes, _id) -> bytes:
    address, value = _fields(pdu, "HH")
    if value not in (COIL_ON, COIL_OFF):
        raise Refused(ILLEGAL_DATA_VALUE)
    refused = await store.async_setValues(unit, 5, address, [value == COIL_ON])
    if refused:
        raise Refused(int(refused))
    return pdu  # the normal response is an echo of the request


async def _write_single_register(store: Datastore, unit: int, pdu: bytes, _id) -> bytes:
    address, value = _fields(pdu, "HH")
    refused = await store.async_setValues(unit, 6, address, [value])
    if refused:
        raise Refused(int(refused))
    return pdu


async def _write_multiple_coils(store: Datastore, unit: int, pdu: bytes, _id) -> bytes:
    address, quantity, byte_count = _fields(pdu, "HHB", exact=False)
    if (
        not 1 <= quantity <= MAX_WRITE_COILS
        or byte_count != (quantity + 7) // 8
        or len(pdu) != 6 + byte_count
    ):
        raise Refused(ILLEGAL_DATA_VALUE)
    _check_range(address, quantity)
    refused = await store.async_setValues(unit, 15, address, _unpack_bits(pdu[6:], quantity))
    if refused:
        raise Refused(int(refused))
    return pdu[:5]


async def _write_multiple_registers(store: Datastore, unit: int, pdu: bytes, _id) -> bytes:
    address, quantity, byte_count = _fields(pdu, "HHB", exact=False)
    if (
        not 1 <= quantity <= MAX_WRITE_REGISTERS
        or byte_count != 2 * quantity
        or len(pdu) != 6 + byte_count
    ):
        raise Refused(ILLEGAL_DATA_VALUE)
    _check_range(address, quantity)
    values = list(struct.unpack_from(f">{quantity}H", pdu, 6))
    refused = await store.async_setValues(unit, 16, address, values)
    if refused:
        raise Refused(int(refused))
    return pdu[:5]


async def _read_write_registers(store: Datastore, unit: int, pdu: bytes, _id) -> bytes:
    read_address, read_qty, write_address, write_qty, byte_count = _fields(
        pdu, "HHHHB", exact=False
    )
    if (
        not 1 <= read_qty <= MAX_RW_READ
        or not 1 <= write_qty <= MAX_RW_WRITE
        or byte_count != 2 * write_qty
        or len(pdu) != 10 + byte_count
    ):
        raise Refused(ILLEGAL_DATA_VALUE)
    _check_range(read_address, read_qty)
    _check_range(write_address, write_qty)
    # 6.17: the read addresses are checked (02) before the operation, which writes first
    # and then reads; a request refused for its read must write nothing
    _values(await store.async_getValues(unit, 23, read_address, read_qty))
    values = list(struct.unpack_from(f">{write_qty}H", pdu, 10))
    refused = await store.async_setValues(unit, 23, write_address, values)
    if refused:
        raise Refused(int(refused))
    read = _values(await store.async_getValues(unit, 23, read_address, read_qty))
    return bytes([23, 2 * read_qty]) + struct.pack(f">{read_qty}H", *read[:read_qty])


async def _encapsulated(
    _store: Datastore, unit: int, pdu: bytes, identity: DeviceIdentity | None
) -> bytes:
    """43/14 read device identification: the basic objects, stream (01) or one (04)."""
    if identity is None or len(pdu) < 2 or pdu[1] != MEI_READ_DEVICE_ID:
        raise Refused(ILLEGAL_FUNCTION)  # 43/13 (CANopen) and others are not implemented
    read_code, object_id = _fields(pdu, "xBB")
    if read_code not in (1, 2, 3, 4):
        raise Refused(ILLEGAL_DATA_VALUE)
    objects = {
        0x00: identity.vendor_name,
        0x01: identity.product_code.get(unit, "?"),
        0x02: identity.revision,
    }
    if read_code == 4:
        if object_id not in objects:
            raise Refused(ILLEGAL_DATA_ADDRESS)
        chosen = [object_id]
    else:
        # 6.21: a stream access to an object id that does not exist restarts at 0
        chosen = [i for i in sorted(objects) if i >= (object_id if object_id in objects else 0)]
    body = bytearray()
    for i in chosen:
        text = objects[i].encode("utf-8")[:200]
        body += bytes([i, len(text)]) + text
    conformity = 0x81  # basic identification, stream and individual access
    return bytes([43, MEI_READ_DEVICE_ID, read_code, conformity, 0, 0, len(chosen)]) + body


#: A write checked without being made: (unit, function code, address, values) -> the
#: exception code it would get, or None where it would be carried out
WriteCheck = Callable[[int, int, int, list], Awaitable[int | None]]
#: the read of the table a write function writes (a write's addresses, checked by reading)
_READ_OF_WRITE = {5: 1, 15: 1, 6: 3, 16: 3, 23: 3}


class FailingOperation:
    """The datastore of a unit whose device fails at the operation (a fault's 04).

    Reads read as always (a read changes nothing, and its refusal, 02, answers as always); a
    write is checked and never made: by ``check_write`` (the server's write rules) where
    given, else its addresses by a read of the range; one that passes is refused with 04
    SERVER DEVICE FAILURE."""

    def __init__(self, store: Datastore, check_write: WriteCheck | None = None) -> None:
        self.store = store
        self.check_write = check_write

    async def async_getValues(
        self, device_id: int, func_code: int, address: int, count: int = 1
    ) -> list | int:
        return await self.store.async_getValues(device_id, func_code, address, count)

    async def async_setValues(
        self, device_id: int, func_code: int, address: int, values: list
    ) -> int | None:
        if self.check_write is not None:
            refused = await self.check_write(device_id, func_code, address, values)
        else:
            read = await self.store.async_getValues(
                device_id, _READ_OF_WRITE[func_code], address, len(values)
            )
            refused = None if isinstance(read, list) else int(read)
        return refused or SERVER_DEVICE_FAILURE


HANDLERS: dict[int, Handler] = {
    1: _read_bits_or_registers,
    2: _read_bits_or_registers,
    3: _read_bits_or_registers,
    4: _read_bits_or_registers,
    5: _write_single_coil,
    6: _write_single_register,
    15: _write_multiple_coils,
    16: _write_multiple_registers,
    23: _read_write_registers,
    ENCAPSULATED_INTERFACE: _encapsulated,
}


async def process(
    store: Datastore, unit: int, pdu: bytes, identity: DeviceIdentity | None = None
) -> bytes:
    """The response PDU to request ``pdu`` for ``unit`` (a unit the server has), checked in
    the spec's order; exceptions are returned as exception responses."""
    function_code = pdu[0]
    handler = HANDLERS.get(function_code)  # codes >= 0x80 are never requests: 01
    if handler is None:
        return exception_pdu(function_code, ILLEGAL_FUNCTION)
    try:
        return await handler(store, unit, pdu, identity)
    except Refused as refusal:
        return exception_pdu(function_code, refusal.code)


async def process_failing(
    store: Datastore,
    unit: int,
    pdu: bytes,
    identity: DeviceIdentity | None = None,
    check_write: WriteCheck | None = None,
) -> bytes:
    """The response PDU to request ``pdu`` for a ``unit`` whose device fails (a fault's 04):
    the spec's checks first, as :func:`process` makes them (01, 03, 02: the state diagrams
    of section 6, and the write rules ``check_write`` gives), each answering as always;
    a request that passes them gets 04 at the operation, and nothing is written
    (:class:`FailingOperation`). A stranger's probe: under such a fault an unsupported
    function code, a quantity of 0, an unmapped address and an FC5 value of 0x1234 all got
    04, as if the device had failed before it could tell an illegal request."""
    response = await process(FailingOperation(store, check_write), unit, pdu, identity)
    if response[0] & 0x80:  # refused by a check (or the failing write itself: 04)
        return response
    return exception_pdu(pdu[0], SERVER_DEVICE_FAILURE)
