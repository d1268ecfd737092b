"""Instruments' error codes among a lab log's readings: what they are and which they are.

A lab instrument that cannot measure writes a code where its reading goes: a thermocouple
open-circuit 999.9, a data logger -999 or 9999, a flow meter 99999. Where the code lies
beyond what the instrument can read at all, the log reader's plausible ranges catch it;
where it lies inside (999.9 C in a flue-gas column, -999 ppm of CO, 9999 kg/h of water,
-999 kg on a balance) it was read as a measurement and moved every result downstream (a
stranger's probe: a flow of 9999 gave a direct efficiency of 115 %, a balance at -999 kg a
fuel of 1,508 kg). Two rules find them:

- **All nines** (:func:`all_nines_codes`): a reading of three or more nines before the
  point, nines after it if any (999, -999, 999.9, 9999, 99999.99, ...), that lies outside
  the range of the column's other readings. A measurement is that exact value by chance
  only at the edge of its column, and there never beyond all its neighbours; a code is.
  So a large boiler's real 9999 kg/h among readings of 9,000-11,000 stays a reading.
- **Declared** (:func:`declared_codes`): the log's meta file names its instruments' codes
  under ``missing_values``, for every column (a number or a list) or per column (an object
  of column names to a number or a list), as NetCDF's ``missing_value`` and pandas'
  ``na_values`` do. Those are missing wherever they appear.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

#: The meta file's key for the codes a lab's instruments write (see the module docstring).
META_KEY = "missing_values"

#: Every all-nines value: three to nine nines before the point and none to three after
#: it, both signs; each as the float its decimal text reads as and as a float32 register
#: carries it (999.9 arrives over Modbus as 999.9000244140625).
_NINES = [
    sign * float("9" * whole + ("." + "9" * frac if frac else ""))
    for whole in range(3, 10)
    for frac in range(4)
    for sign in (1.0, -1.0)
]
ALL_NINES = np.unique(np.array(_NINES + [float(np.float32(v)) for v in _NINES if abs(v) < 1e7]))


def all_nines_codes(values: np.ndarray) -> np.ndarray:
    """Per reading, whether it is an all-nines error code: an all-nines value (see
    :data:`ALL_NINES`) outside the range of the column's other finite readings (every one
    of them, where the column has no other reading)."""
    nines = np.isin(values, ALL_NINES)
    if not nines.any():
        return nines
    others = values[np.isfinite(values) & ~nines]
    if not others.size:
        return nines
    return nines & ((values < others.min()) | (values > others.max()))


class CodesError(ValueError):
    """The meta file's ``missing_values`` cannot be read; the message says what is wrong."""


def declared_codes(
    meta: Mapping[str, Any], columns: list[str], meta_file: Path
) -> dict[str, np.ndarray]:
    """The codes the meta's ``missing_values`` declares, per column of ``columns`` it
    applies to (a column it names that the log lacks is an error: a misspelt name would
    silently keep its codes as readings)."""
    declared = meta.get(META_KEY)
    if declared is None:
        return {}
    where = f"{meta_file}: '{META_KEY}'"
    if isinstance(declared, Mapping):
        unknown = [name for name in declared if name not in columns]
        if unknown:
            raise CodesError(f"{where} names column '{unknown[0]}', which the log does not have")
        if "time_s" in declared:
            raise CodesError(f"{where} names 'time_s': a time is never an error code")
        return {name: _numbers(codes, f"{where} of '{name}'") for name, codes in declared.items()}
    codes = _numbers(declared, where)
    return {name: codes for name in columns if name != "time_s"}


def _numbers(codes: object, where: str) -> np.ndarray:
    """``codes`` (a number or a list of numbers) as an array, or a :class:`CodesError`."""
    items = codes if isinstance(codes, list) else [codes]
    if not items:
        raise CodesError(f"{where} is an empty list")
    out = []
    for item in items:
        number = _finite(item)
        if number is None:
            raise CodesError(f"{where}: {str(item)[:40]!r} is not a finite number")
        out.append(number)
    return np.array(out)


def _finite(item: object) -> float | None:
    if isinstance(item, bool) or not isinstance(item, int | float):
        return None
    try:
        number = float(item)
    except OverflowError:  # an integer of 400 digits
        return None
    return number if np.isfinite(number) else None
