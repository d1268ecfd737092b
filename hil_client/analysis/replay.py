"""A lab log prepared for the diagnosis: inputs, lab signals, and the model replaying it.

The calibrated one-node model (Type 869) runs with the log's measured inputs (water flow,
return and room temperature) and with the combustion the lab observed
(:mod:`hil_client.analysis.firing`) as its on/off command, as the paper validated it
(Carlon et al. 2015, Section 3.2): the real boiler's own restart rule and start-up
sequence are not the model's and are not what the diagnosis looks for. The model's
thermostat cut-out is lifted for the replay (shut-off 99 C) so it burns whenever the lab
burned; within a burn it modulates to its set temperature as Type 869 does.

Predictions include the response times of the bench's sensors, so a thermowell's lag is
not mistaken for an effect: each as the calibration log shows it, at most its data sheet's
(:data:`SENSOR_TAU_S`; :func:`sensor_lags`). A probe faster than its data sheet (or a log
with no lags at all, as the emulator's clean profile writes) was replayed with the sheet's
lag, and its first seconds after each start read as a gap no effect explains.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hil_client.analysis.augment import first_order_lag
from hil_client.analysis.firing import Firing, observe_firing
from hil_client.analysis.logio import LabLog, LogError, fill_gaps
from hil_client.analysis.phases import Phases
from rig_emulator.model import pack_constants
from rig_emulator.model.layout import K_SHUTOFF
from rig_emulator.model.params import BoilerParams
from rig_emulator.model.simulate import simulate
from rig_emulator.model.water_heat import heat_to_water_kW

SIGNALS = (
    "boiler_water_temp_C",
    "water_out_temp_C",
    "heat_to_water_kW",
    "flue_gas_temp_C",
    "fuel_cum_kg",
)
#: Response times of the bench's sensors [s] (thermowells, duct probe; data sheets): the
#: most a log's own can be (:func:`sensor_lags`).
SENSOR_TAU_S = {
    "boiler_water_temp_C": 10.0,
    "water_out_temp_C": 4.0,
    "water_in_temp_C": 4.0,
    "flue_gas_temp_C": 8.0,
}
#: Rows further than this from any start or stop of the burner are "settled" [s].
SETTLED_AFTER_S = 1800.0
REPLAY_SHUTOFF_C = 99.0


@dataclass
class Case:
    """One log prepared for the diagnosis (see the module docstring)."""

    log: LabLog
    phases: Phases
    params: BoilerParams
    t: np.ndarray
    dt: np.ndarray
    flow: np.ndarray
    t_in: np.ndarray
    room: np.ndarray
    firing: Firing
    lab: dict[str, np.ndarray]
    model: dict[str, np.ndarray]  # replay outputs by name (model.layout.OUTPUT_FIELDS)
    balance: np.ndarray  # the balance's reading without refills, gaps kept [kg]
    settled: np.ndarray  # test-phase rows far from any start or stop, with flow
    #: fuel the burner's start-up program feeds before the flame by design, as received
    #: (its manual) [kg]: not an ignition delay (0: not documented)
    ignition_charge_kg: float = 0.0
    #: the response time of each sensor as the replay applies it [s] (:func:`sensor_lags`)
    sensor_tau_s: dict[str, float] = field(default_factory=lambda: dict(SENSOR_TAU_S))
    _lag_cache: dict = field(default_factory=dict)
    _memo: dict = field(default_factory=dict)

    @property
    def transitions(self) -> np.ndarray:
        return np.sort(np.concatenate([self.firing.starts, self.firing.stops]))

    def memo(self, key: tuple, compute):
        """What ``compute()`` gives for this log, computed once (the log does not change)."""
        if key not in self._memo:
            self._memo[key] = compute()
        return self._memo[key]

    def lagged(self, x_name: str, x: np.ndarray, tau_s: float) -> np.ndarray:
        """``x`` through a first-order lag (cached by name and rounded tau)."""
        key = (x_name, round(float(tau_s), 2))
        if key not in self._lag_cache:
            if len(self._lag_cache) > 256:
                self._lag_cache.clear()
            self._lag_cache[key] = first_order_lag(x, self.dt, float(tau_s))
        return self._lag_cache[key]

    def fuel_cum(self, scale: float = 1.0) -> np.ndarray:
        """The model's cumulative fuel as the balance sees it [kg as received, ash stays]."""
        per_kg = self.params.fuel.balance_loss_per_kg_dry
        fuel = np.cumsum(self.model["fuel_dry_kg_h"] * self.dt) / 3600.0 * per_kg * scale
        return fuel - fuel[0]

    def base_prediction(self) -> dict[str, np.ndarray]:
        """The calibrated model's prediction of every lab signal (sensor lags included)."""
        node = self.model["t_boiler_C"]
        tau = self.sensor_tau_s
        return {
            "boiler_water_temp_C": self.lagged("node", node, tau["boiler_water_temp_C"]),
            "water_out_temp_C": self.lagged("node", node, tau["water_out_temp_C"]),
            "heat_to_water_kW": heat_to_water_kW(self.flow, self.t_in, node),
            "flue_gas_temp_C": self.lagged(
                "t_fg", self.model["t_flue_gas_C"], tau["flue_gas_temp_C"]
            ),
            "fuel_cum_kg": self.fuel_cum(),
        }


def _filled(log: LabLog, name: str) -> np.ndarray:
    values = log[name]
    if np.isnan(values).all():
        raise LogError(f"{log.path}: column '{name}' has no values")
    return fill_gaps(values, log.t)


def _step_lengths(t: np.ndarray) -> np.ndarray:
    """Each row's step [s]: the time since the row before (the first: the median step)."""
    if len(t) < 2:
        raise LogError("the log has fewer than two rows")
    steps = np.diff(t)
    return np.concatenate(([float(np.median(steps))], steps))


def prepare(
    log: LabLog,
    phases: Phases,
    params: BoilerParams,
    ignition_charge_kg: float = 0.0,
    sensor_tau_s: dict[str, float] | None = None,
) -> Case:
    """Fill gaps, observe the firing, and replay the log through the model
    (``ignition_charge_kg``: :attr:`Case.ignition_charge_kg`; ``sensor_tau_s``: the
    sensors' response times, None: as this log shows them, :func:`sensor_lags`)."""
    t = log.t
    dt = _step_lengths(t)
    # (an empty flow column ran the model at zero flow and named an effect: a probe)
    flow = np.clip(_filled(log, "water_flow_kg_h"), 0.0, None)
    t_in = _filled(log, "water_in_temp_C")
    room = _filled(log, "room_temp_C")
    water = _filled(log, "boiler_water_temp_C")
    out_t = _filled(log, "water_out_temp_C")
    balance = log.balance_without_refills()
    if np.isnan(balance).all():
        raise LogError(f"{log.path}: column 'balance_mass_kg' has no values")
    mass = fill_gaps(balance, t)
    lab = {
        "boiler_water_temp_C": water,
        "water_out_temp_C": out_t,
        "heat_to_water_kW": heat_to_water_kW(flow, t_in, out_t),
        "flue_gas_temp_C": _filled(log, "flue_gas_temp_C"),
        "fuel_cum_kg": mass[0] - mass,
    }
    firing = observe_firing(log)
    c = pack_constants(params)
    # the lab's burner decides when it burns: the model does not cut out on its own (the
    # start-up's hand-over keeps the boiler's own shut-off, K_HANDOVER_LIMIT)
    c[K_SHUTOFF] = max(params.shutoff_temp_C, REPLAY_SHUTOFF_C)
    model = simulate(c, float(water[0]), dt, flow, t_in, room, firing.burning)
    test = phases.mask("test", t)
    settled = test.copy()
    for i in np.concatenate([firing.starts, firing.stops]):
        settled &= np.abs(t - t[i]) > SETTLED_AFTER_S
    if test.any():
        settled &= flow > 0.3 * float(np.median(flow[test]))
    if settled.sum() < 60:
        settled = test if test.sum() >= 60 else np.ones(len(t), bool)
    if sensor_tau_s is None:
        sensor_tau_s = sensor_lags(lab, model, dt)
    return Case(
        log,
        phases,
        params,
        t,
        dt,
        flow,
        t_in,
        room,
        firing,
        lab,
        model,
        balance,
        settled,
        ignition_charge_kg,
        dict(sensor_tau_s),
    )


#: Where each lagged signal comes from in the replay's outputs.
_LAGGED_FROM = {
    "boiler_water_temp_C": "t_boiler_C",
    "water_out_temp_C": "t_boiler_C",
    "flue_gas_temp_C": "t_flue_gas_C",
}


def sensor_lags(
    lab: dict[str, np.ndarray], model: dict[str, np.ndarray], dt: np.ndarray
) -> dict[str, float]:
    """Each sensor's response time as a log shows it [s]: of 0 to its data sheet's
    (:data:`SENSOR_TAU_S`, in eighths), the one whose lag of the replay comes closest to
    the reading (least squares over the log). Only the sheet's range is searched: what is
    slower than the probe (a pipe, a store in the flue) is an effect, for the candidates to
    read, not the sensor's."""
    out = {}
    for signal, tau_max in SENSOR_TAU_S.items():
        source = _LAGGED_FROM.get(signal)
        if source is None:  # the return's sensor: an input of the replay, not predicted
            out[signal] = tau_max
            continue
        reading, x = lab[signal], model[source]
        grid = np.linspace(0.0, tau_max, 9)
        sse = [float(np.nansum((reading - first_order_lag(x, dt, tau)) ** 2)) for tau in grid]
        out[signal] = float(grid[int(np.argmin(sse))])
    return out
