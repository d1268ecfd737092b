"""The candidate effects of the diagnosis, each with its physical fingerprint.

Every effect of CONTRACT section 4 leaves its mark on one signal, in the rows where its
physics acts, and nowhere else; each candidate looks only there, with a predictor that
takes as much as it can from the lab's own measurements so that what the real boiler does
differently from Type 869 (its controller, its start-up, its exchanger) cannot be mistaken
for the effect:

``outlet_sensor_pipe`` (signal: forward temperature; rows: low flow and stagnation)
    The forward sensor is predicted from the *measured* boiler water through a mixed pipe
    volume fed by the flow, losing heat to the room and coupled to the boiler by
    conduction (:func:`hil_client.analysis.augment.pipe_sensor`); base: the boiler water
    itself. Sensor offset and slow drift of forward minus boiler water are fitted on the
    settled, flowing rows, where a pipe does nothing.
``body_heat_diffusion`` (boiler water; the 30 min after each stop of the burner)
    The body as two lumps, the metal (the documented Ctherm) heated by the flame and giving
    its heat to the water through a conductance (time constant C_metal / G). After a stop
    the hot metal keeps warming the water, which the one node cannot do. Starts are not
    used: there a real boiler's own start-up (purge, ignition, fuel ramp) differs from the
    model's, and an effect must not be named for absorbing that.
``flue_gas_lag`` (flue gas; the 30 min after each stop)
    A share of the flue gas's heat passes through a first-order lag (exchanger and
    refractory storage, charged by the gas the lab measured while burning; the store's
    pace and how much of the gas's heat it holds are fitted apart): the slow fall after a
    stop, where no controller or start-up is involved. Without combustion the draught air
    leaves at the *measured* water's temperature less what the exchanger does not give it
    (as the log's own settled stand-by shows), so water that stays warmer than the model's
    (a body, the plant's own losses), or an idle flue gas settling below the water, is not
    taken for (nor hides) a store.

The responses after a stop are read while the analyser reads air (no combustion: a bed
burning out or smouldering is ``ignition_delay``'s, not storage), the flue gas's relative to
its level once the probe has settled, the water's relative to the steady burn just before
the stop, so a mismatch the plant carried into the stop (its own set point, its modulation)
is not counted; each window is cut into 5-min blocks for the cross-validation.
``ignition_delay`` (balance; around each start)
    Measured directly: the fuel the balance lost before the flue gas showed combustion
    (the mass before the start less the mass at the onset, read from the readings before
    it). Without the effect it is what the auger feeds within the onset's detection time,
    well under two balance steps (0.04 kg). Where the flue gas counts the flame's fuel (O2
    consumed times the gas flow), also the fuel fed but not burnt five minutes into the
    start: a bed that lights at once but burns slowly at first holds its fuel there.
``fuel_energy_bias`` (balance; test phase, 1-h blocks without starts or stops)
    Energy closure from the instruments: the fuel the measured heat to water, storage,
    loss to the room and flue-gas losses (from the measured flue-gas temperature and O2,
    Eq. 4-7) need at the nominal calorific value, against what the balance lost. The
    forward-return difference is checked at the isothermal end of the preheat, where the
    bench holds supply = return (Section 2.3), so a fixed sensor error does not pass for a
    fuel bias. Each hour carries its own systematic uncertainty (the sensors, the loss to
    the room, the water's storage; :func:`closure_u_rel`) and weighs by it: an hour of a
    load cycle whose heat is largely the water's warming says little about the fuel.

Each candidate gives *units* of evidence that can be drawn again in a bootstrap (held-out
blocks, starts, closure blocks) and a rule deciding from them whether it is named.

One module per candidate (:mod:`.pipe`, :mod:`.body`, :mod:`.flue`, :mod:`.ignition`,
:mod:`.fuel`) on what they share (:mod:`.base`, :mod:`.windows`); this package registers
them.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from hil_client.analysis.candidates.base import Assessment
from hil_client.analysis.candidates.body import BODY
from hil_client.analysis.candidates.flue import FLUE
from hil_client.analysis.candidates.fuel import BiasCandidate
from hil_client.analysis.candidates.ignition import IgnitionCandidate
from hil_client.analysis.candidates.pipe import PIPE
from hil_client.analysis.replay import Case


class Candidate(Protocol):
    """What the diagnosis needs of a candidate effect: its name (CONTRACT section 4), its
    fingerprint (the signal and the phases where it must act), its out-of-sample evidence
    on the calibration log, its held-out RMSD on the validation log, and its prediction of
    the signals it changes. Adding an effect is one such class registered here."""

    effect: str
    signal: str
    locus: str

    def assess(self, case: Case) -> Assessment: ...

    def held_out(self, case: Case, theta: dict[str, float]) -> tuple[float, float]: ...

    def prediction(self, case: Case, theta: dict[str, float]) -> dict[str, np.ndarray]: ...


#: The registry of candidate effects, by name.
CANDIDATES: dict[str, Candidate] = {
    c.effect: c for c in (PIPE, BODY, IgnitionCandidate(), FLUE, BiasCandidate())
}


def full_prediction(case: Case, effect: str, theta: dict[str, float]) -> dict[str, np.ndarray]:
    """The model's prediction of every lab signal with one effect added (for the figures)."""
    pred = case.base_prediction()
    if effect in CANDIDATES and theta:
        pred.update(CANDIDATES[effect].prediction(case, theta))
    return pred
