"""Instrument profiles: how each measured signal is read (YAML data, validated on load).

A profile names, per measured signal, the instrument's error model:

    name: lab
    description: ...
    instruments:
      flue_gas_temp_C: {accuracy_abs: 0.30, accuracy_rel: 0.005, noise_sd: 0.05,
                        resolution: 0.01, lag_s: 8, delay_s: 0, update_period_s: 1}

Keys of an instrument (all optional, default 0 = ideal):

- ``accuracy_abs`` [unit], ``accuracy_rel`` [-]: tolerance band +-(abs + rel |x|); a fixed
  error is drawn once per run, uniformly within the band (e.g. Pt100 class B: 0.30 + 0.005|t|);
- ``noise_sd`` [unit], ``noise_rel`` [-]: standard deviation of white noise added at each
  update, sd = noise_sd + noise_rel |x|;
- ``resolution`` [unit]: the reading is rounded to a multiple of it;
- ``lag_s`` [s]: first-order response time constant (thermowell, analyser cell);
- ``delay_s`` [s]: dead time (sample line transport);
- ``update_period_s`` [s]: the reading is refreshed only this often and held in between;
- ``reading_min`` [unit]: the lowest value the instrument can show (absent: none), applied
  after the error, noise and rounding. It is a property of how the instrument measures, not
  of the signal: a vortex flow meter counts the frequency of the vortices shed behind its
  bluff body and a frequency is never below zero, so a fixed error and noise around a
  near-still flue gas read 0 m/s, never -0.18 m/s (a stranger's probe of the ``lab``
  profile). A gas analyser's small negative reading, by contrast, is its zero drift and is
  real, so the shipped profiles give a floor to the vortex meter only. Any measured signal
  may have one (the profile author's choice), in the signal's unit, below zero too (the
  lower end of a draught gauge's range); ``null`` is none.

Signals not listed are ideal. ``clean`` lists none.

A profile may also switch on unmodelled effects of the plant (CONTRACT section 4), each
with a ``strength`` (0 off, 1 the lab default) and optional explicit parameters:

    effects:
      body_heat_diffusion: {strength: 1.0}
      fuel_energy_bias: {relative_bias: -0.05}

Names, parameters, units, defaults and ranges: :mod:`rig_emulator.bench.effects`.

A profile may also carry ``faults:``, a list as in ``FAULTS.yaml`` (:mod:`rig_emulator.faults`),
which a server with this profile schedules. Shipped: ``clean`` (ideal instruments, no
effects), ``lab`` (the bench's instruments and all five effects at lab strength),
``lab_instruments`` (the same instruments, no effects), ``lab_faulty`` (``lab`` plus
random faults at a low rate).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rig_emulator.bench.effects import EffectError, check_effects
from rig_emulator.faults.spec import Entry, FaultError, faults_from_list
from rig_emulator.signals import MEASURED
from rig_emulator.yamlio import finite_number, read_yaml, resolve_named

PROFILE_DIR = Path(__file__).resolve().parent.parent / "profiles"

#: The keys of an instrument's errors: 0 is the ideal instrument's value of each.
ERROR_KEYS = (
    "accuracy_abs",
    "accuracy_rel",
    "noise_sd",
    "noise_rel",
    "resolution",
    "lag_s",
    "delay_s",
    "update_period_s",
)
#: Every key of an instrument: its errors and the lowest value it can show (absent: none).
INSTRUMENT_KEYS = (*ERROR_KEYS, "reading_min")


#: The largest value each key may take: a relative error of 100 %; a lag, dead time or
#: update period of an hour (beyond that the reading is of another test); an absolute
#: error or a lowest reading of +-10,000 of the signal's units (the widest range of the
#: bench's instruments: CO and OGC in ppm). Beyond these a profile describes no instrument
#: (a noise of 1e300 K).
INSTRUMENT_BOUNDS = {
    "accuracy_abs": 1e4,
    "accuracy_rel": 1.0,
    "noise_sd": 1e4,
    "noise_rel": 1.0,
    "resolution": 1e4,
    "lag_s": 3600.0,
    "delay_s": 3600.0,
    "update_period_s": 3600.0,
    "reading_min": 1e4,
}


class ProfileError(ValueError):
    """A profile is malformed; the message names the file and key."""


@dataclass(frozen=True, slots=True)
class InstrumentSpec:
    """Error model of one instrument (see the module docstring; units of the signal)."""

    accuracy_abs: float = 0.0
    accuracy_rel: float = 0.0
    noise_sd: float = 0.0
    noise_rel: float = 0.0
    resolution: float = 0.0
    lag_s: float = 0.0
    delay_s: float = 0.0
    update_period_s: float = 0.0
    #: the lowest value the instrument can show; None: no such limit
    reading_min: float | None = None

    @property
    def ideal(self) -> bool:
        """Whether the reading is the plant value exactly: no error and no floor (a floor
        alone changes a plant value below it)."""
        return self.reading_min is None and all(getattr(self, key) == 0.0 for key in ERROR_KEYS)


@dataclass(frozen=True, slots=True)
class Profile:
    """A named set of instrument specs and plant effects (validated, values as float)."""

    name: str
    description: str = ""
    instruments: Mapping[str, InstrumentSpec] = field(default_factory=dict)
    effects: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    #: faults a server with this profile schedules (``FAULTS.yaml`` entries; none: none)
    faults: tuple[Entry, ...] = ()

    def spec(self, signal: str) -> InstrumentSpec:
        return self.instruments.get(signal, InstrumentSpec())

    @property
    def reading_floors(self) -> dict[str, float]:
        """Per signal with one, the lowest value its instrument can show (``reading_min``):
        what an instrument fault serves is floored there too (the fault engine)."""
        return {
            signal: spec.reading_min
            for signal, spec in self.instruments.items()
            if spec.reading_min is not None
        }


def profile_from_mapping(data: Any, source: str = "<profile>") -> Profile:
    """Validate ``data`` and build a :class:`Profile`."""
    if not isinstance(data, Mapping):
        raise ProfileError(f"{source}: expected a mapping")
    for key in data:
        if key not in ("name", "description", "instruments", "effects", "faults"):
            raise ProfileError(f"{source}: unknown key '{key}'")
    name = data.get("name")
    if not isinstance(name, str) or not name:
        raise ProfileError(f"{source}: missing required key 'name'")
    raw = data.get("instruments") or {}
    if not isinstance(raw, Mapping):
        raise ProfileError(f"{source}: key 'instruments' must be a mapping")
    instruments: dict[str, InstrumentSpec] = {}
    for signal, spec in raw.items():
        if signal not in MEASURED:
            raise ProfileError(
                f"{source}: key 'instruments.{signal}' is not a measured signal "
                f"(known: {', '.join(MEASURED)})"
            )
        if not isinstance(spec, Mapping):
            raise ProfileError(f"{source}: key 'instruments.{signal}' must be a mapping")
        values = {}
        for key, value in spec.items():
            full = f"instruments.{signal}.{key}"
            if key not in INSTRUMENT_KEYS:
                raise ProfileError(f"{source}: unknown key '{full}'")
            if key == "reading_min" and value is None:  # (written out: none, its default)
                continue
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ProfileError(f"{source}: key '{full}' must be a number")
            high = INSTRUMENT_BOUNDS[key]
            low = -high if key == "reading_min" else 0.0  # (a draught gauge's range ends
            number = finite_number(value)  # below zero: -12 Pa is a reading, a re-probe)
            if number is None or not low <= number <= high:
                raise ProfileError(f"{source}: key '{full}' must be finite, in {low:g}..{high:g}")
            values[key] = number
        instruments[signal] = InstrumentSpec(**values)
    try:
        effects = check_effects(data.get("effects"))
    except EffectError as exc:
        raise ProfileError(f"{source}: {exc}") from None
    try:
        faults = tuple(faults_from_list(data.get("faults"), source))
    except FaultError as exc:
        raise ProfileError(str(exc)) from None
    return Profile(name, str(data.get("description", "")), instruments, effects, faults)


def load_profile(name_or_path: str) -> Profile:
    """Load a shipped profile (``clean``, ``lab``, ``lab_instruments``) or a YAML file."""
    path = resolve_named(name_or_path, PROFILE_DIR, "profile", ProfileError)
    data = read_yaml(path, ProfileError)
    return profile_from_mapping(data, source=str(path))
