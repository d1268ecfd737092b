"""A live view of the bench in a browser (CONTRACT section 8): ``serve --http PORT``."""

from rig_emulator.dashboard.http import Dashboard

__all__ = ["Dashboard"]
