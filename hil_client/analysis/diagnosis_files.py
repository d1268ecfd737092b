"""Writing a diagnosis: ``diagnosis.json`` (CONTRACT section 4), ``report.md`` and figures."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from hil_client.analysis.diagnose import Diagnosis
from hil_client.analysis.figures import diagnosis_figures
from hil_client.analysis.report import diagnosis_report
from rig_emulator.atomic import write_atomically


def _json_safe(value):
    """Numbers as JSON numbers; a value that is not finite becomes null (strict JSON)."""
    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    return value


def public(result: Diagnosis) -> dict:
    """What ``diagnosis.json`` holds, as strict JSON."""
    return _json_safe(result.content)


def write_diagnosis(result: Diagnosis, out: Path, calibration: str, validation: str) -> dict:
    """Write the three outputs into ``out`` (created); returns the public result."""
    out.mkdir(parents=True, exist_ok=True)
    figures = diagnosis_figures(result, out)
    content = public(result)
    write_atomically(out / "diagnosis.json", json.dumps(content, indent=2, allow_nan=False) + "\n")
    write_atomically(out / "report.md", diagnosis_report(content, figures, calibration, validation))
    return content
