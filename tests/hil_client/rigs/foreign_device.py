"""A bench device of someone else's making, for tests of ``hil-client run`` against it.

A stranger wrote his own Modbus/TCP device from docs/register_map.md (raw asyncio, no
pymodbus) and found the client assuming things the Modbus specification leaves to the
device: that every unit takes a read of 125 registers, that every unit takes FC15, that a
float register never stands at its type's largest value, that the simulation control
never answers a gateway's transient exception. This device is such a bench, in lockstep
(the client advances it, so a run is quick and the same every time), serving the shipped
map's registers from a small plant of its own, with the quirks a test switches on
(:class:`Quirks`). Every request is recorded in :attr:`ForeignDevice.requests`.

It listens on a free port of 127.0.0.1, in a thread of its own::

    with ForeignDevice(Quirks(max_registers=8)) as device:
        main(["run", ..., "--rig", f"modbus://127.0.0.1:{device.port}"])
"""

from __future__ import annotations

import asyncio
import struct
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

from rig_emulator.boilers import load_boiler
from rig_emulator.emulator import boiler_identity
from rig_emulator.registers import Point, encode, load_map, map_identity

SIM_CONTROL = 100
_TABLE_OF = {1: "coil", 2: "discrete", 3: "holding", 4: "input"}


@dataclass
class Quirks:
    """What this device does differently from the emulator (all off by default).

    Args:
        max_registers: the most registers a read of an instrument (not unit 100) may ask
            for; a longer read gets ``max_registers_code`` (the spec lets a device allow
            fewer than 125).
        max_registers_code: the exception a longer read gets (03, or 02).
        refuse_units: instruments that answer every read with ``refuse_code``.
        refuse_code: see ``refuse_units``.
        no_fc15: FC15 (write multiple coils) answered with 01; FC5 still works.
        no_fc5: FC5 answered with 01 too.
        override: ``(signal, sim_time_s) -> value`` served instead of the plant's, or None.
        sim_control_exceptions: ``n -> code``: the n-th request to unit 100 (from 0, the
            client's own reads and advances) is answered with that exception, or None.
    """

    max_registers: int | None = None
    max_registers_code: int = 3
    refuse_units: frozenset[int] = frozenset()
    refuse_code: int = 2
    no_fc15: bool = False
    no_fc5: bool = False
    override: Callable[[str, float], float | None] | None = None
    sim_control_exceptions: Callable[[int], int | None] | None = None


@dataclass
class _Plant:
    """A boiler that heats while switched on, and the bench around it (just enough for a
    protocol's phases to be played)."""

    time_s: float = 0.0
    counter: int = 0
    boiler_water_C: float = 20.0
    mass_kg: float = 180.0
    energy_Wh: float = 0.0
    coils: dict[tuple[int, int], bool] = field(default_factory=dict)
    holding: dict[tuple[int, int], int] = field(default_factory=dict)

    @property
    def burning(self) -> bool:
        return self.coils.get((7, 0), False)

    def advance(self, seconds: float) -> None:
        self.time_s += seconds
        self.counter = (self.counter + 1) % 65536
        rate = 0.5 if self.burning else -0.05  # K/s
        self.boiler_water_C = min(max(self.boiler_water_C + rate * seconds, 20.0), 85.0)
        if self.burning:
            self.mass_kg -= 0.001 * seconds
        self.energy_Wh += (50.0 if self.burning else 5.0) * seconds / 3600

    def signals(self) -> dict[str, float]:
        on = self.burning
        flow = _float32_of(self.holding, 1, 0) if self.coils.get((1, 0), False) else 0.0
        o2 = 8.5 if on else 20.9
        return {
            "water_flow_kg_h": flow,
            "water_in_temp_C": max(self.boiler_water_C - 10.0, 20.0),
            "water_out_temp_C": self.boiler_water_C - 0.3,
            "boiler_water_temp_C": self.boiler_water_C,
            "room_temp_C": 22.0,
            "ambient_pressure_hPa": 985.0,
            "relative_humidity_pct": 45.0,
            "flue_gas_O2_pct": o2,
            "flue_gas_CO2_pct": (20.9 - o2) * 0.95,
            "flue_gas_CO_ppm": 100.0 if on else 0.0,
            "flue_gas_NOx_ppm": 80.0 if on else 0.0,
            "flue_gas_SO2_ppm": 5.0 if on else 0.0,
            "analyser_status": 0.0,
            "flue_gas_OGC_ppm": 3.0 if on else 0.0,
            "flue_gas_temp_C": 60.0 + self.boiler_water_C if on else self.boiler_water_C,
            "flue_gas_velocity_m_s": 2.5 if on else 0.8,
            "chimney_draught_Pa": -12.0,
            "balance_mass_kg": self.mass_kg,
            "balance_stable": 1.0,
            "electric_power_W": 50.0 if on else 5.0,
            "electric_energy_Wh": self.energy_Wh,
            "boiler_on": float(on),
            "boiler_mode": 2.0 if on else 0.0,
            "firing_power_kW": 12.0 if on else 0.0,
            "boiler_set_temp_C": 70.0,
        }


def _float32_of(holding: dict[tuple[int, int], int], unit: int, address: int) -> float:
    words = (holding.get((unit, address), 0), holding.get((unit, address + 1), 0))
    return struct.unpack(">f", struct.pack(">HH", *words))[0]


class ForeignDevice:
    """The device (see the module docstring); a context manager that starts and stops it."""

    def __init__(self, quirks: Quirks | None = None) -> None:
        self.quirks = quirks or Quirks()
        self.map = load_map()
        self.plant = _Plant()
        #: every request: (unit, function, address, count or value, exception code or None)
        self.requests: list[tuple[int, int, int, int, int | None]] = []
        self._sim_control_requests = 0
        self._points: dict[tuple[int, str], list[Point]] = {}
        for device in self.map.devices:
            for point in device.points:
                self._points.setdefault((device.unit_id, point.table), []).append(point)
        self._identity = {
            "epoch_id": 0x12345678,
            "boiler_id": boiler_identity(load_boiler("windhager_12kw")),
            "profile_id": 0,
            "seed": 0,
            "map_id": map_identity(self.map),
            "clock_mode": 1.0,
            "speed_factor": 1.0,
        }
        self._loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self.port = 0

    def __enter__(self) -> ForeignDevice:
        self._thread.start()
        if not self._ready.wait(10):
            raise RuntimeError("the foreign device did not start")
        return self

    def __exit__(self, *exc: object) -> None:
        asyncio.run_coroutine_threadsafe(self._stop(), self._loop).result(10)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(10)

    async def _stop(self) -> None:
        """Close the listener and every connection."""
        self._server.close()
        others = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
        for task in others:
            task.cancel()
        await asyncio.gather(*others, return_exceptions=True)

    # ------------------------------------------------------------------ the wire
    def _serve(self) -> None:
        asyncio.set_event_loop(self._loop)
        self._server = self._loop.run_until_complete(
            asyncio.start_server(self._connection, "127.0.0.1", 0)
        )
        self.port = self._server.sockets[0].getsockname()[1]
        self._ready.set()
        try:
            self._loop.run_forever()
        finally:
            self._loop.close()

    async def _connection(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter):
        buffer = b""
        try:
            while chunk := await reader.read(4096):
                buffer += chunk
                replies = []
                while len(buffer) >= 7:
                    tid, _, length, unit = struct.unpack(">HHHB", buffer[:7])
                    if len(buffer) < 6 + length:
                        break
                    pdu, buffer = buffer[7 : 6 + length], buffer[6 + length :]
                    reply = self.answer(unit, pdu)
                    replies.append(struct.pack(">HHHB", tid, 0, len(reply) + 1, unit) + reply)
                writer.write(b"".join(replies))
                await writer.drain()
        except ConnectionError:
            pass
        finally:
            writer.close()

    # ------------------------------------------------------------------ the device
    def answer(self, unit: int, pdu: bytes) -> bytes:
        """The reply PDU to ``pdu`` sent to ``unit`` (recorded in :attr:`requests`)."""
        function = pdu[0]
        address, quantity = struct.unpack(">HH", pdu[1:5])
        code = self._refusal(unit, function, quantity)
        reply = b"" if code is not None else self._carry_out(unit, function, pdu)
        if not reply and code is None:
            code = 2
        self.requests.append((unit, function, address, quantity, code))
        return bytes([function | 0x80, code]) if code is not None else reply

    def _refusal(self, unit: int, function: int, quantity: int) -> int | None:
        q = self.quirks
        if unit == SIM_CONTROL:
            n, self._sim_control_requests = (
                self._sim_control_requests,
                self._sim_control_requests + 1,
            )
            return q.sim_control_exceptions(n) if q.sim_control_exceptions else None
        if function in (3, 4) and unit in q.refuse_units:
            return q.refuse_code
        if function in (3, 4) and q.max_registers is not None and quantity > q.max_registers:
            return q.max_registers_code
        if (function == 15 and (q.no_fc15 or q.no_fc5)) or (function == 5 and q.no_fc5):
            return 1
        if function not in (1, 2, 3, 4, 5, 6, 15, 16):
            return 1
        return None

    def _carry_out(self, unit: int, function: int, pdu: bytes) -> bytes:
        """The reply of a request this device takes; b"" for an unmapped address (02)."""
        plant = self.plant
        address, quantity = struct.unpack(">HH", pdu[1:5])
        if function in (1, 2, 3, 4):
            words = self._table(unit, _TABLE_OF[function])
            wanted = range(address, address + quantity)
            if any(a not in words for a in wanted):
                return b""
            if function in (1, 2):
                data = bytearray((quantity + 7) // 8)
                for i, a in enumerate(wanted):
                    data[i // 8] |= (1 if words[a] else 0) << (i % 8)
                return bytes([function, len(data)]) + bytes(data)
            return bytes([function, 2 * quantity]) + struct.pack(
                f">{quantity}H", *(words[a] for a in wanted)
            )
        if function == 5:
            plant.coils[(unit, address)] = pdu[3] == 0xFF
            return pdu
        if function == 15:
            for i in range(quantity):
                plant.coils[(unit, address + i)] = bool(pdu[6 + i // 8] >> (i % 8) & 1)
            return pdu[:5]
        if function == 6:
            plant.holding[(unit, address)] = quantity
            return pdu
        words = struct.unpack(f">{quantity}H", pdu[6 : 6 + 2 * quantity])
        if unit == SIM_CONTROL and address == 4:  # lockstep_advance (uint32 s)
            plant.advance(float((words[0] << 16) | words[1]))
            return pdu[:5]
        for i, word in enumerate(words):
            plant.holding[(unit, address + i)] = word
        return pdu[:5]

    def _table(self, unit: int, table: str) -> dict[int, int]:
        """Address -> register (or bit) of one table of one unit, as served now."""
        values = self.plant.signals()
        plant = self.plant
        values |= {"sim_time_s": plant.time_s, "lockstep_counter": float(plant.counter)}
        values |= {k: float(v) for k, v in self._identity.items()}
        override = self.quirks.override
        words: dict[int, int] = {}
        for point in self._points.get((unit, table), []):
            if table == "coil":
                words[point.address] = int(plant.coils.get((unit, point.address), False))
                continue
            if table == "holding" and unit != SIM_CONTROL:
                for i in range(point.width):
                    words[point.address + i] = plant.holding.get((unit, point.address + i), 0)
                continue
            value = values.get(point.signal, 0.0)
            if override is not None:
                served = override(point.signal, plant.time_s)
                value = value if served is None else served
            for i, word in enumerate(encode(point, value)):
                words[point.address + i] = word
        return words
