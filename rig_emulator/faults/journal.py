"""The fault journal: one JSON line per fault start and end (CONTRACT section 5).

Each line: ``event`` (``start`` | ``end``), ``id`` (the same for a fault's start and end),
``t_sim_s`` (simulated time of the event), ``t_wall`` (Unix time), ``kind``, ``unit`` or
``signal``, ``source`` (``file``, ``profile``, ``random``, ``python``, ``modbus``),
``parameter`` (the kind's own: ``delay_ms``, ``code``, ``rate_per_h`` or ``value``) and
``served``: what the server answered (``delay_ms``, ``reply: none``, ``exception_code``,
``connections_closed``) or the reading it published next to the instrument's own reading
without the fault and the plant's true value (``reading``, ``instrument``, ``truth``; a
dropout's reading is null). End lines add ``requests`` (communication: how many requests
the fault answered) and ``reason`` (``for_s elapsed``, ``cleared``, ``reset``, ``once``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, TextIO


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value


class FaultJournal:
    """Appends fault events to a JSONL file, one flushed line each."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file: TextIO | None = self.path.open("w", encoding="utf-8")

    def write(self, event: dict[str, Any]) -> None:
        if self._file is None:
            return
        self._file.write(json.dumps(_json_safe(event), allow_nan=False) + "\n")
        self._file.flush()

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


def read_journal(path: str | Path) -> list[dict[str, Any]]:
    """The events of a journal file, in order."""
    events = []
    for number, line in enumerate(Path(path).read_text(encoding="utf-8").splitlines(), 1):
        if line.strip():
            try:
                events.append(json.loads(line))
            except (json.JSONDecodeError, RecursionError):
                raise ValueError(f"{path}: line {number} is not JSON") from None
    return events
