"""Unmodelled effects of the real bench (CONTRACT section 4): names, parameters, strengths.

The Type 869 model (:mod:`rig_emulator.model`) is what the analysis calls "the model"; these
effects make the emulated *plant* depart from it the way the Wieselburg lab departed from
the paper's simulation (Carlon et al. 2015, Section 3.2; digest section 7). They act in the
bench layer only (:mod:`rig_emulator.bench.plant` holds the compiled physics), are off
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

Effects and parameters (lab value at strength 1; accepted range of an explicit value):

``body_heat_diffusion``: the body heats from the combustion chamber outwards. The one node
of capacity C = Ctherm + water is split into ``nodes`` metal nodes in series (together
``metal_share`` C) and the water node ((1 - metal_share) C); the heat to the exchanger enters
the first metal node and is conducted node to node to the water; the water node carries the
flow, the loss to the room and the boiler's own sensor:

    C_m dT_1/dt = Q_hx + Q_el,ign - G (T_1 - T_2),   C_m = metal_share C / nodes
    C_m dT_i/dt = G (T_(i-1) - T_i) - G (T_i - T_(i+1))
    C_w dT_w/dt = G (T_n - T_w) - m_w cp_w (T_w - T_w,in) - UA (T_w - T_room)

Total capacity and every loss are the model's, so energy is conserved and only the timing
of the heat to water changes: the water lags at start-up and after load steps, and the
metal, hotter than the water by Q tau / C_metal in steady firing, gives its excess
((nodes + 1) / (2 nodes) Q tau) to the water after a stop.

- ``time_constant_s`` tau [s], linear, lab 250, 0..3600: C_metal / G_path, with
  G_path = G / nodes the series conductance of the whole path (0: the one-node model).
- ``metal_share`` [-], shape, lab 0.40 (= Ctherm / C of Table 3), 0.05..0.95.
- ``nodes`` [-], shape, lab 3, whole number 1..6.

``outlet_sensor_pipe``: the forward sensor sits about 30 cm down the exit pipe. The pipe is
plug flow: the water at the sensor left the boiler one pipe content of flow ago (a
transport delay rho V / m_w that grows as the flow falls). Every parcel in the pipe (water
and wall, its own small capacity) relaxes toward T_c = (k_b T_boiler + k_r T_room) /
(k_b + k_r) at the rate k_b + k_r: k_r = 1 / tau_r is the wall's loss to the room, k_b =
1 / tau_b the conduction along the pipe from the boiler. While water flows a parcel stays a
few seconds and loses a few hundredths of a kelvin; once circulation stops the stagnant
parcel at the sensor cools toward T_c within about tau_r, fast against the boiler
(C / UA_amb,OFF of about 20 h), so the forward reading falls below the boiler water after
t3. Only the forward reading (``water_out_temp_C``) is affected; the boiler, its water
temperature and the loop are not.

- ``volume_l`` V [l], linear, lab 0.25 (30 cm of DN32), 0..5.
- ``cooling_time_constant_s`` tau_r [s], inverse, lab 1800, 1..1e6.
- ``coupling_time_constant_s`` tau_b [s], linear, lab 18000 (steel wall conduction over
  30 cm), 0..1e6 (0: instant, the sensor reads the boiler water). At strength s the
  stagnant sensor settles at T_room + (T_boiler - T_room) / (1 + 10 s^2): 9 % of the way
  back to the boiler at s = 1, nearly the room; as s goes to 0 the pipe vanishes (no
  delay, no loss, instant coupling): the model.

``ignition_delay``: after a start the auger feeds while the bed is not yet burning. The
fuel fed (the balance loses it) collects in the bed of mass M [kg dry]:
dM/dt = m_feed - m_burn. For ``delay_s`` after a start from an unlit bed nothing burns;
then the bed burns at m_burn = M / tau_b, also after a stop (without feed) until it is
empty (burn-out; below 0.1 g it counts as burnt and the bed goes out). The bed holds
m_feed tau_b in steady firing, so the heat release follows the feed with the lag tau_b;
at ignition it holds m_feed delay_s, which flares up if the delay exceeds tau_b (equal at
the lab values and under any strength: at constant feed the heat is the feed delayed). The
excess-air ratio is the controller's (Eq. 9 at the feed rate; the fan keeps the last value
in the burn-out); flue-gas temperature (Eq. 8), composition and losses follow the fuel
that burns. The fan runs (UA_amb,ON) while the controller fires or the bed burns.

- ``delay_s`` [s], linear, lab 90, 0..900.
- ``burnout_time_constant_s`` tau_b [s], linear, lab 90, 0..900.

``flue_gas_lag``: heat exchanger and refractory store heat, so the flue-gas temperature
follows its Eq. 8 value (while the bed burns; the water temperature otherwise) through two
first-order nodes in series, the exchanger surface (tau (1 - r)) and the refractory
(tau r): an S-shaped response of mean delay tau. The losses (Eq. 4) use the lagged
temperature and the heat to the exchanger is the remainder (Eq. 1), so what the cold
exchanger takes from the gas goes to the body: energy is conserved.

- ``time_constant_s`` tau [s], linear, lab 150, 0..3600.
- ``refractory_share`` r [-], shape, lab 0.5, 0..1 (0 or 1: a single first-order lag).

``fuel_energy_bias``: the fuel delivers (1 + b) times the nominal energy per kg (moisture,
fines, unburnt carbon). The boiler's controller acts on the heat it gets, so the heat flows
are the model's while the balance loses 1 / (1 + b) times the mass (lab: 16.3 kg measured
vs 15.0 kg simulated for the 12 kW stationary test, b = 15.0 / 16.3 - 1 = -0.08).

- ``relative_bias`` b [-], linear, lab -0.08, -0.3..0.3.

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

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

EFFECT_NAMES: tuple[str, ...] = (
    "body_heat_diffusion",
    "outlet_sensor_pipe",
    "ignition_delay",
    "flue_gas_lag",
    "fuel_energy_bias",
)

#: Accepted range of ``strength`` (validation); realistic ranges: :func:`strength_ranges`.
STRENGTH_LIMITS = (0.0, 3.0)


@dataclass(frozen=True, slots=True)
class ParamSpec:
    """One physical parameter of an effect.

    Attributes:
        name: key in the profile (unit in the name where it has one).
        lab: value at strength 1 (the lab default).
        scaling: ``linear`` (lab * s), ``inverse`` (lab / s) or ``shape`` (lab, any s).
        lo, hi: accepted range of an explicit value (inclusive).
        integer: the value must be a whole number.
    """

    name: str
    lab: float
    scaling: str
    lo: float
    hi: float
    integer: bool = False

    def scaled(self, strength: float) -> float:
        """The value at ``strength`` (no explicit override)."""
        if self.scaling == "linear":
            return self.lab * strength
        if self.scaling == "inverse":
            return self.lab / strength if strength > 0 else math.inf
        return self.lab


@dataclass(frozen=True, slots=True)
class EffectSpec:
    """An effect: its parameters and the documented range of realistic strengths."""

    name: str
    params: tuple[ParamSpec, ...]
    strength_range: tuple[float, float]

    def param(self, name: str) -> ParamSpec:
        return next(p for p in self.params if p.name == name)


SPECS: dict[str, EffectSpec] = {
    s.name: s
    for s in (
        EffectSpec(
            "body_heat_diffusion",
            (
                ParamSpec("time_constant_s", 250.0, "linear", 0.0, 3600.0),
                ParamSpec("metal_share", 0.40, "shape", 0.05, 0.95),
                ParamSpec("nodes", 3.0, "shape", 1.0, 6.0, integer=True),
            ),
            (0.5, 2.0),
        ),
        EffectSpec(
            "outlet_sensor_pipe",
            (
                ParamSpec("volume_l", 0.25, "linear", 0.0, 5.0),
                ParamSpec("cooling_time_constant_s", 1800.0, "inverse", 1.0, 1e6),
                ParamSpec("coupling_time_constant_s", 18000.0, "linear", 0.0, 1e6),
            ),
            (0.5, 2.0),
        ),
        EffectSpec(
            "ignition_delay",
            (
                ParamSpec("delay_s", 90.0, "linear", 0.0, 900.0),
                ParamSpec("burnout_time_constant_s", 90.0, "linear", 0.0, 900.0),
            ),
            (0.5, 2.0),
        ),
        EffectSpec(
            "flue_gas_lag",
            (
                ParamSpec("time_constant_s", 150.0, "linear", 0.0, 3600.0),
                ParamSpec("refractory_share", 0.5, "shape", 0.0, 1.0),
            ),
            (0.5, 2.0),
        ),
        EffectSpec(
            "fuel_energy_bias",
            (ParamSpec("relative_bias", -0.08, "linear", -0.3, 0.3),),
            (0.5, 2.0),
        ),
    )
}

#: Maximum number of metal nodes of ``body_heat_diffusion``.
MAX_BODY_NODES = 6


class EffectError(ValueError):
    """An ``effects`` entry is malformed; :attr:`key` is its dotted path."""

    def __init__(self, key: str, message: str) -> None:
        super().__init__(f"key '{key}' {message}")
        self.key = key


def strength_ranges() -> dict[str, tuple[float, float]]:
    """Documented range of realistic strengths of each effect (1 = the lab default)."""
    return {name: spec.strength_range for name, spec in SPECS.items()}


def lab_parameters() -> dict[str, dict[str, float]]:
    """Each effect's physical parameters at strength 1 (the lab default)."""
    return {name: {p.name: p.lab for p in spec.params} for name, spec in SPECS.items()}


def _number(key: str, value: Any, lo: float, hi: float, integer: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise EffectError(key, "must be a number")
    value = float(value)
    if not math.isfinite(value) or not lo <= value <= hi:
        raise EffectError(key, f"must be finite and within {lo:g}..{hi:g}")
    if integer and value != int(value):
        raise EffectError(key, "must be a whole number")
    return value


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
        spec = SPECS.get(name)
        if spec is None:
            raise EffectError(
                f"effects.{name}", f"is not a known effect (known: {', '.join(EFFECT_NAMES)})"
            )
        entry = {} if entry is None else entry
        if not isinstance(entry, Mapping):
            raise EffectError(f"effects.{name}", "must be a mapping")
        values: dict[str, float] = {}
        for key, value in entry.items():
            full = f"effects.{name}.{key}"
            if key == "strength":
                values[key] = _number(full, value, *STRENGTH_LIMITS)
                continue
            try:
                p = spec.param(key)
            except StopIteration:
                known = ", ".join(("strength", *(q.name for q in spec.params)))
                raise EffectError(full, f"is not a parameter (known: {known})") from None
            values[key] = _number(full, value, p.lo, p.hi, p.integer)
        out[name] = values
    return out


@dataclass(frozen=True, slots=True)
class EffectSettings:
    """Resolved physical parameters of every effect (the neutral values mean off).

    Attributes (units in the names; see the module docstring):
        body_time_constant_s, body_metal_share, body_nodes: ``body_heat_diffusion``.
        pipe_volume_l, pipe_cooling_time_constant_s, pipe_coupling_time_constant_s:
            ``outlet_sensor_pipe`` (cooling inf: no loss; coupling 0: instant).
        ignition_delay_s, burnout_time_constant_s: ``ignition_delay``.
        flue_time_constant_s, flue_refractory_share: ``flue_gas_lag``.
        fuel_relative_bias: ``fuel_energy_bias``.
    """

    body_time_constant_s: float = 0.0
    body_metal_share: float = 0.40
    body_nodes: int = 3
    pipe_volume_l: float = 0.0
    pipe_cooling_time_constant_s: float = math.inf
    pipe_coupling_time_constant_s: float = 0.0
    ignition_delay_s: float = 0.0
    burnout_time_constant_s: float = 0.0
    flue_time_constant_s: float = 0.0
    flue_refractory_share: float = 0.5
    fuel_relative_bias: float = 0.0

    @property
    def body_on(self) -> bool:
        return self.body_time_constant_s > 0.0

    @property
    def pipe_on(self) -> bool:
        return (
            self.pipe_volume_l > 0.0
            or math.isfinite(self.pipe_cooling_time_constant_s)
            or self.pipe_coupling_time_constant_s > 0.0
        )

    @property
    def ignition_on(self) -> bool:
        return self.ignition_delay_s > 0.0 or self.burnout_time_constant_s > 0.0

    @property
    def flue_on(self) -> bool:
        return self.flue_time_constant_s > 0.0

    @property
    def dynamic(self) -> bool:
        """Any effect that needs the effects-aware plant step (all but the fuel bias)."""
        return self.body_on or self.pipe_on or self.ignition_on or self.flue_on

    @property
    def active(self) -> tuple[str, ...]:
        """Names of the effects that are on."""
        on = (
            self.body_on,
            self.pipe_on,
            self.ignition_on,
            self.flue_on,
            self.fuel_relative_bias != 0.0,
        )
        return tuple(name for name, flag in zip(EFFECT_NAMES, on, strict=True) if flag)


def resolve_effects(effects: Mapping[str, Mapping[str, float]] | None) -> EffectSettings:
    """Physical parameters from a profile's (validated or raw) ``effects`` mapping."""
    checked = check_effects(effects)
    values: dict[str, dict[str, float]] = {}
    for name, entry in checked.items():
        spec = SPECS[name]
        strength = entry.get("strength", 1.0)
        values[name] = {p.name: entry.get(p.name, p.scaled(strength)) for p in spec.params}
    body = values.get("body_heat_diffusion")
    pipe = values.get("outlet_sensor_pipe")
    ign = values.get("ignition_delay")
    flue = values.get("flue_gas_lag")
    bias = values.get("fuel_energy_bias")
    settings = EffectSettings()
    kwargs: dict[str, float | int] = {}
    if body:
        kwargs.update(
            body_time_constant_s=body["time_constant_s"],
            body_metal_share=body["metal_share"],
            body_nodes=int(body["nodes"]),
        )
    if pipe:
        kwargs.update(
            pipe_volume_l=pipe["volume_l"],
            pipe_cooling_time_constant_s=pipe["cooling_time_constant_s"],
            pipe_coupling_time_constant_s=pipe["coupling_time_constant_s"],
        )
    if ign:
        kwargs.update(
            ignition_delay_s=ign["delay_s"], burnout_time_constant_s=ign["burnout_time_constant_s"]
        )
    if flue:
        kwargs.update(
            flue_time_constant_s=flue["time_constant_s"],
            flue_refractory_share=flue["refractory_share"],
        )
    if bias:
        kwargs.update(fuel_relative_bias=bias["relative_bias"])
    return EffectSettings(**{**_asdict(settings), **kwargs})


def _asdict(settings: EffectSettings) -> dict[str, Any]:
    return {name: getattr(settings, name) for name in EffectSettings.__slots__}


def effects_at(strengths: Mapping[str, float]) -> dict[str, dict[str, float]]:
    """An ``effects`` mapping for a profile with the given strengths (names as keys)."""
    for name in strengths:
        if name not in SPECS:
            raise EffectError(f"effects.{name}", "is not a known effect")
    return check_effects({name: {"strength": s} for name, s in strengths.items()})
