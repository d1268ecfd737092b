"""``fuel_energy_bias``: the fuel delivers (1 + b) times the nominal energy per kg
(moisture, fines, unburnt carbon).

The boiler's controller acts on the heat it gets, so the heat flows are the model's while
the balance loses 1 / (1 + b) times the mass. Reference magnitude b = -0.08 (strength 1):
the paper's 16.3 kg measured against 15.0 kg simulated for the 12 kW stationary test, read
on one basis (15.0 / 16.3 - 1); read as the balance's fuel as received against dry fuel,
the gap is -0.02, which the ``lab`` profile sets (strength 0.25). Fuel masses in the
plant's step are in kg of nominal energy (HHV); only the balance sees the bias.

Stage: ``balance`` (a factor on what the balance loses per kg; no compiled stage).
"""

from __future__ import annotations

from rig_emulator.bench.effects._spec import EffectSpec, ParamSpec

EFFECT = EffectSpec(
    name="fuel_energy_bias",
    params=(
        ParamSpec(
            "relative_bias",
            "-",
            -0.08,
            "linear",
            -0.3,
            0.1,
            # (+0.3 was taken: 26 MJ/kg, a coal's, and a direct efficiency of 104 % on the
            # HHV: a physics review)
            doc="b, the fuel's energy per kg over the nominal HHV, less 1; at most +10 %: dry "
            "wood's HHV lies within 18-22 MJ/kg of the nominal 20.07, and moisture, fines and "
            "unburnt carbon only lower it",
        ),
    ),
    strength_range=(0.5, 2.0),
    is_on=lambda v: v["relative_bias"] != 0.0,
    balance_factor=lambda v: 1.0 / (1.0 + v["relative_bias"]),
)
