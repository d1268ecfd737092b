"""reality8: an independent simulated pellet-boiler test bench (a "real" Windhager boiler).

Written from Carlon et al. (2015) and the bench digest only. It plays the lab: a pellet boiler
of the Windhager type on the Wieselburg bench, run through the stationary test or the load
cycle (Fig. 3: preheat to 45 C, start-up until the flue gas rises < 0.5 K/min over 5 min,
the test sequence, cooling 1 at 20 % load until the forward sensor reads 55 C, cooling 2
without flow until t2 + 8 h), logged with the columns of CONTRACT section 3.

Physics (kernel.py, 1 s step, energy closes every step to rounding)
--------------------------------------------------------------------
Fuel (Eq. 3): Q_fuel = m_dry * HHV. Combustion products from the ultimate analysis (fuel.py).
The flue gas takes Q_fuel - Q_ash - Q_lat - Q_chem (+ igniter power) as sensible heat and
passes an NTU heat exchanger on the metal node: T_g1 = T_ad - (1 - exp(-NTU)) (T_ad - T_m),
NTU = NTU_nom (W_g / W_g,nom)^(-n) (convective film ~ W^0.8). Metal -> water through G_mw,
water -> envelope (UA_env) -> room. Idle boiler: natural draught ~ sqrt(T_m - T_room) through
the exchanger (the physical reason why UA_amb,OFF > UA_amb,ON). Water path: boiler water ->
exit pipe cell(s) -> bench loop (capacity, PI cooler/heater with capacity limit and valve lag)
-> return pipe -> boiler (implicit upwind). The balance carries the hopper (assumption: the
burner is fed through a decoupled drop tube, so the balance loses mass when the auger feeds).

Background (draw_background, per case; differences from Type 869 no one listed)
------------------------------------------------------------------------------
* Own controller: PI on the boiler's own water sensor (set point 70 C +-0.2-0.8 K, own sensor
  offset, lag 15-40 s), conditional-integration anti-windup, rate limit 0.4-1.2 %/s of Pmax,
  shut-off at 85 +-0.5 C, restart at 55.3-55.8 C only after a minimum pause of 5-15 min.
* Volumetric pulsed auger (period 8-20 s) with pellet bulk density wandering 2-6 % (AR(1),
  2-10 min), feed calibration +1/-6 %; bed burning with tau 40-90 s, oxygen limited.
* Normal start-up: pre-purge 30-60 s (fan), igniter 280-400 W on, preload at Pstart feed for
  30-60 s, the bed ignites 30-90 s after the preload, the controller sees the flame (+8 K flue
  gas), fires at Pstart for 10-17 min (or until 72 C) with the igniter on for 3-6 min after the
  flame, then modulates. After a stop the bed burns out with the fan on.
* Exchanger: flue gas at full fire dt_nom*(0.9-1.1) above the return, its own load exponent,
  metal-water time constant 40-100 s, capacity 0.92-1.08 x documented, envelope UA 0.8-1.2 x
  UA_ON, draught 0.8-1.25 x (UA_OFF - UA_ON), own excess-air line (+-5 %, +-10 %), CO.
* Fuel lot: HHV +-1.2 %, moisture +-0.5 pp.
* Bench: loop capacity 60-120 kJ/K, cooler 1.3-1.8 x Pmax, heater 3-6 kW, valve 10-40 s,
  flow lag 5-15 s; room 18-30 C with a slow swing; pressure and humidity.
* Sensors: forward sensor placement (normal): immersion well in an insulated exit pipe 30 cm
  from the boiler (one cell, 0.7 kJ/K, 5-20 mW/K to the room, wall conduction to the boiler),
  well lag 5-20 s. Boiler-body sensor in the upper jacket: reads the water plus 1-2.5 K
  (either sign) per nominal heat flux (incomplete mixing), lag 15-40 s. Offsets, noise and
  resolution as in sensors.py; O2 behind a heated line (15-40 s + 8-20 s), drift +-0.2 %.

Effects (EFFECT_FORMS), strength s in [0, 1] interpolates linearly between the ends shown
-----------------------------------------------------------------------------------------
body_heat_diffusion
  layered_wall_conduction: the firebox wall takes f_rad = 0.5-0.8 of Q_hx as radiation and
    conducts it through two series nodes (80 % of the metal capacity) to the water-side metal,
    time constant per link 4-14 min.
  heavy_base_plate: a massive burner base plate (40-70 % of the metal capacity) takes
    f_pl = 0.3-0.5 of Q_hx and gives it to the water through a weld seam, tau 15-40 min.
outlet_sensor_pipe
  bare_outlet_run: sensor at the end of L = 0.3-0.9 m of bare DN25 steel pipe with fittings
    (4 plug-flow cells, 3.6 kJ/(K m), 1.5 W/(K m) to the room): transport delay ~ V/flow and
    fast cooling once circulation stops.
  stratified_horizontal_run: horizontal run, sensor boss at the pipe bottom: the bottom layer
    mixes with the core by turbulence G = 0.03 W/K + k W_w (k = 0.02-0.01) and loses
    UA_bot = 0.15-0.5 W/K through the bare boss, so it reads low at low flow and without flow.
ignition_delay
  oversized_start_charge: preload 2-5 min at Pstart feed, the igniter lights the big pile only
    3-10 min after the preload; the charge then burns oxygen-limited.
  drying_zone_holdup: fed pellets sit in a drying/pyrolysis zone (tau_dry = 2-8 min) before
    they reach the flaming bed: delayed heat at start, long burnout after a stop.
flue_gas_lag
  finned_economiser_mass: finned economiser after the tube bank, effectiveness 0.35-0.6,
    thermal time constant 3-12 min, coupled to the water jacket.
  lined_flue_connector: ceramic-lined connector before the probe, effectiveness 0.3-0.6,
    time constant 3-15 min, jacket loss to the room.
fuel_energy_bias
  flyash_char_entrainment: char fines blown out with the gas, deficit d (P/Pfull)^1.5 of
    Q_fuel, d = 7-18 % at full fire (mass leaves the balance, energy never released).
  tar_slip_low_load: unburnt tars from a cool bed, deficit d (0.4 + 0.6 Pfull/P), d = 4-12 %.

Interface: EFFECT_FORMS, draw_background, simulate_log, write_log_csv, COLUMNS.
"""

from .background import draw_background
from .csvlog import COLUMNS, write_log_csv
from .effects import EFFECT_FORMS
from .simulate import simulate_log

__all__ = ["COLUMNS", "EFFECT_FORMS", "draw_background", "simulate_log", "write_log_csv"]
