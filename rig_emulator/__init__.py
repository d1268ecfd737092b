"""Hardware-in-the-loop emulator of a pellet-boiler test bench (Carlon et al. 2015).

Layers, imports pointing one way only:
``rig_emulator.model`` (pure physics) <- ``rig_emulator.bench`` (water loop, balance, room)
<- clock and Modbus adapter.
"""

__version__ = "0.1.0"
