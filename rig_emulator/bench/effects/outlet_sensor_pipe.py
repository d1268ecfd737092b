"""``outlet_sensor_pipe``: the forward sensor sits about 30 cm down the exit pipe.

The pipe is plug flow: the water at the sensor left the boiler one pipe content of flow ago
(a transport delay rho V / m_w that grows as the flow falls). Every parcel in the pipe
(water and wall, its own small capacity) relaxes toward T_c = (k_b T_boiler + k_r T_room) /
(k_b + k_r) at the rate k_b + k_r: k_r = 1 / tau_r is the wall's loss to the room, k_b =
1 / tau_b the conduction along the pipe from the boiler. While water flows a parcel stays a
few seconds and loses a few hundredths of a kelvin; once circulation stops the stagnant
parcel at the sensor cools toward T_c within about tau_r, fast against the boiler
(C / UA_amb,OFF of about 20 h), so the forward reading falls below the boiler water after
t3. Only the forward reading (``water_out_temp_C``) is affected; the boiler, its water
temperature and the loop are not. At strength s the stagnant sensor settles at
T_room + (T_boiler - T_room) / (1 + 10 s^2): 9 % of the way back to the boiler at s = 1,
nearly the room; as s goes to 0 the pipe vanishes (no delay, no loss, instant coupling):
the model.

Numerics: a history of the water that entered the pipe (cumulated mass, temperature, time;
rows ``H_*`` of :data:`N_HISTORY` entries), searched forward for the parcel now at the
sensor (amortised O(1) per step).

Stage: ``forward_sensor``.
"""

from __future__ import annotations

import math

from numba import njit

from rig_emulator.bench.effects._spec import EffectSpec, ParamSpec
from rig_emulator.model.constants import RHO_WATER
from rig_emulator.model.layout import index_of

CONSTANTS = (
    "on",
    "water_kg",  # water in the pipe up to the sensor
    "room_rate_1_s",  # relaxation rate toward the room
    "boiler_rate_1_s",  # relaxation rate toward the boiler water (inf: instant)
)
C = index_of(CONSTANTS)
C_ON, C_MASS, C_K_ROOM, C_K_BOILER = (
    C["on"], C["water_kg"], C["room_rate_1_s"], C["boiler_rate_1_s"]
)  # fmt: skip

STATE = (
    "sensor_C",  # temperature of the parcel at the sensor
    "cumulated_kg",  # cumulated mass that entered the pipe
    "parcel",  # history index of the parcel at the sensor (-1: initial water)
    "head",  # entries written to the history so far
    "time_s",  # time at the end of the last step
)
S = index_of(STATE)
S_SENSOR, S_MASS, S_PARCEL, S_HEAD, S_TIME = (
    S["sensor_C"], S["cumulated_kg"], S["parcel"], S["head"], S["time_s"]
)  # fmt: skip

# history rows: cumulated mass at the end of the entry [kg], temperature [C], time at its
# end [s]
H_MASS, H_TEMP, H_TIME = range(3)
N_HISTORY = 4096


def pack(values, params) -> dict[str, float]:
    tau_b = values["coupling_time_constant_s"]
    return {
        "water_kg": values["volume_l"] * 1e-3 * RHO_WATER,
        "room_rate_1_s": 1.0 / values["cooling_time_constant_s"],
        "boiler_rate_1_s": 1.0 / tau_b if tau_b > 0 else math.inf,
    }


@njit(cache=True)
def forward_sensor(fc, fs, row, ph, flow_kg_h, t_outlet_C, t_boiler_C, room_C, dt_s):
    """``forward_sensor``: advance the exit pipe by a step; the sensor's temperature [C].

    ``t_outlet_C`` is the mean temperature of the water leaving the boiler over the step
    (it enters the pipe); the sensor's parcel is the water that entered one pipe content
    of flow ago. Parcels relax toward T_c at the rate k_b + k_r (module docstring): a
    parcel newly at the sensor has done so for its residence time (with the present T_c,
    exact while T_boiler changes little over a residence), the same parcel is advanced by
    ``dt_s``. Entries smaller than 1/256 of the pipe content (the trickle after the pump
    stops) are merged into the last one, so the history always spans many pipe contents.
    Off (or with instant coupling) the sensor reads the boiler water.
    """
    if fc[row, C_ON] < 0.5:
        return t_boiler_C
    fs[row, S_TIME] += dt_s
    k_r = fc[row, C_K_ROOM]
    k_b = fc[row, C_K_BOILER]
    if math.isinf(k_b):  # instant coupling: the pipe's water is the boiler's
        return t_boiler_C
    rate = k_b + k_r
    t_c = (k_b * t_boiler_C + k_r * room_C) / rate if rate > 0.0 else t_boiler_C
    now = fs[row, S_TIME]  # the end of this step
    head = int(fs[row, S_HEAD])
    inc = flow_kg_h * dt_s / 3600.0
    if inc > 0.0:
        mass = fs[row, S_MASS] + inc
        eps = max(fc[row, C_MASS] / 256.0, 1e-6)
        last_start = ph[H_MASS, (head - 2) % N_HISTORY] if head >= 2 else 0.0
        if head >= 1 and mass - last_start < eps:  # merge into the last entry
            entry = (head - 1) % N_HISTORY
            size = ph[H_MASS, entry] - last_start
            ph[H_TEMP, entry] = (ph[H_TEMP, entry] * size + t_outlet_C * inc) / (size + inc)
        else:
            entry = head % N_HISTORY
            ph[H_TEMP, entry] = t_outlet_C
            head += 1
            fs[row, S_HEAD] = head
        ph[H_MASS, entry] = mass
        ph[H_TIME, entry] = now
        fs[row, S_MASS] = mass
    target = fs[row, S_MASS] - fc[row, C_MASS]  # cumulated mass when the parcel entered
    parcel = int(fs[row, S_PARCEL])
    new = parcel
    if target > 0.0 and head > 0:
        new = max(parcel, head - N_HISTORY, 0)
        while new < head - 1 and ph[H_MASS, new % N_HISTORY] < target:
            new += 1
    if new != parcel:
        fs[row, S_PARCEL] = new
        entry = new % N_HISTORY
        end_mass = ph[H_MASS, entry]
        end_time = ph[H_TIME, entry]
        if new >= 1 and new - 1 >= head - N_HISTORY:
            prev = (new - 1) % N_HISTORY
            start_mass, start_time = ph[H_MASS, prev], ph[H_TIME, prev]
        else:  # the first entry: it started with the cumulated mass 0 one step earlier
            start_mass, start_time = 0.0, end_time - dt_s
        # entry time of the parcel, interpolated within its history entry
        w = (target - start_mass) / (end_mass - start_mass) if end_mass > start_mass else 1.0
        w = min(max(w, 0.0), 1.0)
        residence = max(now - (start_time + w * (end_time - start_time)), 0.0)
        t_s = t_c + (ph[H_TEMP, entry] - t_c) * math.exp(-rate * residence)
    else:
        t_s = t_c + (fs[row, S_SENSOR] - t_c) * math.exp(-rate * dt_s)
    fs[row, S_SENSOR] = t_s
    return t_s


EFFECT = EffectSpec(
    name="outlet_sensor_pipe",
    params=(
        ParamSpec(
            "volume_l",
            "l",
            0.25,
            "linear",
            0.0,
            5.0,
            doc="pipe volume up to the sensor V (lab: 30 cm of DN32)",
        ),
        ParamSpec(
            "cooling_time_constant_s",
            "s",
            1800.0,
            "inverse",
            300.0,
            1e6,
            # (1 s was taken: a 30-cm pipe threw away 28 kW, the forward 20 K under the
            # return while the boiler fired: a physics review)
            doc="tau_r, the pipe's loss to the room; at least a water-filled pipe's own, "
            "rho c d / (4 h): 500 s for 10 mm bare in a draught",
        ),
        ParamSpec(
            "coupling_time_constant_s",
            "s",
            18000.0,
            "linear",
            0.0,
            1e6,
            doc="tau_b, conduction along the pipe from the boiler (lab: steel wall over "
            "30 cm; 0: instant, the sensor reads the boiler water)",
        ),
    ),
    strength_range=(0.5, 2.0),
    is_on=lambda v: (
        v["volume_l"] > 0.0
        or math.isfinite(v["cooling_time_constant_s"])
        or v["coupling_time_constant_s"] > 0.0
    ),
    stages={"forward_sensor": forward_sensor},
    constants=CONSTANTS,
    state=STATE,
    pack=pack,
    initial_state=lambda t_C: {"sensor_C": t_C, "parcel": -1.0},
    history_shape=(3, N_HISTORY),
)
