"""Analysis of lab logs: reading, phases, energy balance, calibration, validation."""
