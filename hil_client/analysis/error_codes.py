"""Instruments' error codes among a lab log's readings: what they are and which they are.

A lab instrument that cannot measure writes a code where its reading goes: a thermocouple
open-circuit 999.9, a data logger -999 or 9999, a flow meter 99999. Where the code lies
beyond what the instrument can read at all, the log reader's plausible ranges catch it;
where it lies inside (999.9 C in a flue-gas column, -999 ppm of CO, 9999 kg/h of water,
-999 kg on a balance) it was read as a measurement and moved every result downstream (a
stranger's probe: a flow of 9999 gave a direct efficiency of 115 %, a balance at -999 kg a
fuel of 1,508 kg). Two rules find them:

- **All nines** (:func:`all_nines_codes`), in the columns of the bench's instruments only
  (a setpoint of 999 kg/h is a command, not a reading): a reading of three or more nines
  before the point and nines after it if any (999, -999, 999.9, 9999, 99999.99, ...) that
  lies beyond the readings next to it (the nearest before and after that are not all
  nines) by more than :data:`CODE_JUMP_FRACTION` of its own size, unless such readings
  are most of the column or all it holds (kept, and said: :func:`nines_verdict`). A code
  replaces the reading and has nothing to do with those around it; a real reading that happens to be
  all nines lies between them (a start-up's CO at 5-s rows: 630, 999, 1259 ppm) or near
  them (a CO peak's 999 between 964 and 973, a barometer's 999.9 hPa after 1000.0, a
  large boiler's 9999 kg/h among 9,800 and 10,100). Re-probes: each of these was dropped
  by rules that looked at the column's range, or at the distance to each neighbour.
- **Declared** (:func:`declared_codes`): the log's meta file names its instruments' codes
  under ``missing_values``, for every reading column (a number or a list; not the log
  format's commands and state such as setpoints, ``boiler_on``, ``rig_epoch``) or per
  column (an object of column names, in any letter case, to a number or a list), as
  NetCDF's ``missing_value`` and pandas' ``na_values`` do. Those are missing wherever they
  appear.

Both compare as a float32 register carries a value and a log prints it: to
:data:`CODE_RTOL` of the value (a client logs 9999.9 from a float32 register as 9999.9004,
-999.9 as -999.90002: a re-probe).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any

import numpy as np

#: The meta file's key for the codes a lab's instruments write (see the module docstring).
META_KEY = "missing_values"

#: Every all-nines value: three to nine nines before the point and none to three after
#: it, both signs, sorted.
ALL_NINES = np.array(
    sorted(
        sign * float("9" * whole + ("." + "9" * frac if frac else ""))
        for whole in range(3, 10)
        for frac in range(4)
        for sign in (1.0, -1.0)
    )
)

#: How close a reading is to a code to be it, relative to the code: a float32 register's
#: rounding (half a unit in the last place: 2^-24) printed with a few decimals, doubled.
CODE_RTOL = 2.0**-22

#: How far beyond the readings before and after it an all-nines reading lies to be a
#: code, relative to its own size: a code next to real readings is nowhere near them
#: (9999 kg/h among 600, -999 kg among 40, 999.9 C among 120), a real reading that peaks
#: exactly at all nines tops its neighbours by little (at most a tenth: a CO peak of 999
#: ppm that 1-10 s rows saw rise from 630 and fall to 700 is dropped, an instrument's
#: reading interpolated over one row).
CODE_JUMP_FRACTION = 0.1


def near(values: np.ndarray, codes: np.ndarray) -> np.ndarray:
    """Per value, whether it is one of the sorted ``codes`` within :data:`CODE_RTOL`."""
    if not codes.size:
        return np.zeros(values.shape, dtype=bool)
    j = np.clip(np.searchsorted(codes, values), 1, max(codes.size - 1, 1))
    below, above = codes[j - 1], codes[np.minimum(j, codes.size - 1)]
    with np.errstate(invalid="ignore"):
        nearest = np.where(np.abs(values - below) <= np.abs(values - above), below, above)
        return np.abs(values - nearest) <= CODE_RTOL * np.abs(nearest)


def all_nines_codes(values: np.ndarray) -> np.ndarray:
    """Per reading, whether it is an all-nines error code (see the module docstring): an
    all-nines value beyond the nearest readings before and after it that are not, and no
    more than half the column's readings (:func:`nines_verdict`)."""
    return nines_verdict(values)[0]


def nines_verdict(values: np.ndarray) -> tuple[np.ndarray, list[float]]:
    """The all-nines codes of a column (a mask) and the all-nines values it keeps although
    they could be codes: where they are all it holds besides none (a barometer that logs
    whole hPa on a day at 999 hPa, a sensor open all run: nothing to compare with), and
    where those beyond their neighbours make up most of its readings (a meter at a whole
    999 kg/h from a 0 on, with its code 9999 in between: every 999 lay beyond the 0). The
    data cannot tell codes from readings there; a log says so, its meta file's
    ``missing_values`` can (re-probes: each of these was emptied, real readings and all,
    and calibrate's UA_on became NaN with the barometer's)."""
    finite = np.isfinite(values)
    nines = finite & near(values, ALL_NINES)
    if not nines.any():
        return nines, []
    rows = np.flatnonzero(finite)
    v = values[rows]
    plain = ~nines[rows]
    k = np.arange(v.size)
    before = np.maximum.accumulate(np.where(plain, k, -1))
    after = np.minimum.accumulate(np.where(plain, k, v.size)[::-1])[::-1]
    prev = np.where(before >= 0, v[np.maximum(before, 0)], np.nan)
    next_ = np.where(after < v.size, v[np.minimum(after, v.size - 1)], np.nan)
    low, high = np.fmin(prev, next_), np.fmax(prev, next_)  # NaN: neither side has one
    reach = CODE_JUMP_FRACTION * np.abs(v)
    with np.errstate(invalid="ignore"):  # (NaN: no reading to compare with, no code)
        beyond = ~plain & ((v < low - reach) | (v > high + reach))
    kept = [] if plain.any() else sorted({float(x) for x in v})
    for level in np.unique(v[beyond]):
        same = beyond & (v == level)
        if 2 * same.sum() > v.size:  # most of the column: no code to take out
            beyond &= ~same
            kept.append(float(level))
    out = np.zeros(values.shape, dtype=bool)
    out[rows] = beyond
    return out, sorted(kept)


class CodesError(ValueError):
    """The meta file's ``missing_values`` cannot be read; the message says what is wrong."""


def declared_codes(
    meta: Mapping[str, Any],
    columns: Collection[str],
    not_readings: Collection[str],
    text_columns: Collection[str],
    meta_file: Path,
) -> dict[str, np.ndarray]:
    """The sorted codes the meta's ``missing_values`` declares, per number column of the
    log they apply to: all of ``columns`` but ``time_s`` and ``not_readings`` (commands
    and state) for a declaration of every column; those named, in any letter case, for a
    declaration per column (naming a column the log lacks, ``time_s`` or a text column is
    an error: a misspelt name would silently keep its codes as readings)."""
    declared = meta.get(META_KEY)
    if declared is None:
        return {}
    where = f"{meta_file}: '{META_KEY}'"
    if not isinstance(declared, Mapping):
        codes = _numbers(declared, where)
        return {n: codes for n in columns if n != "time_s" and n not in not_readings}
    by_case = {name.lower(): name for name in columns}
    texts = {name.lower() for name in text_columns}
    out = {}
    for named, value in declared.items():
        name = by_case.get(str(named).lower())
        if str(named).lower() in texts:
            raise CodesError(f"{where} names '{named}', a text column: it holds no readings")
        if name is None:
            raise CodesError(f"{where} names column '{named}', which the log does not have")
        if name == "time_s":
            raise CodesError(f"{where} names 'time_s': a time is never an error code")
        out[name] = _numbers(value, f"{where} of '{named}'")
    return out


def _numbers(codes: object, where: str) -> np.ndarray:
    """``codes`` (a number or a list of numbers; an empty list: none) sorted, or a
    :class:`CodesError`."""
    items = codes if isinstance(codes, list) else [codes]
    out = []
    for item in items:
        number = _finite(item)
        if number is None:
            raise CodesError(f"{where}: {str(item)[:40]!r} is not a finite number")
        out.append(number)
    return np.array(sorted(out), dtype=float)


def _finite(item: object) -> float | None:
    if isinstance(item, bool) or not isinstance(item, int | float):
        return None
    try:
        number = float(item)
    except OverflowError:  # an integer of 400 digits
        return None
    return number if np.isfinite(number) else None
