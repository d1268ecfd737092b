"""Strict JSON for every file the client writes: a number a figure does not have (NaN, an
infinity) is ``null``, never the ``NaN`` or ``Infinity`` that Python's :mod:`json` writes by
default and strict readers (JavaScript, jq, most languages' parsers) refuse."""

from __future__ import annotations

import json
import math
from typing import Any


def nulls(value: Any) -> Any:
    """``value`` with every non-finite float (numpy's too) replaced by None."""
    if isinstance(value, dict):
        return {k: nulls(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [nulls(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def strict_json(value: Any, **options: Any) -> str:
    """``json.dumps`` of ``value`` with :func:`nulls` (``options`` as for json.dumps)."""
    return json.dumps(nulls(value), allow_nan=False, **options)
