"""The candidates' kernels against closed forms."""

from __future__ import annotations

import numpy as np

from hil_client.analysis.augment import first_order_lag, pipe_sensor, two_lump_water

CP = 4.19  # [kJ/(kg K)]


def test_two_lump_steady_state_is_the_closed_form_and_energy_is_conserved():
    n, dt = 20_000, 1.0
    q, flow, t_in, room, ua = 10.0, 600.0, 55.0, 20.0, 0.003  # kW, kg/h, C, C, kW/K
    ones = np.ones(n)
    tw = two_lump_water(
        q * ones,
        flow * ones,
        t_in * ones,
        room * ones,
        ua * ones,
        dt * ones,
        55.0,
        80.0,
        125.0,
        80.0 / 250.0,
    )
    m_cp = flow * CP / 3600.0
    closed = (q + m_cp * t_in + ua * room) / (m_cp + ua)  # water balance in steady state
    assert abs(tw[-1] - closed) < 1e-6
    # energy: heat in = heat out + storage (metal + water), to the step's rounding
    # (backward Euler conserves energy exactly per step)
    out = np.sum(m_cp * (tw - t_in) + ua * (tw - room)) * dt
    # metal temperature at the end from the water balance of the last step
    g = 80.0 / 250.0
    tm_end = tw[-1] + (m_cp * (tw[-1] - t_in) + ua * (tw[-1] - room)) / g
    stored = 80.0 * (tm_end - 55.0) + 125.0 * (tw[-1] - 55.0)
    assert abs(q * n * dt - out - stored) < 1e-6 * q * n * dt


def test_after_a_stop_the_water_keeps_warming_from_the_metal():
    n = 4000
    q = np.where(np.arange(n) < 2000, 10.0, 0.0)
    ones = np.ones(n)
    tw = two_lump_water(
        q, 0.0 * ones, 55.0 * ones, 20.0 * ones, 0.003 * ones, ones, 50.0, 80.0, 125.0, 80.0 / 250
    )
    assert tw[2100] > tw[1999] + 1.0  # the metal's excess heat reaches the water


def test_pipe_sensor_settles_between_boiler_and_room_without_flow():
    n = 50_000
    ones = np.ones(n)
    ts = pipe_sensor(70.0 * ones, 0.0 * ones, 20.0 * ones, ones, 0.3, 1800.0, 1e4)
    k_loss, k_c = 1 / 1800.0, 1 / 1e4
    assert abs(ts[-1] - (k_c * 70.0 + k_loss * 20.0) / (k_c + k_loss)) < 1e-6
    flowing = pipe_sensor(70.0 * ones, 600.0 * ones, 20.0 * ones, ones, 0.3, 1800.0, 1e9)
    assert 69.9 < flowing[-1] < 70.0  # a few hundredths of a kelvin lost while flowing


def test_first_order_lag_is_exact_for_a_step():
    x = np.ones(1000)
    x[0] = 0.0
    y = first_order_lag(x, np.ones(1000), 100.0)
    assert abs(y[100] - (1 - np.exp(-1.0))) < 1e-12
