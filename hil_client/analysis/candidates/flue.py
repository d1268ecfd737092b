"""``flue_gas_lag``: a share of the flue gas's heat passes through a first-order store
(exchanger and refractory, charged by the gas the lab measured while burning), read in the
slow fall after a stop against the idle level the log's own stand-by shows.
"""

from __future__ import annotations

import numpy as np

from hil_client.analysis.augment import first_order_lag
from hil_client.analysis.candidates.base import AIR_O2_MARGIN_PCT, O2_AIR_PCT, CurveCandidate
from hil_client.analysis.candidates.windows import (
    PROBE_SETTLE_S,
    STOP_REFERENCE_S,
    SUB_BLOCK_S,
    WINDOW_S,
    per_stop,
    stop_blocks,
)
from hil_client.analysis.replay import Case

#: What stored heat must show after stops [K], beyond what a real boiler's background
#: reaches without it: the flue gas falling toward its idle level (the measured water's) by
#: 3 K, twice a class-1 thermocouple's tolerance (1.5 K; with the idle level read at the
#: model's node, the water's own mismatch moved it by up to 13 K and the floor was 5 K,
#: the paper's lower flue-gas figure).
FLUE_STORED_MIN_K = 3.0


def _flue_fingerprint(case: Case, blocks: list, r: np.ndarray) -> tuple[float, str]:
    """Stored heat: the flue gas is hotter than the model's when combustion ends and falls
    toward it afterwards (by :data:`FLUE_STORED_MIN_K` at least, in the median stop; the
    mean of its last 5 min against its first minute once the probe has settled,
    :data:`PROBE_SETTLE_S`), and by no more than it stood above the idle level at the
    reference (what a store holds). A flue gas that ends up *further above* the model's,
    or starts below it, is the probe's own idle level (draught air, radiation to the duct)
    or a post-purge fan blowing cold air through, not storage."""
    pairs = per_stop(case, blocks, r, STOP_REFERENCE_S, SUB_BLOCK_S, PROBE_SETTLE_S)
    # a store releases what it holds above the idle level: no more than the gas shows
    # above it at the reference (a gas already below it is a purge or the probe's own)
    fall = [
        min(float(np.mean(ref) - np.mean(late)), max(float(np.mean(ref)), 0.0))
        for ref, late in pairs
    ]
    if not fall:
        return 0.0, "no stop to read the flue gas's fall from"
    mark = float(np.median(fall)) / FLUE_STORED_MIN_K
    return (
        mark,
        f"flue gas does not fall toward the model's after stops ({mark * FLUE_STORED_MIN_K:.1f} K)",
    )


#: The stand-by the draught air's exchanger share is read from: the second cooling, from
#: this long after circulation stops [s] (the bed and any store long cold), on rows of air.
STAND_BY_SETTLED_S = 1800.0


#: Fewest such rows to read it from; with fewer the air is taken to leave at the water's.
STAND_BY_MIN_ROWS = 30


#: Least water-to-room difference the share is read at [K]: below it a class-1
#: thermocouple's 1.5 K would move the share by over 15 %.
STAND_BY_MIN_SPREAD_K = 10.0


#: Plausible range of that share: a probe offset can put it a little above 1.
STAND_BY_SHARE_RANGE = (0.5, 1.2)


def stand_by_gas_share(case: Case) -> float:
    """How close to the boiler water the draught air leaves the exchanger without
    combustion: (T_fg - T_room) / (T_water - T_room), the median over the log's settled
    second cooling on rows of air. An exchanger passing the draught at a finite rate warms
    it only partway (0.8-1 on the bench's boilers), so the idle flue gas settles some
    kelvin below the water; read from the lab's own stand-by, not assumed 1 (the model's
    Section 2.1 idle level, the node's temperature). 1 where the log has no such stand-by."""
    t, ph = case.t, case.phases
    o2 = case.log["flue_gas_O2_pct"]
    water, room = case.lab["boiler_water_temp_C"], case.room
    rows = (
        ph.mask("cooling_2", t)
        & (t > ph.t3 + STAND_BY_SETTLED_S)
        & np.isfinite(o2)
        & (o2 >= O2_AIR_PCT - AIR_O2_MARGIN_PCT)
        & (water - room > STAND_BY_MIN_SPREAD_K)
    )
    share = (case.lab["flue_gas_temp_C"][rows] - room[rows]) / (water[rows] - room[rows])
    share = share[np.isfinite(share)]
    if len(share) < STAND_BY_MIN_ROWS:
        return 1.0
    return float(np.clip(np.median(share), *STAND_BY_SHARE_RANGE))


def _flue_gas_with_idle_air(case: Case) -> np.ndarray:
    """The model's flue gas, where it burns; elsewhere (no combustion: its excess-air
    ratio is infinite, model.layout) the draught air leaves at the *measured* boiler
    water's temperature less what the exchanger does not give it
    (:func:`stand_by_gas_share`; the model's: at its node's, Section 2.1). A water that
    stays warmer than the model's after a stop (a body, the plant's own losses), or an
    idle flue gas settling below the water, then does not pass for (or hide) heat stored
    in the flue-gas path."""
    idle = ~np.isfinite(case.model["lambda"])
    share = case.memo(("stand_by_gas_share",), lambda: stand_by_gas_share(case))
    air = case.room + share * (case.lab["boiler_water_temp_C"] - case.room)
    return np.where(idle, air, case.model["t_flue_gas_C"])


def _flue_gas_store_charge(case: Case) -> np.ndarray:
    """What the store is charged with: the *measured* flue gas while it burns (the gas
    that actually flowed past the store: at part load a real boiler's runs well above the
    model's, whose charge would leave the store colder than the draught air after the
    stop), the idle level (:func:`_flue_gas_with_idle_air`) elsewhere."""
    idle = ~np.isfinite(case.model["lambda"])
    base = case.memo(("flue_gas_with_idle_air",), lambda: _flue_gas_with_idle_air(case))
    return np.where(idle, base, case.lab["flue_gas_temp_C"])


def _flue_predict(case: Case, theta: dict[str, float] | None) -> np.ndarray:
    """The model's flue gas plus what a store releases: a share of the gas's heat passes
    through the store's first-order lag, charged by the gas that flowed
    (:func:`_flue_gas_store_charge`); the store's time constant and how much of the gas's
    heat it holds are separate (one parameter for both trades the fall's size against its
    pace and fits either end of it)."""
    gas = case.memo(("flue_gas_with_idle_air",), lambda: _flue_gas_with_idle_air(case))
    if theta:
        charge = case.memo(("flue_gas_store_charge",), lambda: _flue_gas_store_charge(case))
        lagged = case.lagged("flue_gas_store_charge", charge, theta["tau_fg_s"])
        gas = gas + theta["share"] * (lagged - charge)
    return first_order_lag(gas, case.dt, case.sensor_tau_s["flue_gas_temp_C"])


FLUE = CurveCandidate(
    "flue_gas_lag",
    "flue_gas_temp_C",
    "after_stops",
    {
        "tau_fg_s": np.geomspace(20.0, WINDOW_S, 15),
        "share": np.array([0.1, 0.2, 0.35, 0.5, 0.7, 1.0]),
    },
    _flue_predict,
    stop_blocks,
    nuisance_drift=False,
    anchor_s=-STOP_REFERENCE_S,
    fingerprint=_flue_fingerprint,
    floors={"tau_fg_s": (PROBE_SETTLE_S / 3.0, "no slower than the duct probe itself")},
)
