"""Rig backends behind the runner's rig interface: in-process (``local``), Modbus."""
