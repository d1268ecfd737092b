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
            0.3,
            doc="b, the fuel's energy per kg over the nominal HHV, less 1",
        ),
    ),
    strength_range=(0.5, 2.0),
    is_on=lambda v: v["relative_bias"] != 0.0,
    balance_factor=lambda v: 1.0 / (1.0 + v["relative_bias"]),
)
