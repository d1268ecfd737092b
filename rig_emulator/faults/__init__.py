"""Fault injection for protocol tests of acquisition software (CONTRACT section 5).

- :mod:`~rig_emulator.faults.spec`: faults as data (``FAULTS.yaml``), validated;
- :mod:`~rig_emulator.faults.engine`: the schedule in simulated time, per-request
  communication decisions and the changed readings;
- :mod:`~rig_emulator.faults.journal`: the JSONL journal of fault starts and ends;
- :mod:`~rig_emulator.faults.wire`: the fault command block of the simulation control unit.
"""

from rig_emulator.faults.engine import ActiveFault, CommDecision, FaultEngine
from rig_emulator.faults.journal import FaultJournal, read_journal
from rig_emulator.faults.spec import (
    COMM_KINDS,
    INSTRUMENT_KINDS,
    KINDS,
    Entry,
    FaultError,
    FaultSpec,
    RandomSpec,
    ReadingRange,
    check_spikes,
    check_units,
    fault_from_mapping,
    faults_from_list,
    load_faults,
)

__all__ = [
    "COMM_KINDS",
    "INSTRUMENT_KINDS",
    "KINDS",
    "ActiveFault",
    "CommDecision",
    "Entry",
    "FaultEngine",
    "FaultError",
    "FaultJournal",
    "FaultSpec",
    "RandomSpec",
    "ReadingRange",
    "check_spikes",
    "check_units",
    "fault_from_mapping",
    "faults_from_list",
    "load_faults",
    "read_journal",
]
