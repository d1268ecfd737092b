"""Unmodelled effects of the real bench (CONTRACT section 4): the plant-side registry.

The Type 869 model (:mod:`rig_emulator.model`) is what the analysis calls "the model"; these
effects make the emulated *plant* depart from it the way the Wieselburg lab departed from
the paper's simulation (Carlon et al. 2015, Section 3.2; digest section 7). They act in the
bench layer only, are off
unless a profile asks for them, and combine freely.

A profile lists them under ``effects``; each entry takes a ``strength`` and, optionally,
explicit physical parameters:

    effects:
      body_heat_diffusion: {strength: 1.0}                 # the lab default
      outlet_sensor_pipe: {strength: 0.5}                  # half as strong
      ignition_delay: {strength: 1.0, delay_s: 200}        # explicit delay, default burn-out
      fuel_energy_bias: {relative_bias: 0.05}              # explicit: 5 % more energy per kg

Scheme: ``strength`` s (default 1 when the entry is present; 0 switches the effect off;
accepted 0..3) scales each *scaled* parameter from its lab value: ``linear`` ones as
lab * s, ``inverse`` ones (time constants of a loss) as lab / s (s = 0: no loss). *Shape*
parameters stay at their lab value whatever s. An explicit parameter overrides its scaled
value and is taken as it is (within its accepted range). An effect whose resolved
parameters are all neutral is off; with every effect off the plant is bit-identical to the
model. :func:`strength_ranges` gives the documented range of realistic strengths of each
effect (what a benchmark may draw from); 1 is the lab default of ``lab.yaml``. Strengths
above 2 exaggerate: at 3 the exit pipe alone cools the forward reading at the 6 kW
boiler's preheat flow by more than the preheat tolerance (0.5 K), so t0 times out.

One module per effect: each module of this package whose name does not start with ``_``
holds one :class:`EffectSpec` named ``EFFECT`` (its parameters with units, documented
strength range, what makes it act, and the stages it contributes at named points of the
step skeleton, see :mod:`rig_emulator.bench.effects._spec`), its physics in its docstring
and its compiled stages. This registry collects them in module-name order
(:data:`REGISTRY`); validation, resolution and the plant (:mod:`rig_emulator.bench.plant`)
work from it alone, so adding an effect is adding a module (docs/extending.md).

Lab defaults (``lab.yaml``: all five at strength 1) against the clean model, stationary
test, as measured once (tests/rig_emulator/bench/test_effects.py checks the 12 kW figures'
direction and size, not their values): t1 about 15
instead of 9 min (6 kW: 19 instead of 13); the model's heat to water at the lab's t1 (same
time after t0) over the lab's: 1.16 (6 kW: 1.24; the paper: 10-30 % overestimated); fuel
over the test +8.7 %; the forward reading 9 K below the boiler water 10 min after t3, about
25 K after an hour and 21 K at t4 (6 kW: 17 K), within 0.2 K of it while water flows.

Controller (part of the plant, assumption ours): the model's controller is ideal, it brings
the water to the set temperature within one step. Behind a lag (body conduction, bed) such
a controller would hunt between Pmin and Pmax, so with those effects on it aims at the set
temperature over a horizon of one step plus 0.8 tau (body) plus tau_b (bed); in steady
state it holds the set temperature exactly, as the model does.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from rig_emulator.bench.effects._spec import (
    BENCH_POINTS,
    POINTS,
    STRENGTH_LIMITS,
    EffectError,
    EffectSpec,
    ParamSpec,
    number,
)
from rig_emulator.bench.effects.body_heat_diffusion import MAX_BODY_NODES


def _discover() -> dict[str, EffectSpec]:
    """Every effect module's ``EFFECT``, checked, by name in module-name order."""
    found: dict[str, EffectSpec] = {}
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        spec = getattr(module, "EFFECT", None)
        if not isinstance(spec, EffectSpec):
            raise TypeError(f"{module.__name__} declares no EffectSpec named EFFECT")
        if spec.name != info.name:
            raise ValueError(f"{module.__name__} declares the effect {spec.name!r}")
        spec.validate()
        found[spec.name] = spec
    owners: dict[str, str] = {}
    for spec in found.values():
        for point in spec.points:
            if point != "balance" and point in owners:
                raise ValueError(
                    f"stage point {point!r} claimed by {owners[point]!r} and {spec.name!r}"
                )
            owners[point] = spec.name
    return found


#: The registered effects by name.
REGISTRY: dict[str, EffectSpec] = _discover()
#: Alias kept for existing callers.
SPECS = REGISTRY
EFFECT_NAMES: tuple[str, ...] = tuple(REGISTRY)


def strength_ranges() -> dict[str, tuple[float, float]]:
    """Documented range of realistic strengths of each effect (1 = the lab default)."""
    return {name: spec.strength_range for name, spec in REGISTRY.items()}


def lab_parameters() -> dict[str, dict[str, float]]:
    """Each effect's physical parameters at strength 1 (the lab default)."""
    return {name: {p.name: p.lab for p in spec.params} for name, spec in REGISTRY.items()}


def check_effects(data: Any) -> dict[str, dict[str, float]]:
    """Validate an ``effects`` mapping; returns it with every value as float.

    Raises:
        EffectError: naming the key at fault (``effects``, ``effects.NAME`` or
            ``effects.NAME.PARAM``).
    """
    if data is None:
        return {}
    if not isinstance(data, Mapping):
        raise EffectError("effects", "must be a mapping")
    out: dict[str, dict[str, float]] = {}
    for name, entry in data.items():
        spec = REGISTRY.get(name)
        if spec is None:
            raise EffectError(
                f"effects.{name}", f"is not a known effect (known: {', '.join(EFFECT_NAMES)})"
            )
        if entry is None:  # (on at full strength, where a user blanked it to switch it
            raise EffectError(  # off: a stranger's probe)
                f"effects.{name}",
                "is empty: write {strength: S} ({} for its reference magnitude), or leave it "
                "out (or strength 0) to switch it off",
            )
        if not isinstance(entry, Mapping):
            raise EffectError(f"effects.{name}", "must be a mapping")
        values: dict[str, float] = {}
        for key, value in entry.items():
            full = f"effects.{name}.{key}"
            if key == "strength":
                values[key] = number(full, value, *STRENGTH_LIMITS)
                continue
            try:
                p = spec.param(key)
            except KeyError:
                known = ", ".join(("strength", *(q.name for q in spec.params)))
                raise EffectError(full, f"is not a parameter (known: {known})") from None
            values[key] = p.check(full, value)
        out[name] = values
    return out


@dataclass(frozen=True)
class EffectSettings:
    """Resolved physical parameters of the effects that act (any other is off).

    Attributes:
        values: effect name -> its physical parameters by name (units in the names, see
            the effect's module); only effects that are on, in registry order.
    """

    values: Mapping[str, Mapping[str, float]] = field(default_factory=dict)

    def __getitem__(self, name: str) -> Mapping[str, float]:
        """The parameters of the effect ``name`` (KeyError if it is off)."""
        return self.values[name]

    def __contains__(self, name: object) -> bool:
        return name in self.values

    @property
    def active(self) -> tuple[str, ...]:
        """Names of the effects that are on, in registry order."""
        return tuple(self.values)

    @property
    def dynamic(self) -> bool:
        """Any effect on that needs the effects-aware plant step (a compiled stage)."""
        return any(REGISTRY[name].stages for name in self.values)


def resolve_effects(effects: Mapping[str, Mapping[str, float]] | None) -> EffectSettings:
    """Physical parameters from a profile's (validated or raw) ``effects`` mapping."""
    checked = check_effects(effects)
    values = {}
    for name, spec in REGISTRY.items():
        if name in checked:
            resolved = spec.resolve(checked[name])
            if spec.is_on(resolved):
                values[name] = resolved
    return EffectSettings(values)


def effects_at(strengths: Mapping[str, float]) -> dict[str, dict[str, float]]:
    """An ``effects`` mapping for a profile with the given strengths (names as keys)."""
    for name in strengths:
        if name not in REGISTRY:
            raise EffectError(f"effects.{name}", "is not a known effect")
    return check_effects({name: {"strength": s} for name, s in strengths.items()})


__all__ = [
    "BENCH_POINTS",
    "EFFECT_NAMES",
    "MAX_BODY_NODES",
    "POINTS",
    "REGISTRY",
    "SPECS",
    "STRENGTH_LIMITS",
    "EffectError",
    "EffectSettings",
    "EffectSpec",
    "ParamSpec",
    "check_effects",
    "effects_at",
    "lab_parameters",
    "resolve_effects",
    "strength_ranges",
]
