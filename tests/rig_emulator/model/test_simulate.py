"""Open-loop simulation on a log's rows: a row longer than the controller's step (a gap in
a lab log) is stepped in parts, and the row still closes the energy balance."""

import numpy as np
import pytest

from rig_emulator.model import balance_residual_kW, pack_constants
from rig_emulator.model.simulate import MAX_STEP_S, simulate


@pytest.mark.parametrize("row_s", [600.0, 900.0, 3600.0])
def test_long_rows_never_pass_the_shut_off_and_burn_what_short_rows_burn(params, row_s):
    """At zero flow from 45 C one 900-s step fired on to 110 C (3600 s: 265 C). In parts of
    at most MAX_STEP_S the water never passes the shut-off by more than the heat-up of one
    part, and the fuel over the record is that of 60-s rows."""
    c = pack_constants(params)

    def run(row):
        n = int(4 * 3600 / row)
        ones = np.ones(n)
        return simulate(c, 45.0, ones * row, 0 * ones, 55 * ones, 22 * ones, ones > 0)

    long, short = run(row_s), run(MAX_STEP_S)
    # bound: Pstart with no flow heats the node by Pstart / C per second (no loss counted)
    rise_per_part = params.p_start_kW / params.capacity_kJ_K * MAX_STEP_S
    assert long["t_boiler_C"].max() < params.shutoff_temp_C + rise_per_part
    fuel = [
        np.sum(out["fuel_dry_kg_h"]) * row / 3600
        for out, row in ((long, row_s), (short, MAX_STEP_S))
    ]
    assert fuel[0] == pytest.approx(fuel[1], rel=1e-9)  # the same steps, grouped


def test_a_long_row_closes_the_energy_balance(params):
    """The row's flows are means over its parts and its stored heat is C dT over the row:
    the balance closes over the row as it does every step."""
    c = pack_constants(params)
    n = 6
    ones = np.ones(n)
    out = simulate(c, 50.0, ones * 1800.0, ones * 300.0, ones * 55.0, ones * 22.0, ones > 0)
    rows = np.column_stack([out[name] for name in out])
    for row in rows:
        assert abs(balance_residual_kW(row)) < 1e-9
    start = np.concatenate([[50.0], out["t_boiler_C"][:-1]])
    stored = params.capacity_kJ_K * (out["t_boiler_C"] - start) / 1800.0
    np.testing.assert_allclose(out["q_stored_kW"], stored, atol=1e-9)
