"""Boiler parameter set (Table 3 of Carlon et al. 2015) and its validation.

Pure: :func:`params_from_mapping` checks a mapping (as read from a YAML file by
:mod:`rig_emulator.boilers`) and raises :class:`ParameterError` naming the key at fault.
Beyond types and plausible ranges it refuses what physics does not allow, whatever the
ranges: a fuel without net heat, lambda outside 1..:data:`LAMBDA_MAX` (Eq. 9), a flue gas
colder than the water it heats or hotter than its flame (Eq. 8), a boiler that cannot heat
its water at nominal load (the model's own steady state), controller temperatures outside
liquid water.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from rig_emulator.model import constants as k
from rig_emulator.model.boiler import pack_constants
from rig_emulator.model.fuel import Fuel
from rig_emulator.model.steady_state import exchanger_heat, steady_state
from rig_emulator.names import hidden_character, shown

REQUIRED_KEYS: tuple[str, ...] = (
    "name",
    "p_nom_kW",
    "p_max_kW",
    "p_min_kW",
    "p_start_kW",
    "c_therm_kJ_K",
    "vol_water_m3",
    "ua_amb_off_W_K",
    "ua_amb_on_W_K",
    "dt_nom_K",
    "dt_hx_fg_K",
    "dt_hx_wat_K",
    "fac_a_lambda",
    "fac_b_lambda_h_kg",
    "p_el_min_W",
    "p_el_max_W",
    "p_el_off_W",
    "w_el_Wh",
    "fuel",
)
FUEL_KEYS: tuple[str, ...] = ("hhv_dry_kJ_kg", "c", "h", "o", "n", "s", "ash", "moisture")

#: Optional keys and their defaults (the paper's controller and our CO model).
OPTIONAL_DEFAULTS: dict[str, float] = {
    "set_temp_C": 70.0,  # outlet set temperature (Section 2.3)
    "shutoff_temp_C": 85.0,  # cut-out of the water inside the boiler (Section 3.2)
    "restart_temp_C": 55.0,  # restart after a cut-out (Section 3.2.3)
    "startup_duration_s": 900.0,  # firing at Pstart after each start (about 15 min, 3.2.1)
    "co_ppm_at_p_max": 60.0,  # stationary CO at Pmax [ppm, dry] (assumption)
    "co_ppm_at_p_min": 200.0,  # stationary CO at Pmin [ppm, dry] (assumption)
    "co_start_peak_ppm": 1500.0,  # extra CO right after ignition [ppm] (assumption)
    "co_stop_peak_ppm": 600.0,  # extra CO of the burn-out after a stop [ppm] (assumption)
    "co_transient_s": 240.0,  # decay time of the start/stop CO peaks [s] (assumption)
}

#: The water spread of nominal load [K]: outlet at the set temperature, return this much
#: below it (Section 2.3; :attr:`BoilerParams.nominal_flow_kg_h`)
NOMINAL_SPREAD_K = 15.0


class ParameterError(ValueError):
    """A parameter set is incomplete or inconsistent; the message names the key."""


@dataclass(frozen=True, slots=True)
class BoilerParams:
    """Parameters of the Type 869 one-node boiler model.

    Power figures are firing powers of the burner on a net (dry-fuel LHV) basis, the basis
    manufacturers document; the model converts them to the gross basis of Eq. 3 with
    HHV/LHV of the fuel. With the paper's 12 kW figures this gives about 85 % of Q_fuel to
    water at Pmax, as the paper reports (Section 3.2.1).

    Attributes:
        name: label of the boiler.
        p_nom_kW: nominal heat output to water [kW].
        p_max_kW, p_min_kW, p_start_kW: firing power at maximum, minimum, start-up [kW].
        c_therm_kJ_K: thermal capacity of the structure [kJ/K].
        vol_water_m3: water volume inside the boiler [m3].
        ua_amb_off_W_K, ua_amb_on_W_K: loss coefficient to the room, idle and firing [W/K].
        dt_nom_K, dt_hx_fg_K, dt_hx_wat_K: empirical delta-T coefficients of Eq. 8 [K].
        fac_a_lambda [-], fac_b_lambda_h_kg [h/kg]: excess-air coefficients of Eq. 9.
        p_el_min_W, p_el_max_W, p_el_off_W: electric power at 30 %, 100 % load, stand-by [W].
        w_el_Wh: electric energy for ignition, per start [Wh].
        fuel: the fuel burnt.
        set_temp_C, shutoff_temp_C, restart_temp_C: controller temperatures [C].
        startup_duration_s: duration of the start-up at Pstart [s].
        co_*: parameters of the CO model (:func:`rig_emulator.model.boiler.co_stationary_ppm`).
    """

    name: str
    p_nom_kW: float
    p_max_kW: float
    p_min_kW: float
    p_start_kW: float
    c_therm_kJ_K: float
    vol_water_m3: float
    ua_amb_off_W_K: float
    ua_amb_on_W_K: float
    dt_nom_K: float
    dt_hx_fg_K: float
    dt_hx_wat_K: float
    fac_a_lambda: float
    fac_b_lambda_h_kg: float
    p_el_min_W: float
    p_el_max_W: float
    p_el_off_W: float
    w_el_Wh: float
    fuel: Fuel
    set_temp_C: float = OPTIONAL_DEFAULTS["set_temp_C"]
    shutoff_temp_C: float = OPTIONAL_DEFAULTS["shutoff_temp_C"]
    restart_temp_C: float = OPTIONAL_DEFAULTS["restart_temp_C"]
    startup_duration_s: float = OPTIONAL_DEFAULTS["startup_duration_s"]
    co_ppm_at_p_max: float = OPTIONAL_DEFAULTS["co_ppm_at_p_max"]
    co_ppm_at_p_min: float = OPTIONAL_DEFAULTS["co_ppm_at_p_min"]
    co_start_peak_ppm: float = OPTIONAL_DEFAULTS["co_start_peak_ppm"]
    co_stop_peak_ppm: float = OPTIONAL_DEFAULTS["co_stop_peak_ppm"]
    co_transient_s: float = OPTIONAL_DEFAULTS["co_transient_s"]

    @property
    def capacity_kJ_K(self) -> float:
        """Capacity of the one node [kJ/K]: structure plus water (digest section 1)."""
        return self.c_therm_kJ_K + self.vol_water_m3 * k.RHO_WATER * k.CP_WATER

    @property
    def nominal_flow_kg_h(self) -> float:
        """Water flow of nominal load with a 15 K spread [kg/h] (Section 2.3)."""
        return self.p_nom_kW * 3600.0 / (k.CP_WATER * NOMINAL_SPREAD_K)

    def firing_points(self) -> tuple[tuple[str, float], ...]:
        """The firing powers the burner runs at [kW, net], named: Pmax (nominal load), Pmin
        and, where it differs from Pmax, Pstart (the start-up); Eq. 8 and 9 are linear in
        the fuel flow between them."""
        points = (("Pmax", self.p_max_kW), ("Pmin", self.p_min_kW))
        if self.p_start_kW != self.p_max_kW:
            points += (("Pstart", self.p_start_kW),)
        return points

    def to_mapping(self) -> dict[str, Any]:
        """The parameter set as a plain mapping of CONTRACT section 2 form."""
        out: dict[str, Any] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "fuel":
                value = {key: getattr(value, key) for key in FUEL_KEYS}
            out[f.name] = value
        return out


#: The plausibility check of the standing losses: at this much above the room ...
UA_CHECK_DT_K = 100.0
#: ... a boiler loses at most this share of its nominal power.
UA_MAX_SHARE = 0.5


def _number(value: Any, key: str, source: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ParameterError(f"{source}: key '{key}' must be a number, got {value!r}")
    try:
        x = float(value)
    except OverflowError:  # an integer of hundreds of digits
        raise ParameterError(f"{source}: key '{key}' is too large to be a number") from None
    if not math.isfinite(x):
        raise ParameterError(f"{source}: key '{key}' must be finite, got {value!r}")
    return x


def params_from_mapping(data: Any, source: str = "<parameters>") -> BoilerParams:
    """Validate ``data`` and build :class:`BoilerParams`.

    Raises:
        ParameterError: a key is missing, unknown, of the wrong type or out of range; the
            message names ``source`` and the key.
    """
    if not isinstance(data, Mapping):
        raise ParameterError(
            f"{source}: expected a mapping of parameters, got {type(data).__name__}"
        )
    _check_keys(data, REQUIRED_KEYS, OPTIONAL_DEFAULTS, "", source)
    name = data["name"]
    if not isinstance(name, str) or not name:
        raise ParameterError(f"{source}: key 'name' must be a non-empty string")
    if len(name) > NAME_MAX_CHARS:  # (100,000 characters went into every line naming it)
        raise ParameterError(
            f"{source}: key 'name' is {len(name)} characters long: a boiler's name is at most "
            f"{NAME_MAX_CHARS}"
        )
    hidden = hidden_character(name)
    if hidden is not None:  # (U+202E and a line break were printed raw: a stranger's probe)
        raise ParameterError(f"{source}: key 'name' '{shown(name)}' holds {hidden}")
    values: dict[str, Any] = {"name": name}
    for key in (*REQUIRED_KEYS, *OPTIONAL_DEFAULTS):
        if key in ("name", "fuel") or key not in data:
            continue
        values[key] = _number(data[key], key, source)

    fuel_data = data["fuel"]
    if not isinstance(fuel_data, Mapping):
        raise ParameterError(f"{source}: key 'fuel' must be a mapping")
    _check_keys(fuel_data, FUEL_KEYS, {}, "fuel.", source)
    fuel_values = {key: _number(fuel_data[key], f"fuel.{key}", source) for key in FUEL_KEYS}
    for key in FUEL_KEYS[1:]:
        if not 0.0 <= fuel_values[key] < 1.0:
            raise ParameterError(f"{source}: key 'fuel.{key}' must be a fraction in [0, 1)")
    if fuel_values["hhv_dry_kJ_kg"] <= 0:
        raise ParameterError(f"{source}: key 'fuel.hhv_dry_kJ_kg' must be positive")
    _check_unit(fuel_values["hhv_dry_kJ_kg"], HHV_DRY_RANGE_KJ_KG, "fuel.hhv_dry_kJ_kg", source)
    total = sum(fuel_values[key] for key in ("c", "h", "o", "n", "s", "ash"))
    if abs(total - 1.0) > 0.02:
        raise ParameterError(
            f"{source}: key 'fuel' fractions c+h+o+n+s+ash sum to {total:.4f}, expected 1"
        )
    values["fuel"] = Fuel(**fuel_values)
    _check_net_heat(values["fuel"], source)

    positive = (
        "p_nom_kW",
        "p_max_kW",
        "p_min_kW",
        "p_start_kW",
        "c_therm_kJ_K",
        "vol_water_m3",
        "ua_amb_off_W_K",
        "ua_amb_on_W_K",
        "dt_nom_K",
        "startup_duration_s",
    )
    for key in (*positive, "co_transient_s"):  # (0 divided by zero in the bench: a probe)
        if key in values and values[key] <= 0:
            raise ParameterError(f"{source}: key '{key}' must be positive, got {values[key]}")
    _check_unit(values["p_nom_kW"], P_NOM_RANGE_KW, "p_nom_kW", source)
    for key, per_kW in PER_KW_RANGES.items():
        _check_unit(values[key] / values["p_nom_kW"], per_kW, key, source, values[key])
    # (a negative CO was served as a negative reading: a stranger's probe)
    nonnegative = ("p_el_min_W", "p_el_max_W", "p_el_off_W", "w_el_Wh")
    co = ("co_ppm_at_p_max", "co_ppm_at_p_min", "co_start_peak_ppm", "co_stop_peak_ppm")
    for key in (*nonnegative, *co):
        if values.get(key, 0.0) < 0:
            raise ParameterError(f"{source}: key '{key}' must not be negative")
    for key in co:  # (1e300 ppm was served: a re-probe)
        if values.get(key, 0.0) > 1e6:
            raise ParameterError(f"{source}: key '{key}' is above 1e6 ppm, the whole flue gas")
    if values["p_min_kW"] > values["p_max_kW"]:
        raise ParameterError(
            f"{source}: key 'p_min_kW' ({values['p_min_kW']}) exceeds 'p_max_kW' "
            f"({values['p_max_kW']})"
        )
    if not values["p_min_kW"] <= values["p_nom_kW"] <= values["p_max_kW"]:
        raise ParameterError(
            f"{source}: key 'p_nom_kW' ({values['p_nom_kW']}) must lie between 'p_min_kW' "
            f"({values['p_min_kW']}) and 'p_max_kW' ({values['p_max_kW']})"
        )
    for key in ("ua_amb_off_W_K", "ua_amb_on_W_K"):
        # a boiler that loses half its nominal power to the room 100 K above it is no
        # boiler (the bench's: 1-3 W/K, Table 3; at most 0.5 p_nom / 100 K)
        if values[key] * UA_CHECK_DT_K > UA_MAX_SHARE * values["p_nom_kW"] * 1000.0:
            raise ParameterError(
                f"{source}: key '{key}' ({values[key]:g} W/K) would lose more than "
                f"{UA_MAX_SHARE:.0%} of p_nom_kW to the room at {UA_CHECK_DT_K:g} K above it"
            )
    for low, high, why in ORDERED_PAIRS:
        if values[low] > values[high]:
            raise ParameterError(
                f"{source}: key '{low}' ({values[low]:g}) exceeds '{high}' "
                f"({values[high]:g}): {why}"
            )
    if values["p_max_kW"] > P_MAX_OVER_NOM * values["p_nom_kW"]:  # (13200 with p_nom 12,
        hint = (  # a lambda curve flat enough: accepted; a re-probe)
            " (written in W?)"
            if values["p_max_kW"] / 1e3 <= P_MAX_OVER_NOM * values["p_nom_kW"]
            else ""
        )
        raise ParameterError(
            f"{source}: key 'p_max_kW' ({values['p_max_kW']:g}) is over {P_MAX_OVER_NOM:g} x "
            f"p_nom_kW ({values['p_nom_kW']:g}){hint}"
        )
    if values["p_start_kW"] > values["p_max_kW"] * 1.5:
        raise ParameterError(f"{source}: key 'p_start_kW' is above 1.5 x p_max_kW")
    _check_electricity(values, source)
    startup_s = values.get("startup_duration_s", 0.0)
    if startup_s > STARTUP_MAX_S:  # (1e12 s was taken: a probe)
        raise ParameterError(
            f"{source}: key 'startup_duration_s' ({startup_s:g}) is over "
            f"{STARTUP_MAX_S / 3600:g} h, longer than any start-up"
        )
    params = BoilerParams(**values)
    for key in CONTROLLER_TEMPERATURES:
        _check_liquid(getattr(params, key), key, source)
    if not params.restart_temp_C < params.set_temp_C < params.shutoff_temp_C:
        raise ParameterError(
            f"{source}: keys 'restart_temp_C' < 'set_temp_C' < 'shutoff_temp_C' must hold"
        )
    _check_lambda(params, source)
    _check_flue_gas(params, source)
    return params


#: The longest boiler name [characters]: a maker, a model and a lab's note fit in it; a
#: name of 100,000 characters was taken into every message and meta file (a stranger's probe).
NAME_MAX_CHARS = 200
#: The most of the nominal firing power the auxiliaries may draw at full load [-]: fans,
#: auger and controller draw 0.3-1 % (the bench's boilers: 50 W of 12 kW); 20 % is no
#: boiler, and 7 MW of stand-by went into a log unremarked (a stranger's probe).
P_EL_MAX_SHARE = 0.2
#: The most electric energy one ignition may take, in hours of the nominal firing power
#: [h]: an igniter of a few hundred watts for minutes (the 12-kW boiler's 126 Wh: 0.01 h).
W_EL_MAX_H = 0.1
#: The longest start-up [s]: minutes to an hour in the paper's tests.
STARTUP_MAX_S = 86_400.0


def _check_electricity(values: dict[str, float], source: str) -> None:
    """The auxiliaries' power and the ignition's energy within what a boiler draws (see
    :data:`P_EL_MAX_SHARE`, :data:`W_EL_MAX_H`; the stand-by below full load's is one of
    :data:`ORDERED_PAIRS`)."""
    nominal_W = values["p_nom_kW"] * 1000.0
    for key, most, what in (
        ("p_el_max_W", P_EL_MAX_SHARE * nominal_W, f"{P_EL_MAX_SHARE:.0%} of p_nom_kW"),
        ("w_el_Wh", W_EL_MAX_H * nominal_W, f"p_nom_kW for {W_EL_MAX_H * 60:g} min"),
    ):
        if values[key] > most:
            raise ParameterError(
                f"{source}: key '{key}' ({values[key]:g}) is above {what}: another unit?"
            )


#: Pairs whose first may not exceed the second, and why (a stranger's review: check took
#: UA_on above UA_off, a negative draught-air heat in Eq. 16, and an electricity that falls
#: with the load)
ORDERED_PAIRS = (
    (
        "ua_amb_on_W_K",
        "ua_amb_off_W_K",
        "the idle boiler loses what the firing one does and the draught air's heat on top "
        "(Eq. 14-16)",
    ),
    ("p_el_min_W", "p_el_max_W", "the auxiliary power at 30 % load is below that at 100 %"),
    # (7 MW of stand-by went into a log unremarked: a stranger's probe)
    ("p_el_off_W", "p_el_max_W", "the stand-by draws less than the auxiliaries at full load"),
)


#: Plausible ranges that tell a value in another unit, with the unit it looks like: (low,
#: high, factor by which the value exceeds the range in that unit, its name). A wrong unit
#: is off by 1000 where these keys are concerned, far outside; the ranges are wide enough
#: for any boiler Type 869 describes (small-scale biomass, a few to a few hundred kW).
#: HHV of dry solid fuels: wood and agro-pellets 17-21 MJ/kg, lignite to hard coal 25-30.
HHV_DRY_RANGE_KJ_KG = (12_000.0, 35_000.0, 1e-3, "MJ/kg")
#: nominal firing power: a pellet boiler of 2 kW to a wood-chip boiler of 2 MW
P_NOM_RANGE_KW = (1.0, 2_000.0, 1e3, "W")
#: the most the maximum firing power may exceed the nominal by (the bench's boilers: 1.1-1.15)
P_MAX_OVER_NOM = 2.0
#: per kW of nominal power: the thermal capacity of the boiler's mass (the bench's boilers:
#: 80 kJ/K for 6 and 12 kW, 7-13 kJ/K per kW; steel and cast-iron boilers 2-50) and its
#: water volume (2.5-5 l per kW; buffer-integrated boilers up to some 50 l per kW)
PER_KW_RANGES: dict[str, tuple[float, float, float, str]] = {
    "c_therm_kJ_K": (0.5, 500.0, 1e3, "J/K"),
    "vol_water_m3": (0.0002, 0.1, 1e3, "litres"),
}


def _check_unit(
    value: float,
    bounds: tuple[float, float, float, str],
    key: str,
    source: str,
    shown: float | None = None,
) -> None:
    """Refuse a value outside its plausible range (:data:`HHV_DRY_RANGE_KJ_KG` and the
    like; per kW of nominal power where ``shown``, the value as written, is given), saying
    which unit it looks like it was written in."""
    low, high, factor, unit = bounds
    slack = 1e-9 * max(abs(low), abs(high))  # a bound met to rounding is met
    if low - slack <= value <= high + slack:
        return
    per = "" if shown is None else f", {value:.4g} per kW of p_nom_kW,"
    hint = f" (written in {unit}?)" if low <= value / factor <= high else ""
    if shown is not None and not hint and low <= value * 1e3 <= high:  # per kW of a p_nom
        hint = " (p_nom_kW and the other powers written in W?)"  # in W (a re-probe)
    raise ParameterError(
        f"{source}: key '{key}' = {value if shown is None else shown:g}{per} lies outside "
        f"the plausible {low:g}..{high:g}{hint}"
    )


def _dry_fuel_kg_h(params: BoilerParams, firing_kW: float) -> float:
    """Dry fuel flow [kg/h] of a firing power on the net basis [kW]."""
    return firing_kW * 3600.0 / params.fuel.lhv_dry_kJ_kg


def _check_keys(
    section: Mapping[Any, Any],
    required: tuple[str, ...],
    optional: Mapping[str, Any],
    prefix: str,
    source: str,
) -> None:
    """Refuse a section (the file, or ``fuel``: ``prefix``) with an unknown or a missing
    key. An unknown key is named first, with the required key it leaves missing: a typo
    ``ashh`` was reported as only the missing ``fuel.ash`` (a stranger's probe)."""
    unknown = [key for key in section if key not in required and key not in optional]
    missing = [key for key in required if key not in section]
    if unknown:
        key = unknown[0]
        text = shown(key) if isinstance(key, str) else repr(key)
        also = f" (and required key '{prefix}{missing[0]}' is missing)" if missing else ""
        raise ParameterError(f"{source}: unknown key '{prefix}{text}'{also}")
    if missing:
        raise ParameterError(f"{source}: missing required key '{prefix}{missing[0]}'")


#: The controller's temperatures (set, shut-off, restart), which the boiler's water reaches
CONTROLLER_TEMPERATURES = ("set_temp_C", "shutoff_temp_C", "restart_temp_C")
#: The water of a hot-water boiler is liquid between these [C]: it freezes at 0 C (the one
#: node holds liquid water of constant heat capacity: the model has no ice), and EN 303-5's
#: boilers work at up to 110 C, above which the water of a heating system at its usual
#: pressure boils
LIQUID_WATER_C = (0.0, 110.0)
#: Absolute zero [C]: no temperature lies below it
ABSOLUTE_ZERO_C = -k.T_NORMAL_K


def _check_liquid(value: float, key: str, source: str) -> None:
    """Refuse a controller temperature the boiler's water cannot have (-300 C was
    accepted: a stranger's probe)."""
    low, high = LIQUID_WATER_C
    if value < ABSOLUTE_ZERO_C:
        why = f"below absolute zero ({ABSOLUTE_ZERO_C:g} C)"
    elif value <= low:
        why = f"at or below {low:g} C, where the boiler's water freezes"
    elif value > high:
        why = f"above {high:g} C, where the boiler's water boils (EN 303-5: up to {high:g} C)"
    else:
        return
    raise ParameterError(f"{source}: key '{key}' ({value:g} C) is {why}")


def _check_net_heat(fuel: Fuel, source: str) -> None:
    """Refuse a fuel whose water (the moisture, and before it the water its hydrogen forms)
    takes more heat to evaporate than the dry fuel gives: its net calorific value as
    received, (1 - w) LHV_dry - w dH_vap, is not positive, so burning it cannot heat
    anything (moisture 0.9 gave -4.8 kW to the water, 0.99 a boiler at -163 C: a stranger's
    probe). That is the physical bound; pellets of EN ISO 17225-2 hold at most 10 % and
    wood chips up to about 55 %, but wetter fuel is a real (modelled) effect, so the
    standard's figure is no reason to refuse a file."""
    if fuel.lhv_dry_kJ_kg <= 0.0:  # the water formed from the hydrogen alone
        raise ParameterError(
            f"{source}: keys 'fuel.h' ({fuel.h:g})/'fuel.hhv_dry_kJ_kg' "
            f"({fuel.hhv_dry_kJ_kg:g}) leave the dry fuel no net heat: evaporating the water "
            f"its hydrogen forms takes more than its gross heat (LHV {fuel.lhv_dry_kJ_kg:.0f} "
            "kJ/kg)"
        )
    net = (1.0 - fuel.moisture) * fuel.lhv_dry_kJ_kg - fuel.moisture * k.DH_VAP_WATER
    if net <= 0.0:
        limit = fuel.lhv_dry_kJ_kg / (fuel.lhv_dry_kJ_kg + k.DH_VAP_WATER)
        raise ParameterError(
            f"{source}: key 'fuel.moisture' ({fuel.moisture:g}) leaves the fuel no net heat: "
            f"evaporating its water takes more than the dry fuel gives ({net:.0f} kJ/kg as "
            f"received); it must be below {limit:.3f}"
        )


#: The most excess air a firing boiler runs at: O2 about 19 % of the dry gas, where the
#: balance counts a row as firing no more (an analyser reading air fits lambda 16). The
#: parameter files and the calibration (:mod:`hil_client.analysis.calibrate`) share it.
LAMBDA_MAX = 10.0


def _check_lambda(params: BoilerParams, source: str) -> None:
    """Refuse an Eq. 9 that gives lambda outside 1..:data:`LAMBDA_MAX` at a firing power
    of :meth:`BoilerParams.firing_points` (linear in the fuel flow, so between them too):
    at or below 1 the combustion is incomplete; far above, the flame is air (facA 100 and
    facB 20 gave water at 3 C and -107 C while firing: a stranger's probe)."""
    for label, firing_kW in params.firing_points():
        lam = params.fac_a_lambda + params.fac_b_lambda_h_kg * _dry_fuel_kg_h(params, firing_kW)
        if 1.0 < lam <= LAMBDA_MAX:
            continue
        why = (
            "lambda <= 1 (incomplete combustion)"
            if lam <= 1.0
            else f"lambda above {LAMBDA_MAX:g} (O2 near air's: no flame)"
        )
        raise ParameterError(
            f"{source}: keys 'fac_a_lambda'/'fac_b_lambda_h_kg' give {why} in the modulation "
            f"range: {lam:.3g} at {label} ({firing_kW:g} kW, Eq. 9)"
        )


#: The room of the reference operating point [C] (a boiler room; the bench's lab)
REFERENCE_ROOM_C = 20.0


def _check_flue_gas(params: BoilerParams, source: str) -> None:
    """Refuse a flue-gas temperature (Eq. 8) the exchanger cannot give, and a boiler that
    cannot heat its water at nominal load.

    At each firing power of :meth:`BoilerParams.firing_points`, with no flow and with the
    nominal flow (Eq. 8 is linear in the flow between them), at the nominal operating point
    (return :data:`NOMINAL_SPREAD_K` below the set temperature, room
    :data:`REFERENCE_ROOM_C`): the flue gas leaves hotter than the return water it heats
    (else the water would heat the gas), and colder than its flame, i.e. its losses (Eq.
    4-6) stay below the fuel's heat (else the exchanger would take heat from the water:
    dt_nom_K 2000 gave a flue gas of 2055 C and -1.3 kW to the water, a stranger's probe).
    Then the model's own steady state at nominal load must deliver heat to the water."""
    c = pack_constants(params)
    t_in = params.set_temp_C - NOMINAL_SPREAD_K
    nominal = params.nominal_flow_kg_h
    for label, firing_kW in params.firing_points():
        for flow, flow_label in ((nominal, "nominal flow"), (0.0, "no flow")):
            q_hx, q_fuel, q_fg, t_fg = exchanger_heat(c, firing_kW, flow, t_in, REFERENCE_ROOM_C)
            if t_fg > t_in and q_hx > 0.0:
                continue
            too_cold = t_fg <= t_in
            # the keys whose terms of Eq. 8 push it that way, the largest first (m_fuel,nom
            # is the fuel at Pmax: the fuel flows are as the firing powers)
            terms = {
                "dt_nom_K": params.dt_nom_K,
                "dt_hx_fg_K": params.dt_hx_fg_K * (1.0 - firing_kW / params.p_max_kW),
                "dt_hx_wat_K": params.dt_hx_wat_K * (1.0 - flow / nominal),
            }
            keys = sorted(
                (key for key, term in terms.items() if term != 0.0 and (term < 0.0) == too_cold),
                key=lambda key: abs(terms[key]),
                reverse=True,
            )
            where = f"at {label} ({firing_kW:g} kW) and {flow_label}"
            why = (
                f"colder than the return water ({t_in:g} C) it heats"
                if too_cold
                else f"carrying off {q_fg:.3g} kW of the fuel's {q_fuel:.3g} kW: hotter than "
                "its flame"
            )
            named = "/".join(f"'{key}'" for key in keys)
            verb = "give" if len(keys) > 1 else "gives"
            raise ParameterError(
                f"{source}: key{'s' if len(keys) > 1 else ''} {named} {verb} a flue gas of "
                f"{t_fg:.0f} C {where} (Eq. 8), {why}"
            )
    ss = steady_state(c, nominal, t_in, REFERENCE_ROOM_C)
    if not ss.q_water_kW > 0.0:
        raise ParameterError(
            f"{source}: keys 'dt_nom_K'/'ua_amb_on_W_K': at nominal load ({nominal:.0f} kg/h, "
            f"return {t_in:g} C, room {REFERENCE_ROOM_C:g} C) the boiler delivers "
            f"{ss.q_water_kW:.3g} kW to the water: its exchanger's {ss.q_hx_kW:.3g} kW do not "
            "cover its loss to the room"
        )
