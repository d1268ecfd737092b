"""What one unmodelled effect declares (its module holds one :class:`EffectSpec`, ``EFFECT``).

The registry (:mod:`rig_emulator.bench.effects`) collects them; the plant
(:mod:`rig_emulator.bench.plant`) puts each effect's stages at their named points of the
step skeleton (:data:`rig_emulator.model.boiler.STAGE_POINTS`, plus :data:`BENCH_POINTS`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from rig_emulator.model.boiler import STAGE_POINTS
from rig_emulator.yamlio import finite_number

#: Stage points of the bench around the boiler's step: ``forward_sensor`` (the forward
#: reading from the boiler's outlet, a compiled stage) and ``balance`` (what the balance
#: loses per kg of fuel the plant burns, a factor applied when the bench is built).
BENCH_POINTS = ("forward_sensor", "balance")
#: Every point an effect may contribute a stage to.
POINTS = (*STAGE_POINTS, *BENCH_POINTS)
#: Accepted range of ``strength`` (validation); realistic ranges: ``EffectSpec.strength_range``.
STRENGTH_LIMITS = (0.0, 3.0)
#: Scalings of a parameter with the strength s: lab * s, lab / s, lab.
SCALINGS = ("linear", "inverse", "shape")


class EffectError(ValueError):
    """An ``effects`` entry is malformed; :attr:`key` is its dotted path."""

    def __init__(self, key: str, message: str) -> None:
        super().__init__(f"key '{key}' {message}")
        self.key = key


@dataclass(frozen=True, slots=True)
class ParamSpec:
    """One physical parameter of an effect.

    Attributes:
        name: key in the profile (unit in the name where it has one).
        unit: its unit (``-`` if dimensionless).
        lab: value at strength 1 (the lab default).
        scaling: ``linear`` (lab * s), ``inverse`` (lab / s) or ``shape`` (lab, any s).
        lo, hi: accepted range of an explicit value (inclusive).
        integer: the value must be a whole number.
        doc: what it is.
    """

    name: str
    unit: str
    lab: float
    scaling: str
    lo: float
    hi: float
    integer: bool = False
    doc: str = ""

    def scaled(self, strength: float) -> float:
        """The value at ``strength`` (no explicit override)."""
        if self.scaling == "linear":
            return self.lab * strength
        if self.scaling == "inverse":
            return self.lab / strength if strength > 0 else math.inf
        return self.lab

    def check(self, key: str, value: Any) -> float:
        """``value`` as float if it is an accepted explicit value, else :class:`EffectError`."""
        return number(key, value, self.lo, self.hi, self.integer)


def number(key: str, value: Any, lo: float, hi: float, integer: bool = False) -> float:
    """``value`` as float if it is a finite number within ``lo..hi`` (whole if ``integer``)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise EffectError(key, "must be a number")
    number = finite_number(value)
    if number is None or not lo <= number <= hi:
        raise EffectError(key, f"must be finite and within {lo:g}..{hi:g}")
    if integer and number != int(number):
        raise EffectError(key, "must be a whole number")
    return number


Values = Mapping[str, float]


@dataclass(frozen=True)
class EffectSpec:
    """An effect as the plant sees it.

    Attributes:
        name: the effect's name (the vocabulary of CONTRACT section 4; shared with the
            diagnosis, nothing else is).
        params: its physical parameters.
        strength_range: documented range of realistic strengths (what a benchmark may
            draw from; 1 is the lab default).
        is_on: whether resolved parameters make the effect act (False: neutral, the plant
            is then the model as far as this effect goes).
        stages: point (:data:`POINTS`) -> compiled stage function for that point of the
            skeleton, with the signature of the model's neutral stage there
            (``rig_emulator.model.boiler.model_<point>``) or of
            :func:`rig_emulator.bench.plant.neutral_forward_sensor`; the stage reads its
            constants and state in row ``row`` of ``fc``/``fs`` and must act as the
            neutral stage while that row's ``on`` constant is 0. ``balance`` is not
            compiled: see ``balance_factor``.
        constants: names of its constants in its row of ``fc``; the first is ``on``.
        state: names of its state in its row of ``fs``.
        pack: (resolved parameters, BoilerParams) -> constants by name (``on`` is set
            by the plant).
        initial_state: temperature of the plant at rest [C] -> state by name (others 0).
        horizon_s: resolved parameters -> what the effect adds to the controller's
            horizon [s] (a lag between firing and the water).
        balance_factor: resolved parameters -> factor on the balance's loss per kg of fuel
            the plant burns (the ``balance`` stage).
        history_shape: shape of the history array its stage needs (``forward_sensor``).
    """

    name: str
    params: tuple[ParamSpec, ...]
    strength_range: tuple[float, float]
    is_on: Callable[[Values], bool]
    stages: Mapping[str, Callable[..., Any]] = field(default_factory=dict)
    constants: tuple[str, ...] = ("on",)
    state: tuple[str, ...] = ()
    pack: Callable[[Values, Any], Mapping[str, float]] = lambda values, params: {}
    initial_state: Callable[[float], Mapping[str, float]] = lambda t_C: {}
    horizon_s: Callable[[Values], float] = lambda values: 0.0
    balance_factor: Callable[[Values], float] | None = None
    history_shape: tuple[int, int] = (0, 0)

    def param(self, name: str) -> ParamSpec:
        """The parameter ``name`` (KeyError if it has none of that name)."""
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(name)

    @property
    def points(self) -> tuple[str, ...]:
        """The points it contributes a stage to."""
        balance = ("balance",) if self.balance_factor is not None else ()
        return (*self.stages, *balance)

    def resolve(self, entry: Values) -> dict[str, float]:
        """Physical parameters from a validated entry: explicit values, else scaled by
        ``strength`` (1 when absent)."""
        strength = entry.get("strength", 1.0)
        return {p.name: entry.get(p.name, p.scaled(strength)) for p in self.params}

    def validate(self) -> None:
        """Check the declaration itself (the registry calls it for every module)."""
        where = f"effect {self.name!r}"
        if not self.params:
            raise ValueError(f"{where}: no parameters")
        if len({p.name for p in self.params}) != len(self.params):
            raise ValueError(f"{where}: duplicate parameter names")
        for p in self.params:
            if p.scaling not in SCALINGS or not p.lo <= p.lab <= p.hi or not p.unit:
                raise ValueError(f"{where}: parameter {p.name!r} badly declared")
        lo, hi = self.strength_range
        if not STRENGTH_LIMITS[0] < lo < 1.0 < hi <= STRENGTH_LIMITS[1]:
            raise ValueError(f"{where}: strength range {self.strength_range} not around 1")
        unknown = set(self.stages) - set(POINTS) | ({"balance"} & set(self.stages))
        if unknown:
            raise ValueError(f"{where}: unknown stage points {sorted(unknown)}")
        if not self.points:
            raise ValueError(f"{where}: contributes no stage")
        if self.constants[:1] != ("on",):
            raise ValueError(f"{where}: its first constant must be 'on'")
