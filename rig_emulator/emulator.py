"""The emulated bench as instruments see it: plant, instruments and commands in one object.

This is what the Modbus adapter publishes and what the in-process rig of the client reads;
both therefore see exactly the same values. The profile gives the instruments and the
plant's unmodelled effects (:mod:`rig_emulator.bench.effects`), which the bench applies.
Time advances in sub-steps of at most ``max_step_s`` so that a long advance (lockstep,
accelerated real time) gives the same result as many short ones at the acquisition period.

Emissions the Type 869 model does not carry (assumptions ours, documented):
- NOx: 35 % of the fuel nitrogen converted to NO (typical of wood pellets, 20-50 %),
  expressed as ppm in the dry flue gas;
- organic gaseous carbon (FID, ppm C1): 5 % of the CO concentration (OGC/CO of wood
  combustion is a few per cent in stationary operation and rises with CO at start-up).
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import json
import math
from collections.abc import Callable, Sequence
from operator import itemgetter

import numpy as np

from rig_emulator.bench import Bench, BenchConfig
from rig_emulator.bench.bench import (
    N_BENCH_OUTPUTS,
    YB_BALANCE,
    YB_DRAUGHT,
    YB_FIRING_FLAG,
    YB_FLOW,
    YB_HUMIDITY,
    YB_PRESSURE,
    YB_ROOM,
    YB_T_IN,
    YB_T_OUT,
    YB_VELOCITY,
)
from rig_emulator.instruments import InstrumentBank, Profile
from rig_emulator.instruments.profile import InstrumentSpec
from rig_emulator.model.constants import V_MOLAR_N
from rig_emulator.model.layout import (
    K_SET,
    K_VDRY0,
    K_VDRY1,
    N_OUTPUTS,
    S_ELECTRIC,
    Y_CO,
    Y_CO2,
    Y_FIRING,
    Y_LAMBDA,
    Y_MODE,
    Y_O2,
    Y_P_EL,
    Y_SO2,
    Y_T_BOILER,
    Y_T_FG,
)
from rig_emulator.model.params import BoilerParams
from rig_emulator.signals import MEASURED, SIGNALS

NOX_CONVERSION = 0.35  # fraction of fuel N emitted as NO
OGC_PER_CO = 0.05  # organic gaseous carbon [ppm C1] per ppm CO
CO_RANGE_PPM = 10_000.0  # analyser range; above it the status word flags over-range
STABLE_WINDOW_S = 5.0  # the balance reports "stable" when unchanged this long
#: Readings of the gas analyser (unit 2): an invalid one clears its "measuring" bit.
ANALYSER_SIGNALS = (
    "flue_gas_O2_pct",
    "flue_gas_CO2_pct",
    "flue_gas_CO_ppm",
    "flue_gas_NOx_ppm",
    "flue_gas_SO2_ppm",
)

_INDEX = {name: i for i, name in enumerate(MEASURED)}
_TRUE_KEYS = tuple("true_" + name for name in MEASURED)  # the plant's values, published


#: Where the plant's true value of each measured signal (and of ``boiler_on``) comes from:
#: (``y``, index) an output of the boiler (layout ``Y_*``), (``yb``, index) one of the bench
#: (``YB_*``), (``derived``, 0) NOx and (``derived``, 1) OGC (module docstring).
PLANT_SOURCES: dict[str, tuple[str, int]] = {
    "water_flow_kg_h": ("yb", YB_FLOW),
    "water_in_temp_C": ("yb", YB_T_IN),
    "water_out_temp_C": ("yb", YB_T_OUT),
    "boiler_water_temp_C": ("y", Y_T_BOILER),
    "room_temp_C": ("yb", YB_ROOM),
    "ambient_pressure_hPa": ("yb", YB_PRESSURE),
    "relative_humidity_pct": ("yb", YB_HUMIDITY),
    "flue_gas_O2_pct": ("y", Y_O2),
    "flue_gas_CO2_pct": ("y", Y_CO2),
    "flue_gas_CO_ppm": ("y", Y_CO),
    "flue_gas_NOx_ppm": ("derived", 0),
    "flue_gas_SO2_ppm": ("y", Y_SO2),
    "flue_gas_OGC_ppm": ("derived", 1),
    "flue_gas_temp_C": ("y", Y_T_FG),
    "flue_gas_velocity_m_s": ("yb", YB_VELOCITY),
    "chimney_draught_Pa": ("yb", YB_DRAUGHT),
    "balance_mass_kg": ("yb", YB_BALANCE),
    "electric_power_W": ("y", Y_P_EL),
    "boiler_on": ("yb", YB_FIRING_FLAG),
}
assert set(MEASURED) <= set(PLANT_SOURCES), set(MEASURED) - set(PLANT_SOURCES)
# offsets of the parts in the list y + yb + derived that the getters gather from
_SOURCE_OFFSET = {"y": 0, "yb": N_OUTPUTS, "derived": N_OUTPUTS + N_BENCH_OUTPUTS}


def _one_tuple(position: int) -> Callable[[list], tuple]:
    """itemgetter for one position, returning a 1-tuple like itemgetter of several."""
    get = itemgetter(position)
    return lambda values: (get(values),)


class CommandError(ValueError):
    """A command value is not acceptable (unknown, NaN, infinite or out of range)."""


def _hash32(data: object) -> int:
    """A 32-bit hash of ``data``'s canonical JSON form."""
    text = json.dumps(data, sort_keys=True, default=str).encode()
    return int.from_bytes(hashlib.blake2b(text, digest_size=4).digest(), "big")


def boiler_identity(params: BoilerParams, config: BenchConfig | None = None) -> int:
    """The published 32-bit hash of a boiler's values (not its file's name: a lab's renamed
    copy is the same boiler) with the bench configuration (the default bench's if None)."""
    values = {k: v for k, v in params.to_mapping().items() if k != "name"}
    return _hash32([values, dataclasses.asdict(config or BenchConfig())])


def _spec_identity(spec: InstrumentSpec) -> dict[str, object]:
    """An instrument's spec as hashed: an absent ``reading_min`` left out, so a profile
    without floors keeps the ``profile_id`` it had before instruments could have one."""
    fields = dataclasses.asdict(spec)
    if fields.get("reading_min") is None:
        fields.pop("reading_min", None)
    return fields


def plant_identity(
    params: BoilerParams, profile: Profile, seed: int, config: BenchConfig
) -> dict[str, float]:
    """What identifies a plant set-up, as published: 32-bit hashes of the boiler's values
    (not its name; with the bench configuration) and of the profile, and the seed modulo
    2**32. Two servers started with the same files and seed publish the same values."""
    profile_data = {
        "name": profile.name,
        "instruments": {k: _spec_identity(v) for k, v in profile.instruments.items()},
        "effects": {k: dict(v) for k, v in profile.effects.items()},
    }
    return {
        "boiler_id": float(boiler_identity(params, config)),
        "profile_id": float(_hash32(profile_data)),
        "seed": float(seed % 2**32),
    }


def check_command(name: str, value: float, within: tuple[float, float] | None = None) -> float:
    """The one check of a command value, on every path (local rig, Modbus, dashboard):
    a command signal, finite, a whole number if the signal takes only those
    (:attr:`~rig_emulator.signals.Signal.whole`: a switch fired on 0.5 written through a
    scaled register, a stranger's probe), within its declared range
    (:mod:`rig_emulator.signals`) or ``within``, a register-map point's range, which the map
    may only narrow. Returns the value as float; :class:`CommandError` if not valid."""
    signal = SIGNALS.get(name)
    if signal is None or signal.kind != "command":
        raise CommandError(f"'{name}' is not a command")
    value = float(value)
    if not math.isfinite(value):
        raise CommandError(f"{name}: {value} is not a finite number")
    # exactly: a writable point of such a command has scale 1 or -1 and a whole offset
    # (the map's rule), so it decodes whole numbers exactly; 1 + 5e-10 through a float64 was
    # taken as 1 while the point held 1.0000000005 (a re-probe)
    if signal.whole and not value.is_integer():
        raise CommandError(f"{name}: {value!r} is not a whole number (a switch, mode or code)")
    lo, hi = within if within is not None else (signal.minimum, signal.maximum)
    if not lo <= value <= hi:
        raise CommandError(f"{name}: {value} outside {lo:g}..{hi:g}")
    return value


class Emulator:
    """Boiler, bench and instruments, advanced in simulated time.

    Args:
        params: the boiler.
        profile: instrument profile (``clean``: readings equal the plant) and the plant's
            unmodelled effects (``effects``; none: the plant is the model).
        seed: seed of the instruments' fixed errors and noise.
        config: the bench (loop, room, balance).
        max_step_s: longest physics step of an advance [s].
    """

    def __init__(
        self,
        params: BoilerParams,
        profile: Profile,
        seed: int = 0,
        config: BenchConfig | None = None,
        max_step_s: float = 1.0,
    ) -> None:
        self.params = params
        self.profile = profile
        self.seed = seed
        self.max_step_s = max_step_s
        self.bench = Bench(params, config, profile.effects)
        #: changes the readings (by signal) before they are published, e.g. instrument
        #: faults (:mod:`rig_emulator.faults`); called as ``hook(readings, sim_time_s)``
        self.reading_hook: Callable[[dict[str, float], float], None] | None = None
        #: published with the readings: what identifies the set-up (CONTRACT section 7)
        self.identity = plant_identity(params, profile, seed, self.bench.config)
        fuel_n = params.fuel.n
        self._nox_per_v = 1e6 * NOX_CONVERSION * fuel_n / 14.007 * V_MOLAR_N
        self._measured_plant_values = self.plant_values_getter(MEASURED)
        self.reset()

    def reset(self) -> None:
        """Back to the initial state; the instruments draw the same errors again."""
        self.bench.reset()
        self.bench.c[K_SET] = self.params.set_temp_C
        self.instruments = InstrumentBank(MEASURED, self.profile, self.seed)
        self.sim_time_s = 0.0
        self.commands: dict[str, float] = {
            "water_flow_setpoint_kg_h": 0.0,
            "return_setpoint_C": self.bench.config.initial_water_temp_C,
            "pump_on": 1.0,
            "return_heating": 0.0,
            "boiler_command": 0.0,
            "boiler_set_temp_C": self.params.set_temp_C,
        }
        self._apply_commands()
        self.bench.initial_outputs()
        self._true = self._plant_values()
        self._readings = self._true if self.instruments.ideal else self._first_readings()
        self._stale = False
        self._balance_last = float(self._readings[_INDEX["balance_mass_kg"]])
        self._balance_since = 0.0

    def _first_readings(self) -> list[float]:
        """What the instruments show before the first step: the plant's values through
        their fixed errors, noise, rounding and floor (they showed the plant's values
        exactly, a reading off by an instrument's offset from the first step on). Read on
        a copy: the instruments' draws after it are those of a bank never read at t=0."""
        first = copy.deepcopy(self.instruments)
        return first.read(np.array(self._true), self.sim_time_s, 0.0).tolist()

    def compile_kernels(self) -> None:
        """Compile (or load from numba's cache) the kernels this emulator runs, on a
        throwaway copy, so that its first step need not wait for them. Safe to run in
        another thread: a step that comes first waits for numba's compiler lock."""
        copy = Emulator(self.params, self.profile, self.seed, self.bench.config)
        copy.set_commands({"boiler_command": 1.0, "water_flow_setpoint_kg_h": 600.0})
        copy.advance(2.0)
        copy.values()

    # ------------------------------------------------------------------ commands
    def set_command(self, name: str, value: float) -> None:
        """Set a bench or boiler command (validated; :class:`CommandError` if not valid)."""
        self.set_commands({name: value})

    def set_commands(self, values: dict[str, float]) -> None:
        """Set several commands at once; all are validated before any is applied."""
        self.set_checked_commands({name: check_command(name, v) for name, v in values.items()})

    def set_checked_commands(self, values: dict[str, float]) -> None:
        """Set plant commands that :func:`check_command` has passed (the Modbus adapter
        checks a whole write against the map's points first, then applies it)."""
        for name in values:
            if name not in self.commands:
                raise CommandError(f"'{name}' is a clock command, not a plant command")
        self.commands.update(values)
        self._apply_commands()

    def _apply_commands(self) -> None:
        cmd = self.commands
        self.bench.set_inputs(
            cmd["water_flow_setpoint_kg_h"],
            cmd["return_setpoint_C"],
            cmd["pump_on"] >= 0.5,
            cmd["boiler_command"] >= 0.5,
            cmd["return_heating"] >= 0.5,
        )
        self.bench.c[K_SET] = cmd["boiler_set_temp_C"]

    # ------------------------------------------------------------------ time
    def advance(self, seconds: float) -> None:
        """Advance by ``seconds`` of simulated time in sub-steps of at most ``max_step_s``."""
        if seconds <= 0:
            return
        if seconds <= self.max_step_s and self.instruments.ideal:
            # one step, readings computed when read: advance_steps(1, seconds), inlined
            # (the per-row path of offline runs)
            self.bench.step(seconds)
            self.sim_time_s += seconds
            self._stale = True
            return
        n, dt = self.substeps(seconds)
        self.advance_steps(n, dt)

    def substeps(self, seconds: float) -> tuple[int, float]:
        """How :meth:`advance` splits ``seconds`` (> 0): ``n`` steps of ``dt`` [s] each,
        ``dt <= max_step_s``. A caller may run the ``n`` steps in chunks with
        :meth:`advance_steps` and get the same result as one :meth:`advance`."""
        n = 1 if seconds <= self.max_step_s else math.ceil(seconds / self.max_step_s - 1e-9)
        return n, seconds / n

    def advance_steps(self, n: int, dt: float) -> None:
        """Advance by ``n`` physics steps of ``dt`` seconds each (``dt <= max_step_s``)."""
        if n <= 0:
            return
        seconds = n * dt
        bench = self.bench
        instruments = self.instruments
        if instruments.ideal:  # readings are the plant values: computed when read
            for _ in range(n):
                bench.step(dt)
            self.sim_time_s += seconds
            self._stale = True
            return
        for _ in range(n):
            bench.step(dt)
            self.sim_time_s += dt
            self._true = self._plant_values()
            self._readings = instruments.read(np.array(self._true), self.sim_time_s, dt).tolist()

    @property
    def readings(self) -> list[float]:
        """Instrument readings of the measured signals, in :data:`MEASURED` order."""
        if self._stale:
            self._true = self._readings = self._plant_values()
            self._stale = False
        return self._readings

    # ------------------------------------------------------------------ values
    def _plant_values(self) -> list[float]:
        """True values of the measured signals, in :data:`MEASURED` order."""
        return list(self._measured_plant_values())

    def _plant_by_name(self) -> dict[str, float]:
        """True values of the measured signals by name, from the plant's named outputs
        (:data:`PLANT_SOURCES`)."""
        return dict(zip(MEASURED, self._measured_plant_values(), strict=True))

    def plant_values_getter(self, names: Sequence[str]) -> Callable[[], tuple[float, ...]]:
        """A function giving the plant's true values of ``names`` (signals of
        :data:`PLANT_SOURCES`), in that order, after the last step: one gather over the
        plant's output lists, no dict (the per-row path of offline runs)."""
        positions = [_SOURCE_OFFSET[PLANT_SOURCES[n][0]] + PLANT_SOURCES[n][1] for n in names]
        gather = itemgetter(*positions) if len(positions) > 1 else _one_tuple(positions[0])
        bench = self.bench
        nox_per_v = self._nox_per_v
        c = bench.c

        def values() -> tuple[float, ...]:
            y = bench.y.tolist()
            lam = y[Y_LAMBDA]
            nox = nox_per_v / (c[K_VDRY0] + c[K_VDRY1] * lam) if math.isfinite(lam) else 0.0
            return gather(y + bench.yb.tolist() + [nox, OGC_PER_CO * y[Y_CO]])

        return values

    def reading_values_getter(self, names: Sequence[str]) -> Callable[[], tuple[float, ...]]:
        """A function giving the readings of ``names`` (measured signals or ``boiler_on``)
        in that order: :meth:`reading_by_name` and :attr:`boiler_on` without the dict."""
        plant = self.plant_values_getter(names)
        flag = len(MEASURED)
        positions = [flag if n == "boiler_on" else _INDEX[n] for n in names]
        gather = itemgetter(*positions) if len(positions) > 1 else _one_tuple(positions[0])

        def values() -> tuple[float, ...]:
            if self._stale:  # ideal instruments: the readings are the plant's values
                return plant()
            return gather([*self._readings, float(self.bench.yb[YB_FIRING_FLAG])])

        return values

    def reading_by_name(self) -> dict[str, float]:
        """Instrument readings of the measured signals by name (a new dict)."""
        if self._stale:  # ideal instruments: the readings are the plant's values (the
            return self._plant_by_name()  # lists are built when asked, see readings)
        return dict(zip(MEASURED, self._readings, strict=True))

    @property
    def boiler_on(self) -> float:
        """1.0 while the burner fires, as the boiler controller reports it."""
        return float(self.bench.yb[YB_FIRING_FLAG])

    def plant(self) -> dict[str, float]:
        """True plant values of the measured signals (what ideal instruments would read)."""
        self.readings  # noqa: B018 - refresh a stale plant vector
        return dict(zip(MEASURED, self._true, strict=True))

    def values(self) -> dict[str, float]:
        """Every published signal: readings, status, current commands and the plant's true
        value of each measured signal (``true_NAME``, the truth unit of the map).

        The balance's "stable" flag and the energy counter are evaluated here, i.e. at the
        rate the values are published; the counter integrates the plant's power. The
        :attr:`reading_hook` (instrument faults) acts before the status flags, so they see
        what it did: an invalid (NaN) analyser reading clears the analyser's "measuring"
        bit and sets bit 2; an invalid or jumping balance is not "stable".
        """
        if self._stale:  # ideal instruments: readings and truth are the plant's values
            self._true = self._readings = self._plant_values()
            out = dict(zip(MEASURED, self._readings, strict=True))
            self._stale = False
        else:
            out = dict(zip(MEASURED, self._readings, strict=True))
        true = dict(zip(_TRUE_KEYS, self._true, strict=True))
        if self.reading_hook is not None:
            self.reading_hook(out, self.sim_time_s)
        y = self.bench.y
        co = out["flue_gas_CO_ppm"]
        invalid = any(math.isnan(out[name]) for name in ANALYSER_SIGNALS)
        # bit 0 measuring, bit 1 CO over range, bit 2 a reading invalid (not measuring)
        out["analyser_status"] = (4.0 if invalid else 1.0) + (2.0 if co > CO_RANGE_PPM else 0.0)
        balance = out["balance_mass_kg"]
        if balance != self._balance_last:
            self._balance_last = balance
            self._balance_since = self.sim_time_s
        out["balance_stable"] = (
            1.0 if self.sim_time_s - self._balance_since >= STABLE_WINDOW_S else 0.0
        )
        out["electric_energy_Wh"] = float(self.bench.s[S_ELECTRIC])
        out["boiler_on"] = self.boiler_on
        out["boiler_mode"] = float(y[Y_MODE])
        out["firing_power_kW"] = float(y[Y_FIRING])
        out["sim_time_s"] = self.sim_time_s
        out.update(self.identity)
        out.update(self.commands)
        out.update(true)
        return out
