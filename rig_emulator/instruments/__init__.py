"""Instrument models between the plant and the registers, configured by profiles."""

from rig_emulator.instruments.bank import InstrumentBank
from rig_emulator.instruments.profile import (
    InstrumentSpec,
    Profile,
    ProfileError,
    load_profile,
    profile_from_mapping,
)

__all__ = [
    "InstrumentBank",
    "InstrumentSpec",
    "Profile",
    "ProfileError",
    "load_profile",
    "profile_from_mapping",
]
