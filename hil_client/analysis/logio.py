"""Reading lab logs (CONTRACT section 3) for analysis, validated before any work starts.

Rules (each refusal is a :class:`LogError` naming the file, column, row or value):
- the header must hold ``time_s`` and the columns an analysis requires;
- ``time_s`` must be present in every row and strictly increasing;
- a number column may have empty fields (missing values, e.g. a Modbus outage): they are
  NaN, and analyses skip or interpolate them as they document; a field that is neither empty
  nor a number is refused; an infinite reading, or one outside what its instrument can read
  (:data:`PLAUSIBLE_RANGES`, an error code such as -999), is missing, named in the notes
  (in ``time_s`` it is refused);
- ``phase``/``sequence`` are text; a column the log format does not name (a lab's own, e.g.
  an operator's note) is kept as numbers if they parse, else as text, not analysed; in a
  column it names, a field that is not a number is refused;
- a file whose fields are separated by semicolons or tabs is refused as such (a
  spreadsheet's export in another locale);
- a row of the wrong width is refused, except a last row cut short without a line end (an
  acquisition killed while writing it): it is left out and named in :attr:`LabLog.notes`;
  so is a last row of the full width without a line end whose last field is shorter than
  the row before's (a number cut in two: '23' of '231.84000'; a hand-written file without
  a final line end keeps its last row).

The optional ``NAME.meta.json`` beside the log is read when present.
"""

from __future__ import annotations

import bisect
import codecs
import csv
import itertools
import json
import math
import re
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hil_client.analysis.error_codes import CodesError, declared_codes, near, nines_verdict
from hil_client.protocol.rig import LOG_COLUMNS
from rig_emulator.model.water_heat import heat_to_water_kW
from rig_emulator.signals import MEASURED

TEXT_COLUMNS = ("phase", "sequence")
#: The columns the log format names (CONTRACT section 3 and the project's own logger's)
KNOWN_COLUMNS = frozenset(LOG_COLUMNS)
#: The columns of the bench's instruments' readings (not commands or state: setpoints,
#: ``boiler_on``, ``rig_epoch``)
INSTRUMENT_COLUMNS = KNOWN_COLUMNS & frozenset(MEASURED)
#: Columns every analysis of CONTRACT section 3 may rely on.
REQUIRED = (
    "time_s",
    "water_flow_kg_h",
    "water_in_temp_C",
    "water_out_temp_C",
    "boiler_water_temp_C",
    "flue_gas_temp_C",
    "flue_gas_O2_pct",
    "balance_mass_kg",
    "room_temp_C",
)


#: What a reading of a lab instrument can physically be, by the unit its column's name ends
#: in [that unit]; beyond it (or infinite), a reading is an instrument's error code (-999,
#: 9999, 1e30, inf) and counts as missing. The flue gas of a small boiler stays below
#: 1,000 C; a balance, flow or power meter reads a few hundred of its units.
PLAUSIBLE_RANGES = {
    "_temp_C": (-60.0, 1500.0),
    "_pct": (-5.0, 105.0),
    "_ppm": (-1000.0, 1e6),
    "_kg_h": (-1e5, 1e5),
    "_kg": (-1e5, 1e5),
    "_m_s": (-100.0, 100.0),
    "_hPa": (300.0, 1300.0),
    "_Pa": (-1e5, 1e5),
    "_W": (-1e6, 1e6),
}


def plausible_range(name: str) -> tuple[float, float]:
    """What column ``name`` can read (any finite number for a unit not listed)."""
    return next(
        (r for unit, r in PLAUSIBLE_RANGES.items() if name.endswith(unit)), (-math.inf, math.inf)
    )


#: How a ``sequence`` name marks a stationary step (the project's ``stationary_100``; a
#: German lab's ``stationär_100``), in any letter case, spaces around it ignored.
STATIONARY_PREFIXES = ("stationary", "stationär", "stationaer")


def stationary_steps(log: LabLog, rows: np.ndarray) -> np.ndarray | None:
    """Per row, whether the ``sequence`` column names a stationary step (see
    :data:`STATIONARY_PREFIXES`); None where the column is missing or names none of
    ``rows`` so (a lab's own step names: "full_load", "Stufe 3"), and the steps must be
    found from the signals. Such names had the calibration keep its documentation values
    for "no stationary interval" and the validation call a whole load cycle dynamic."""
    if not log.has("sequence"):
        return None
    marked = np.array(
        [s.strip().lower().startswith(STATIONARY_PREFIXES) for s in log.text["sequence"]]
    )
    return marked if marked[rows].any() else None


#: A step of the record longer than this many times its usual step, and than
#: :data:`GAP_MIN_S`, is a gap [-]: sampling of 1-10 s, irregular, is data.
GAP_STEPS = 10.0


GAP_MIN_S = 60.0


def record_steps(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(each row's step from the row before [s], whether that step is a gap in the record);
    the first row's step is the usual one (taking the one after it counted a gap twice)."""
    usual = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    dt = np.diff(t, prepend=t[0] - usual)
    return dt, dt > max(GAP_MIN_S, GAP_STEPS * float(np.median(dt)))


def flow_column(log: LabLog) -> str:
    """The column that tells the flow's steps: its setpoint where logged, else the flow."""
    return "water_flow_setpoint_kg_h" if log.has("water_flow_setpoint_kg_h") else "water_flow_kg_h"


#: A stationary step found from the flow lasts at least this long [s] (the load cycle's
#: shortest stationary step is 30 min; its ramps between steps last minutes).
PLATEAU_MIN_S = 1200.0


def flow_plateaus(log: LabLog, rows: np.ndarray) -> list[tuple[int, int, float]]:
    """The runs of the stretch ``rows`` (a mask of one stretch: the test) where the flow
    (its setpoint where logged) holds within 2 % of its median for :data:`PLATEAU_MIN_S` at
    least: (first row, end row, exclusive, level [kg/h]). The stationary steps of a log
    whose ``sequence`` names mark none (:func:`stationary_steps`)."""
    t = log.t
    flow = fill_gaps(log[flow_column(log)], t)
    idx = np.flatnonzero(rows)
    out: list[tuple[int, int, float]] = []
    if not len(idx):
        return out
    start = idx[0]
    stretch = flow[idx[0] : idx[-1] + 1]
    # the run's values kept sorted as it grows: its median at once, not a sort of the run
    # at every row (np.median per row took seconds on a day at 1 s); a NaN (an all-NaN
    # column) has no order: there np.median itself, which gives NaN as before
    window: list[float] | None = None if np.isnan(stretch).any() else [float(flow[start])]
    for i in range(idx[0] + 1, idx[-1] + 2):
        end = i == idx[-1] + 1
        level = _median_of_sorted(window) if window is not None else float(np.median(flow[start:i]))
        if end or abs(flow[i] - level) > 0.02 * max(level, 1.0):
            if t[i - 1] - t[start] >= PLATEAU_MIN_S:
                out.append((int(start), int(i), level))
            start = i
            if window is not None:
                window.clear()
        if window is not None and not end:
            bisect.insort(window, float(flow[i]))
    return out


def _median_of_sorted(values: list[float]) -> float:
    """The median of sorted ``values`` as :func:`numpy.median` gives it (the mean of the
    two middle ones where their number is even)."""
    k = len(values)
    return values[k // 2] if k % 2 else (values[k // 2 - 1] + values[k // 2]) / 2.0


class LogError(ValueError):
    """A lab log cannot be analysed; the message names the file and what is wrong."""


@dataclass(slots=True)
class LabLog:
    """A lab log in columns (numbers as float arrays, NaN where missing) and its meta."""

    path: Path
    columns: dict[str, np.ndarray]
    text: dict[str, list[str]]
    meta: dict[str, Any] = field(default_factory=dict)
    #: what was tolerated on reading (a last row cut short), one line each, for the user
    notes: list[str] = field(default_factory=list)
    #: (the balance column and time it was computed from, the balance without refills)
    _unrefilled: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(
        default=None, repr=False, compare=False
    )
    #: (the balance column and time they were read from, its readings, the stretches unread)
    _readings: tuple[np.ndarray, np.ndarray, np.ndarray, list[Unread]] | None = field(
        default=None, repr=False, compare=False
    )

    @property
    def t(self) -> np.ndarray:
        return self.columns["time_s"]

    def balance_readings(self) -> tuple[np.ndarray, list[Unread]]:
        """The balance's readings with those that are none missing (NaN), and those
        stretches: its dropouts (:func:`balance_falls`; fuel taken off by hand is added
        back, said in a note) and where it is stuck through firing (:func:`stuck_stretches`,
        by the O2 where logged). Both read the heat the water took while firing."""
        mass, t = self.columns["balance_mass_kg"], self.t
        cached = self._readings
        if cached is None or cached[0] is not mass or cached[1] is not t:
            # stuck first: a balance that comes unstuck falls at once to the level it lost
            # meanwhile, which is no dropout once the stuck readings are none
            read = mass.astype(float)
            unread: list[Unread] = []
            heat = self._heat_kW()
            if self.has("flue_gas_O2_pct"):
                firing = fill_gaps(self.columns["flue_gas_O2_pct"], t) < FIRING_O2_PCT
                if heat is not None:  # (the body's heat a cooling gives up needs no fuel)
                    heat = np.where(firing, heat, 0.0)
                unread = stuck_stretches(read, t, firing, heat)
                for u in unread:
                    read[u.start : u.end] = np.nan
            dropouts, removals = balance_falls(read, t, heat)
            for u in dropouts:
                read[u.start : u.end] = np.nan
            for r in removals:
                read[r.row :] += r.kg
                self.notes.append(f"the balance {r.why}")
            unread = sorted([*unread, *dropouts], key=lambda u: u.start)
            cached = self._readings = (mass, t, read, unread)
        return cached[2], cached[3]

    def _heat_kW(self) -> np.ndarray | None:
        """The heat to the water per row [kW] (Eq. 7, gaps read across), None where the
        log lacks a column of it or one has no readings (unknown heat is no heat of 0: it
        let a balance failed to 0 pass as fuel taken off, a re-probe)."""
        names = ("water_flow_kg_h", "water_in_temp_C", "water_out_temp_C")
        if not all(self.has(n) and np.isfinite(self.columns[n]).any() for n in names):
            return None
        flow, t_in, t_out = (fill_gaps(self.columns[n], self.t) for n in names)
        return heat_to_water_kW(flow, t_in, t_out)

    def balance_without_refills(self) -> np.ndarray:
        """The balance's readings (:meth:`balance_readings`) with its refills taken out
        (:func:`without_refills`), computed once per log however many analyses and checks
        read it (again if the column is replaced)."""
        mass, t = self.columns["balance_mass_kg"], self.t
        cached = self._unrefilled
        if cached is None or cached[0] is not mass or cached[1] is not t:
            cached = self._unrefilled = (mass, t, without_refills(self.balance_readings()[0], t))
        return cached[2]

    def has(self, name: str) -> bool:
        return name in self.columns or name in self.text

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __len__(self) -> int:
        return len(self.columns["time_s"])


def read_log(
    path: str | Path, required: tuple[str, ...] = REQUIRED, *, as_read: bool = False
) -> LabLog:
    """Read and validate a lab log (see the module docstring); ``as_read`` keeps every
    reading as the log has it (no finiteness or range check: a fault report compares
    injected values, error codes included, with what was logged)."""
    path = Path(path)
    notes: list[str] = []  # what was tolerated, one line each
    reader = csv.reader(_lines(_text_of(path, notes)))
    header = _header(path, reader, notes)
    for name in required:
        if name not in header:
            like = next((h for h in header if _bare(h) == name.lower()), None)
            hint = (
                f" (column '{_shown(like)}' has a unit or note after the name: rename it '{name}')"
                if like is not None
                else ""
            )
            raise LogError(f"{path}: missing required column '{name}'{hint}")
    named = [h for h in header if h]  # unnamed columns: a spreadsheet's trailing ones
    if len(set(named)) != len(named):
        dup = next(h for h in named if named.count(h) > 1)
        raise LogError(f"{path}: column '{_shown(dup)}' appears twice")
    # rows may end before the header's trailing unnamed columns (a spreadsheet wrote
    # them in the header only): such a row is whole, its missing fields empty
    named_width = len(header)
    while named_width and not header[named_width - 1]:
        named_width -= 1
    parsed = _Parsed(path, header, as_read, required)
    raw: list[list[str]] = []  # rows not parsed yet: the last two wait for the checks below
    comments = 0
    odd: tuple[int, int] | None = None  # (line, fields) of a row of the wrong width
    try:
        for row in reader:
            if not "".join(row).strip():  # a blank line, or a spreadsheet's
                continue  # row of empty fields (",,,,")
            first = row[0].strip()  # a comment: no time_s starts so but Excel's #N/A
            if first.startswith("#") and first.upper() not in _NO_READING:
                comments += 1
                continue
            if odd is not None:
                break  # a row follows the odd one: refused below
            if named_width <= len(row) < len(header):
                row = row + [""] * (len(header) - len(row))
            if len(row) != len(header):
                odd = (reader.line_num, len(row))
                continue
            raw.append(row)
            if len(raw) >= _CHUNK_ROWS + 2:  # (rows as lists of text took 14 times the
                parsed.add(raw[:-2])  # file's size: a million-row log did not fit)
                del raw[:-2]
    except csv.Error as exc:
        raise LogError(f"{path}: line {reader.line_num}: {exc}") from None
    if comments:
        notes.append(f"{path}: {comments} comment line(s) (#...) among the rows skipped")
    if odd is not None:
        line, fields = odd
        if fields < len(header) and reader.line_num == line and _ends_unterminated(path):
            notes.append(
                f"{path}: the last row (line {line}) is cut short ({fields} of {len(header)} "
                "fields, no line end: the acquisition stopped while writing it); ignored"
            )
        else:
            raise LogError(f"{path}: row {line} has {fields} fields, header has {len(header)}")
    elif len(raw) >= 2 and _ends_unterminated(path) and not _whole(raw[-1][-1], raw[-2][-1]):
        notes.append(
            f"{path}: the last row (line {reader.line_num}) has no line end and its last "
            f"field '{_shown(raw[-1][-1])}' is shorter than the row before's "
            f"'{_shown(raw[-2][-1])}' (the "
            "acquisition stopped while writing it); ignored"
        )
        raw.pop()
    parsed.add(raw)
    if not parsed.rows:
        raise LogError(f"{path}: no data rows")
    columns, text = parsed.finish(notes)
    t = columns["time_s"]
    if np.isnan(t).any():
        i = int(np.flatnonzero(np.isnan(t))[0])
        raise LogError(f"{path}: column 'time_s' row {i + 2} is empty")
    _drop_rows_written_twice(path, columns, text, notes)
    t = columns["time_s"]
    steps = np.diff(t)
    if (steps <= 0).any():
        i = int(np.flatnonzero(steps <= 0)[0])
        twice = " with other readings than the row before" if steps[i] == 0 else ""
        raise LogError(
            f"{path}: column 'time_s' is not increasing at row {i + 3} ({t[i]:g} -> "
            f"{t[i + 1]:g}){twice}"
        )
    meta_file = path.with_name(path.stem + ".meta.json")
    meta = _meta(meta_file)
    notes += [unread_key_note(k, m, meta_file) for k, m in unread_meta_keys(meta).items()]
    if not as_read:
        _drop_error_codes(path, columns, text, meta, meta_file, notes)
    return LabLog(path, columns, text, meta, notes)


def _drop_rows_written_twice(
    path: Path, columns: dict[str, np.ndarray], text: dict[str, list[str]], notes: list[str]
) -> None:
    """Drop each row that repeats the row before it, field for field (a logger that wrote
    a row twice: its time does not advance, and the log was refused for it, though nothing
    is lost by reading it once: a stranger's probe), said in ``notes``. A time repeated with
    other readings is left for the caller to refuse: which row holds is not to be guessed."""
    t = columns["time_s"]
    same = np.diff(t) == 0
    if not same.any():
        return
    for values in columns.values():
        a, b = values[:-1], values[1:]
        same &= (a == b) | (np.isnan(a) & np.isnan(b))
    for values in text.values():
        same &= np.array([x == y for x, y in itertools.pairwise(values)], dtype=bool)
    if not same.any():
        return
    keep = np.concatenate(([True], ~same))
    for name, values in columns.items():
        columns[name] = values[keep]
    for name, values in text.items():
        text[name] = [v for v, k in zip(values, keep, strict=True) if k]
    first = int(np.flatnonzero(same)[0]) + 3  # (the repeat's row, the header being row 1)
    notes.append(
        f"{path}: {int(same.sum())} row(s) written twice (the same time and readings as the "
        f"row before, the first at row {first}); read once"
    )


class _TwiceError(ValueError):
    """A JSON object with a key twice (the key)."""


def _object_once(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _TwiceError(key[:40])
        out[key] = value
    return out


def _meta(meta_file: Path) -> dict[str, Any]:
    """The log's meta file as an object, {} where there is none."""
    meta: dict[str, Any] = {}
    if meta_file.exists() and not meta_file.is_file():  # a FIFO or a device: read forever
        raise LogError(f"{meta_file}: not a regular file, not a meta file")
    if meta_file.exists():
        try:
            text = meta_file.read_text(encoding="utf-8-sig")  # BOM dropped
            meta = json.loads(text, object_pairs_hook=_object_once)
        except _TwiceError as exc:  # (the last silently won: a stranger's probe)
            raise LogError(f"{meta_file}: key '{exc}' appears twice in one object") from None
        except UnicodeDecodeError as exc:
            raise LogError(f"{meta_file}: not UTF-8 text (byte at {exc.start})") from None
        except OSError as exc:
            raise LogError(f"{meta_file}: cannot read ({exc.strerror})") from None
        except json.JSONDecodeError as exc:
            raise LogError(f"{meta_file}: not valid JSON ({exc})") from None
        except RecursionError:
            raise LogError(f"{meta_file}: not valid JSON (nested too deeply)") from None
        if not isinstance(meta, dict):
            raise LogError(f"{meta_file}: expected a JSON object")
    return meta


#: The meta file's keys the analyses read (CONTRACT section 3, and the error codes').
META_KEYS_READ = ("boiler", "test", "t0_s", "t1_s", "t2_s", "t3_s", "t4_s", "missing_values")


def unread_meta_keys(meta: dict[str, Any]) -> dict[str, str]:
    """The keys of ``meta`` written like one the analyses read but not as they read it
    (``t0``, ``T1_s``, ``t2 [s]``, ``Boiler``), each with the key meant: its mark was
    silently not used and the phases came from the signals (a stranger's review). Beside
    the key meant, a variant is the lab's own (a 'Boiler' serial: a re-probe), as are all
    other keys."""
    unread = {}
    for key in meta:
        if key in META_KEYS_READ:
            continue
        bare = re.sub(r"[^a-z0-9]", "", key.lower())
        meant = next(
            (
                k
                for k in META_KEYS_READ
                if bare == k.replace("_", "")
                or (
                    k.endswith("_s")
                    and re.fullmatch(re.escape(k[:-2]) + r"(s|sec|secs|seconds|min|ms)?", bare)
                )
            ),
            None,
        )
        if meant is not None and meant not in meta:
            unread[key] = meant
    return unread


def unread_key_note(key: str, meant: str, meta_file: Path) -> str:
    """The line that names an unread meta key (:func:`unread_meta_keys`)."""
    return f"key '{_shown(key)}' of {meta_file.name} is not read: the analyses read '{meant}'"


def _drop_error_codes(
    path: Path,
    columns: dict[str, np.ndarray],
    text: dict[str, list[str]],
    meta: dict[str, Any],
    meta_file: Path,
    notes: list[str],
) -> None:
    """Instruments' error codes inside the plausible ranges (:mod:`.error_codes`: all
    nines in the instruments' columns, and what the meta file declares) taken as missing,
    one note per column."""
    try:
        declared = declared_codes(
            meta,
            list(columns),
            KNOWN_COLUMNS - INSTRUMENT_COLUMNS,
            [*text, *TEXT_COLUMNS],
            meta_file,
        )
    except CodesError as exc:
        raise LogError(str(exc)) from None
    for name, values in columns.items():
        codes = np.zeros(values.shape, dtype=bool)
        if name in declared:
            codes |= near(values, declared[name])
        if name in INSTRUMENT_COLUMNS:  # (on what the declared codes leave: a re-probe)
            left = np.where(codes, np.nan, values)
            nines, kept = nines_verdict(left)
            codes |= nines
            if kept and np.unique(left[np.isfinite(left)]).size > 1:  # (a constant column
                # is what the checks of a stuck sensor name)
                shown = ", ".join(f"{v:g}" for v in kept[:4])
                notes.append(
                    f"{path}: column '{name}': all-nines values ({shown}) that may be an "
                    "instrument's error codes or its readings, which the log cannot tell "
                    "apart; kept as readings (the meta file's missing_values names codes)"
                )
        if codes.any():
            i = int(np.flatnonzero(codes)[0])
            found = ", ".join(f"{v:g}" for v in np.unique(values[codes])[:4])
            notes.append(
                f"{path}: column '{name}': {int(codes.sum())} reading(s) {found} (first row "
                f"{i + 2}), taken as missing (an instrument's error code)"
            )
            values[codes] = np.nan


#: Rows parsed into columns at a time (a few tens of MB of text fields at most)
_CHUNK_ROWS = 20_000
_LINE_END = re.compile(r"\r\n|\r|\n")


def _lines(text: str) -> Iterator[str]:
    """The lines of ``text`` with their ends, as a file opened with ``newline=""`` gives
    them to :mod:`csv` (a StringIO of a long log held four bytes a character)."""
    start = 0
    for end in _LINE_END.finditer(text):
        yield text[start : end.end()]
        start = end.end()
    if start < len(text):
        yield text[start:]


class _Parsed:
    """The rows of a log parsed into columns a chunk at a time (see :func:`read_log`):
    numbers as float arrays, text as lists, a number column's first unreadable field and
    first implausible reading kept as written for the messages."""

    def __init__(
        self, path: Path, header: list[str], as_read: bool, required: tuple[str, ...] = ()
    ) -> None:
        self.path = path
        self.required = required
        self.header = header
        self.as_read = as_read
        self.rows = 0
        #: per column: float parts, or text (TEXT_COLUMNS, the lab's own, unnamed ones)
        self.parts: dict[int, list[np.ndarray]] = {}
        self.strings: dict[int, list[str]] = {}
        for j, name in enumerate(header):
            if not name or name in TEXT_COLUMNS or name not in KNOWN_COLUMNS:
                self.strings[j] = []
            else:
                self.parts[j] = []
        #: per number column: (row, field as written) of its first implausible reading
        self.first_wild: dict[int, tuple[int, str]] = {}
        #: per number column: [fields read as no reading (NaN, NA, #N/A ...), the first's
        #: row, that field as written] (said, as the implausible ones are: a stranger's probe)
        self.no_reading: dict[int, list] = {}

    def add(self, rows: list[list[str]]) -> None:
        if not rows:
            return
        for j, values in enumerate(zip(*rows, strict=True)):
            if j in self.strings:
                self.strings[j].extend(values)
                continue
            out = _numbers(values)
            if out is None:
                name = self.header[j]
                i, v = next((i, v) for i, v in enumerate(values) if v.strip() and not _is_number(v))
                raise LogError(
                    f"{self.path}: column '{name}' row {self.rows + i + 2}: '{_shown(v)}' is "
                    "not a number"
                )
            self._count_no_readings(j, values, out, self.rows)
            if not self.as_read and j not in self.first_wild:
                low, high = plausible_range(self.header[j])
                wild = np.isinf(out) | (out < low) | (out > high)
                if wild.any():
                    i = int(np.flatnonzero(wild)[0])
                    self.first_wild[j] = (self.rows + i, values[i])
            self.parts[j].append(out)
        self.rows += len(rows)

    def _count_no_readings(self, j: int, values: Any, out: np.ndarray, first_row: int) -> None:
        """Count the fields of column ``j`` written but read as no reading (``out`` NaN)."""
        missing = np.flatnonzero(np.isnan(out))
        said = [int(i) for i in missing if values[i].strip()] if len(missing) else []
        if said:
            seen = self.no_reading.setdefault(j, [0, first_row + said[0], values[said[0]]])
            seen[0] += len(said)

    def finish(self, notes: list[str]) -> tuple[dict[str, np.ndarray], dict[str, list[str]]]:
        """The columns and the text columns, with what was tolerated added to ``notes``."""
        path = self.path
        columns: dict[str, np.ndarray] = {}
        text: dict[str, list[str]] = {}
        for j, name in enumerate(self.header):
            if j in self.strings:
                values = self.strings.pop(j)
                if not name:  # a column without a name (Excel's trailing ones): no reading
                    if any(v.strip() for v in values):
                        notes.append(f"{path}: column {j + 1} has no name; not analysed")
                    continue
                if name in TEXT_COLUMNS:
                    text[name] = values
                    continue
                out = _numbers(values)  # a column of the lab's own: kept, not analysed
                if out is None:
                    text[name] = values
                    notes.append(f"{path}: column '{name}' is text, not a reading; not analysed")
                    continue
                if self.as_read:
                    columns[name] = out
                    continue
                low, high = plausible_range(name)
                wild = np.isinf(out) | (out < low) | (out > high)
                if wild.any():
                    i = int(np.flatnonzero(wild)[0])
                    self.first_wild[j] = (i, values[i])
            else:
                parts = self.parts.pop(j)
                out = np.concatenate(parts) if len(parts) != 1 else parts[0]
                del parts
            if j in self.first_wild:
                self._implausible(name, out, *self.first_wild[j], notes)
            if j in self.no_reading:
                count, i, written = self.no_reading[j]
                if name == "time_s":
                    raise LogError(
                        f"{path}: column 'time_s' row {i + 2}: '{_shown(written)}' is no time"
                    )
                notes.append(
                    f"{path}: column '{name}': {count} field(s) written as no reading (first "
                    f"row {i + 2}: '{_shown(written)}'), taken as missing"
                )
            columns[name] = out
        return columns, text

    def _implausible(
        self, name: str, out: np.ndarray, i: int, written: str, notes: list[str]
    ) -> None:
        """Readings beyond what the column's instrument can read taken as missing (in
        ``out``) and said; in ``time_s`` refused."""
        path = self.path
        if name == "time_s":
            raise LogError(
                f"{path}: column 'time_s' row {i + 2}: '{_shown(written)}' is not finite"
            )
        low, high = plausible_range(name)
        wild = np.isinf(out) | (out < low) | (out > high)
        beyond = f"outside {low:g}..{high:g}" if math.isfinite(high) else "not finite"
        why = "an instrument's error code"
        values = out[wild & np.isfinite(out)]
        if (
            name in self.required
            and len(values) > 0.5 * np.isfinite(out).sum()
            and len(np.unique(values)) > UNIT_DISTINCT_MIN
        ):  # most readings, and varied: a unit, not an error code (a balance in grams
            # was taken as missing whole, and then "has no values": a stranger's probe)
            around = float(np.median(values))
            unit = name.rsplit("_", 1)[-1]
            hint = (
                "grams? (kg expected)"
                if name.endswith("_kg") and low <= around / 1000.0 <= high
                else f"another unit than its name's? ({unit} expected, {low:g}..{high:g})"
            )
            raise LogError(f"{path}: column '{name}' reads around {around:.6g}: {hint}")
        if wild.all() or wild.sum() > 0.5 * np.isfinite(out).sum():  # most: not codes
            why = f"most readings: is the column in another unit than its name's ({name})?"
        notes.append(
            f"{path}: column '{name}': {int(wild.sum())} reading(s) {beyond} (first row "
            f"{i + 2}: '{_shown(written)}'), taken as missing ({why})"
        )
        out[wild] = np.nan


#: A required column whose readings beyond its unit's range are most of them and take more
#: than this many values is in another unit (refused); fewer are an instrument's error codes
#: (-999, 9999), taken as missing.
UNIT_DISTINCT_MIN = 20


def _numbers(values: tuple[str, ...] | list[str]) -> np.ndarray | None:
    """Fields as numbers, an empty one or a spreadsheet's no-reading code NaN; None if one
    is not a number (float() reads '6_9' as 69 and a full-width '５' as 5: probes)."""
    joined = "".join(values)
    if "_" in joined or _other_digits(joined):
        return None
    try:  # every field a number (most columns): read at once
        return np.array(values, dtype=float)
    except ValueError:
        pass
    try:  # numbers and empty fields (a log's gaps): still at once
        return np.array([v or "nan" for v in values], dtype=float)
    except ValueError:
        pass
    try:
        return np.array(
            [v if v.strip() and v.strip().upper() not in _NO_READING else "nan" for v in values],
            dtype=float,
        )
    except ValueError:
        return None


#: What spreadsheets and data tools write for no reading, read as an empty field (NaN is
#: already one): Excel's error codes, R's and pandas' NA, SQL's NULL, Python's None, and a
#: dash ('n/a' read but 'NA' refused: a stranger's probe).
_NO_READING = frozenset(
    {"#N/A", "N/A", "#NV", "#NA", "#DIV/0!", "#VALUE!", "#NUM!", "NA", "NULL", "NONE", "-", "--"}
)


#: A log file longer than this is refused before it is read [bytes]: a day at 1 Hz of
#: the full log is about 60 MB.
MAX_LOG_BYTES = 1_000_000_000


#: The first bytes of a compressed file, what it is and how to undo it.
_ARCHIVES = (
    (b"\x1f\x8b", "gzip", "gunzip"),
    (b"PK\x03\x04", "a zip archive", "unzip"),
    (b"\xfd7zXZ\x00", "xz", "unxz"),
)


def _text_of(path: Path, notes: list[str]) -> str:
    """The log's text: UTF-8 (a spreadsheet's byte-order mark dropped) or, where it is not,
    Windows-1252 as Excel writes a CSV on Windows (said in ``notes``); a file that is
    neither, is no regular file (a device streams forever) or cannot be read is refused
    naming it and, for the encoding, the line."""
    try:
        if not path.is_file():
            what = "a directory" if path.is_dir() else "not a regular file"
            if not path.exists() and path.is_symlink():  # (called no such file: a probe)
                raise LogError(f"{path}: a symbolic link that leads to no file (a loop?)")
            if not path.exists():
                raise LogError(f"{path}: cannot read (No such file or directory)")
            raise LogError(f"{path}: {what}, not a lab log")
        if path.stat().st_size > MAX_LOG_BYTES:
            raise LogError(f"{path}: {path.stat().st_size:,} bytes, more than a lab log")
        data = path.read_bytes()
    except OSError as exc:
        raise LogError(f"{path}: cannot read ({exc.strerror})") from None
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):  # a spreadsheet's "Unicode text"
        try:
            notes.append(f"{path}: UTF-16 text (a byte-order mark), read as such")
            return data.decode("utf-16")
        except UnicodeDecodeError:
            raise LogError(f"{path}: starts as UTF-16 text but is not") from None
    for magic, what, undo in _ARCHIVES:  # (a gzip file was called UTF-16: a probe)
        if data.startswith(magic):
            raise LogError(f"{path}: compressed ({what}), not a lab log's text: {undo} it first")
    if b"\x00" in data[:65536]:
        line = data.count(b"\n", 0, data.index(b"\x00")) + 1
        raise LogError(
            f"{path}: line {line} holds NUL bytes: UTF-16 without its byte-order mark, or no"
            " text at all (a lab log is UTF-8 or Windows-1252 text)"
        )
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        try:  # a byte-order mark is UTF-8's even where the rest is not (pasted cells)
            text = data.removeprefix(codecs.BOM_UTF8).decode("cp1252")
        except UnicodeDecodeError:
            raise LogError(
                f"{path}: line {line}: byte 0x{data[exc.start]:02x} is neither UTF-8 nor "
                "Windows-1252 text (a binary file?)"
            ) from None
        notes.append(
            f"{path}: not UTF-8 (line {line} first); read as Windows-1252, as a spreadsheet "
            "on Windows writes it"
        )
        return text


def _header(path: Path, reader: Any, notes: list[str]) -> list[str]:
    """The header row: after any lines a spreadsheet or a logger puts before it (Excel's
    "sep=," and comment lines starting with #, both said in ``notes``); names matched to the
    log format's in any letter case."""
    skipped = []
    try:
        for header in reader:
            first = header[0].strip() if header else ""
            if first.lower().startswith("sep=") and not any(h.strip() for h in header[1:]):
                skipped.append(f"line {reader.line_num} ({_shown(first)})")
                continue
            if not any(h.strip() for h in header) or first.startswith("#"):
                comment = header and first.startswith("#")
                skipped.append(f"line {reader.line_num} (a comment)" if comment else "")
                continue
            break
        else:
            raise LogError(f"{path}: empty file (no header row)")
    except csv.Error as exc:
        raise LogError(f"{path}: not a CSV file ({exc})") from None
    if any(skipped):
        notes.append(f"{path}: {', '.join(s for s in skipped if s)} before the header skipped")
    header = [h.strip() for h in header]
    if len(header) == 1:
        for sep, what in ((";", "semicolons"), ("\t", "tabs")):
            if sep in header[0]:
                raise LogError(
                    f"{path}: fields separated by {what}, not commas (a lab log is a CSV: "
                    "commas between fields, '.' as the decimal point)"
                )
    by_case: dict[str, list[str]] = {}
    for h in header:
        if h:
            by_case.setdefault(h.lower(), []).append(h)
    clash = next((names for names in by_case.values() if len(set(names)) > 1), None)
    if clash is not None:  # (one of them was taken without a word: a re-probe)
        raise LogError(
            f"{path}: columns {' and '.join(repr(_shown(h)) for h in dict.fromkeys(clash))} "
            "differ only in letter case: which one is the reading?"
        )
    known = {name.lower(): name for name in (*KNOWN_COLUMNS, *TEXT_COLUMNS)}
    renamed = []
    for j, name in enumerate(header):
        proper = known.get(name.lower())
        if proper is not None and proper != name and proper not in header:
            renamed.append(f"'{_shown(name)}' as '{proper}'")
            header[j] = proper
    if renamed:
        notes.append(f"{path}: column {', '.join(renamed)} (the log format's letter case)")
    return header


def _bare(name: str) -> str:
    """A column's name without a unit or a note after it ('time_s [s]', 'time_s (s)'),
    in lower case."""
    return re.split(r"[\s\[(/]", name.strip(), maxsplit=1)[0].lower()


def _shown(value: str, width: int = 40) -> str:
    """A field as a message shows it: control characters escaped, at most ``width``
    characters (a field of 4,096 NUL bytes went to the terminal raw)."""
    text = value.encode("unicode_escape").decode("ascii") if not value.isprintable() else value
    return text if len(text) <= width else text[: width - 3] + "..."


def _whole(last: str, before: str) -> bool:
    """Whether the last field of a last row without a line end has the shape of the same
    field a row earlier: as many decimals, and at most one character shorter (a number cut
    in two loses digits, '23' of '231.84000'; a count may gain one, 999 to 1000)."""
    last, before = last.strip(), before.strip()

    def decimals(v: str) -> int:
        return len(v.split(".", 1)[1]) if "." in v else -1

    return decimals(last) == decimals(before) and len(last) >= len(before) - 1


def _ends_unterminated(path: Path) -> bool:
    """Whether the file's last byte is not a line end (a write cut off mid-row)."""
    with path.open("rb") as fh:
        fh.seek(0, 2)
        if fh.tell() == 0:
            return False
        fh.seek(-1, 2)
        return fh.read(1) not in (b"\n", b"\r")


def _other_digits(text: str) -> bool:
    """Whether ``text`` holds a digit of another script than ASCII's (float() reads '５' and
    '٥' as 5; no lab writes them so); other non-ASCII characters, a no-break space after a
    number a spreadsheet pasted, are float()'s to judge (a re-probe)."""
    return not text.isascii() and any(not c.isascii() and c.isdecimal() for c in text)


def _is_number(text: str) -> bool:
    if "_" in text or _other_digits(text):  # (float() reads '6_9' as 69; no lab writes it)
        return False
    try:
        float(text)
    except ValueError:
        return False
    return True


def _number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


#: The meta key :func:`one_plant` sets on the rows it keeps: the ``rig_epoch`` kept.
EPOCH_KEPT = "rig_epoch_kept"


def one_plant(log: LabLog) -> LabLog:
    """The rows of one plant: a log whose ``rig_epoch`` changes (a break the run went on
    from, CONTRACT section 7: a restarted server, another client's reset or advance) holds
    several plants, and a balance or a model run across a break joins them as if
    continuous. The longest stretch of one epoch is kept (the run's marks outside it
    dropped, its phases then read from its own rows), and a note names what is left out."""
    if not log.has("rig_epoch"):
        return log
    epoch = log["rig_epoch"]
    if np.all(np.isnan(epoch)) or len(np.unique(epoch[~np.isnan(epoch)])) < 2:
        return log
    change = np.flatnonzero(np.diff(epoch) != 0) + 1
    starts = np.concatenate(([0], change))
    ends = np.concatenate((change, [len(epoch)]))
    k = int(np.argmax(ends - starts))
    rows = slice(int(starts[k]), int(ends[k]))
    t = log.t
    breaks = ", ".join(f"{t[i - 1]:g} -> {t[i]:g}" for i in change[:3])
    if len(change) > 3:  # (a thousand breaks made a warning of kilobytes: a stranger's probe)
        breaks += f" and {len(change) - 3} more"
    kept = LabLog(
        log.path,
        {name: values[rows] for name, values in log.columns.items()},
        {name: values[rows] for name, values in log.text.items()},
        dict(log.meta),
        list(log.notes),
    )
    first, last = float(kept.t[0]), float(kept.t[-1])
    kept.meta[EPOCH_KEPT] = float(epoch[rows.start])  # (the phases' errors say so)
    marks = ("t0_s", "t1_s", "t2_s", "t3_s", "t4_s")
    before = [k for k in marks if _number(kept.meta.get(k)) and kept.meta[k] < first]
    for key in marks:
        mark = kept.meta.get(key)
        if _number(mark) and not first <= mark <= last:
            kept.meta[key] = None
    if before == ["t0_s"] and _number(kept.meta.get("t1_s")) and kept.meta["t1_s"] > first:
        # a later plant's rows in the start-up (``--on-restart continue``): it starts up
        # from its first row on, to the run's t1
        kept.meta["t0_s"] = first
    elif before:  # it begins in a later phase: the run's marks are no set for its rows,
        for key in marks:  # which tell the phases themselves
            if key in kept.meta:
                kept.meta[key] = None
    kept.notes.append(
        f"{log.path}: the log holds {len(starts)} plants (rig_epoch changes at time_s "
        f"{breaks}: a break the run went on from); only rig_epoch {epoch[rows.start]:g} "
        f"(time_s {first:g}..{last:g}, {len(kept)} of {len(log)} rows, the longest) is "
        "analysed, as a balance or a model run across a break would join two plants"
    )
    return kept


def fill_gaps(values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Missing values (NaN) linearly interpolated in time; ends held. All-NaN stays NaN."""
    ok = ~np.isnan(values)
    if ok.all() or not ok.any():
        return values
    return np.interp(t, t[ok], values[ok])


#: A rise of the balance's level bigger than this is a refill [kg]: fuel only leaves a
#: boiler, and the balance's noise and steps are a few hundredths of a kilogram.
REFILL_STEP_KG = 0.5


#: The burner fires where the flue gas holds less O2 than this [vol-%] (air is 20.95).
FIRING_O2_PCT = 19.0
#: Firing this long [s] changes any balance's reading (0.02 kg at 0.1 kg/h is 12 min): a
#: reading that stays exactly the same through it is stuck (where the heat the water took
#: meanwhile says that fuel left: :func:`stuck_stretches`).
STUCK_FIRING_S = 600.0
#: More energy than this no kilogram of wood gives [kJ/kg]: dry wood's higher heating value
#: is 18-20 MJ/kg (ENplus pellets: 19.8, the paper's Table 1). Heat the water took, over
#: this, is the least fuel that left the hopper.
HHV_MAX_KJ_KG = 21000.0
#: A balance still on one reading after the heat to the water says this many of its steps
#: of fuel left is stuck: at a low load a coarse balance (0.1 kg) holds a reading for half
#: an hour of firing, and is no stuck one.
STUCK_STEPS = 3


def balance_step_kg(mass_kg: np.ndarray) -> float:
    """The balance's smallest change between two readings [kg] (its resolution, where it
    rounds; 0 where it never changes)."""
    steps = np.abs(np.diff(mass_kg[~np.isnan(mass_kg)]))
    return float(steps[steps > 0].min()) if (steps > 0).any() else 0.0


def cumulative_heat_kJ(heat_kW: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The heat to the water summed over the rows' steps up to each row [kJ] (differences
    of it are the heat between rows), none over a gap in the record (:func:`record_steps`)."""
    dt, gap = record_steps(t)
    return np.cumsum(np.where(gap, 0.0, np.nan_to_num(heat_kW) * dt))


#: The heat a small boiler's body gives the water without fuel [kJ]: its water and steel,
#: 200-300 kJ/K (the paper's 12-kW boiler: 80 + 123), from the shut-off's 85 C to a 20 C
#: room: 13-20 MJ. Heat beyond it needs fuel (a sample taken minutes before the end of
#: firing was called a failed balance: the body's heat then needed fuel, a re-probe).
BODY_STORE_KJ = 20000.0


def heat_needs_a_fall(heat_kJ: float, step_kg: float) -> bool:
    """Whether ``heat_kJ`` taken by the water, beyond what the body can give it
    (:data:`BODY_STORE_KJ`), needs more fuel than :data:`STUCK_STEPS` of the balance's
    steps of ``step_kg`` (at :data:`HHV_MAX_KJ_KG`): a balance that did not move
    meanwhile read no fuel."""
    return heat_kJ - BODY_STORE_KJ >= STUCK_STEPS * step_kg * HHV_MAX_KJ_KG


#: Faster than this no small boiler's hopper empties by burning [kg/s]: EN 303-5 ends at
#: 500 kW, which fires about 0.03 kg/s of pellets (500 kW over a lower heating value of
#: ~17 MJ/kg as received, at ~90 % efficiency); half as fast again for a margin. A fall of
#: the balance faster than this (and over :data:`REFILL_STEP_KG`) is no fuel burnt.
BURN_MAX_KG_S = 0.05


@dataclass(frozen=True, slots=True)
class Unread:
    """A stretch of the balance's readings that are none: rows ``start`` to ``end``
    (exclusive; the log's length where it lasts to the end), and why, one line."""

    start: int
    end: int
    why: str


@dataclass(frozen=True, slots=True)
class Removal:
    """Fuel taken off the balance by hand (a sample scooped from the hopper, the hopper
    emptied, the balance tared): the readings from row ``row`` on stand ``kg`` lower
    than the fuel left, and why, one line."""

    row: int
    kg: float
    why: str


#: A level of the balance is read over at most this long [s] (the median of its readings,
#: or a line through them): long enough for a noisy balance's level to its own step
#: (:func:`level_readings`), short enough that a stationary test's firing holds steady
#: through it and fuel burnt meanwhile is read off the line's slope, as a refill's is
#: (:data:`POUR_RATE_FROM_S`).
LEVEL_MAX_S = 300.0


#: The median of n readings of Gaussian scatter sigma scatters this many sigma / sqrt(n)
#: (sqrt(pi / 2): its large-n efficiency against the mean).
MEDIAN_SPREAD = math.sqrt(math.pi / 2.0)


def balance_noise_kg(mass_kg: np.ndarray) -> float:
    """The scatter of one reading about the balance's level [kg]: the robust spread (the
    median absolute deviation, times 1.4826) of its changes from reading to reading, over
    sqrt(2) (two readings' scatters in each); 0 for a balance that only ever steps."""
    jumps = np.diff(mass_kg[~np.isnan(mass_kg)])
    if len(jumps) == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(jumps - np.median(jumps))) / math.sqrt(2.0))


#: A balance whose readings scatter more than this about its level [kg] (one standard
#: deviation) hides falls and rises of :data:`REFILL_STEP_KG` in its noise: they stand less
#: than four of its deviations out (a 0.6-kg sample on a 0.2-kg balance was fuel, and a
#: 0.3-kg balance's upward noise passed for refills, 2.6 times the fuel: a re-probe).
NOISY_BALANCE_KG = REFILL_STEP_KG / 4.0


def noisy_balance(mass_kg: np.ndarray) -> str | None:
    """The line saying that the balance's own noise (:func:`balance_noise_kg`, measured on
    its readings) is beyond :data:`NOISY_BALANCE_KG`, else None."""
    noise_kg = balance_noise_kg(mass_kg)
    if noise_kg <= NOISY_BALANCE_KG:
        return None
    return (
        f"column 'balance_mass_kg' scatters {noise_kg:.2f} kg from its level (its noise, "
        f"measured on the log): refills, samples and dropouts under some {4 * noise_kg:.1f} kg "
        "are not told from it, and the fuel figures carry it"
    )


def level_readings(noise_kg: float, step_kg: float, t: np.ndarray) -> int:
    """How many readings a level of the balance is read over: enough that their median
    scatters less than the balance's own step (:data:`MEDIAN_SPREAD` x ``noise_kg`` /
    sqrt(n) <= ``step_kg``), at least :data:`SMOOTH_READINGS`, over at most
    :data:`LEVEL_MAX_S` of the log's usual sampling. A single reading, however noisy,
    is no level: one sized a 0.6-kg sample as 1.1 kg, and one high reading after it was
    taken for a dropout's return (a re-probe)."""
    n = SMOOTH_READINGS
    if step_kg > 0 and noise_kg > 0:
        n = max(n, math.ceil((MEDIAN_SPREAD * noise_kg / step_kg) ** 2))
    dt = np.diff(t)
    period = float(np.median(dt)) if len(dt) and np.median(dt) > 0 else 1.0
    return int(min(n, max(SMOOTH_READINGS, LEVEL_MAX_S // period)))


def _line_step(
    m: np.ndarray, tt: np.ndarray, before: np.ndarray, after: np.ndarray, tol_kg: float
) -> tuple[float, float]:
    """(the fall between the readings ``before`` and ``after`` (rows), the slope [kg/s]): a
    line of one slope through both, stepping between them, by least squares, fitted again
    without the readings further than ``tol_kg`` from it (a wild reading is no level)."""
    rows = np.concatenate((before, after))
    x = tt[rows] - tt[before[-1]] if len(before) else tt[rows] - tt[after[0]]
    cols = [np.ones(len(rows)), (rows >= after[0]).astype(float)]
    if len(rows) >= 4 and np.ptp(x) > 0:  # (a slope wants readings enough)
        cols.insert(1, x)
    design = np.column_stack(cols)
    y = m[rows]
    keep = np.ones(len(rows), dtype=bool)
    coef = np.zeros(design.shape[1])
    for _ in range(2):  # bounded: a fit, then one again without the wild readings
        if keep.sum() < design.shape[1] or not keep[rows >= after[0]].any():
            break
        coef = np.linalg.lstsq(design[keep], y[keep], rcond=None)[0]
        keep = np.abs(y - design @ coef) <= tol_kg
    slope = float(coef[1]) if design.shape[1] == 3 else 0.0
    return -float(coef[-1]), slope


def _split(m: np.ndarray, lo: int, hi: int, slope: float, tt: np.ndarray) -> int:
    """The row in ``lo + 1..hi - 1`` where the readings ``lo..hi - 1``, less a line of
    ``slope``, are best read as two levels (least squares): where a fall really is."""
    y = m[lo:hi] - slope * (tt[lo:hi] - tt[lo])
    n = len(y)
    if n < 2:
        return lo
    c1, c2 = np.cumsum(y), np.cumsum(y * y)
    i = np.arange(1, n)  # readings left of the split
    left = c2[i - 1] - c1[i - 1] ** 2 / i
    right = (c2[-1] - c2[i - 1]) - (c1[-1] - c1[i - 1]) ** 2 / (n - i)
    return lo + 1 + int(np.argmin(left + right))


def balance_falls(
    mass_kg: np.ndarray, t: np.ndarray, heat_kW: np.ndarray | None = None
) -> tuple[list[Unread], list[Removal]]:
    """The balance's falls that are no fuel burnt: readings falling faster than
    :data:`BURN_MAX_KG_S` from one to the next (in one step, or in scoops up to
    :data:`POUR_PAUSE_S` apart while the fall over all stays that fast: ten scoops of
    0.4 kg, and a hopper emptied at 0.3 kg a reading, were fuel, re-probes), by more than
    :data:`REFILL_STEP_KG`, told on the balance's levels (medians, or a line through
    :func:`level_readings` of readings either side), not on single readings, and to
    below the lowest level of the :data:`POUR_DETECT_S` before (someone who leant on the
    balance and let go comes back to where it stood).

    - A dropout (:class:`Unread`, its readings none) where the level after its first
      reading up again is where it fell from less the fuel burnt meanwhile: at least what
      the water's heat (``heat_kW`` per row, None: unknown) needs at
      :data:`HHV_MAX_KJ_KG`, at most twice that, within the levels' own scatter (a single
      high reading after a sample on a noisy balance passed for its return, a re-probe).
    - A failed balance (:class:`Unread` to the end) where it then loses less, its refills
      counted back, than the heat after it needs beyond the body's own
      (:data:`BODY_STORE_KJ`).
    - A balance in another unit (:class:`Unread` to the end) where it falls that fast for
      longer than anyone pours (:data:`POUR_MAX_S`): grams read as kilograms.
    - Else fuel taken off by hand (:class:`Removal`: a sample, a tare), its size the
      step between the levels either side: the readings after it are read as the fuel
      left, as a refill's are, those while it fell none (taken as a balance that never
      came back, it left the rest of the log without a fuel figure, and ``validate`` half
      the fuel: a re-probe)."""
    ok = np.flatnonzero(~np.isnan(mass_kg))
    m, tt = mass_kg[ok], t[ok]
    dropouts: list[Unread] = []
    removals: list[Removal] = []
    fast = np.zeros(len(m), dtype=bool)  # per reading: fell from the one before too fast
    if len(m) > 1:
        step = m[:-1] - m[1:]
        fast[1:] = (step > 0) & (step > BURN_MAX_KG_S * np.diff(tt))
    step_kg = balance_step_kg(m)
    # the balance's own scatter, measured on the log: its levels are read over as many
    # readings as it needs (a sample on a noisy balance went unseen, was sized from two
    # single readings, or taken for a dropout: a re-probe)
    noise_kg = balance_noise_kg(m)
    n = level_readings(noise_kg, step_kg, tt)
    level_kg = MEDIAN_SPREAD * noise_kg / math.sqrt(n)  # a level's own scatter
    tolerance_kg = 2 * step_kg + 3 * math.sqrt(2.0) * level_kg  # two levels' difference
    wild_kg = 2 * step_kg + 4 * noise_kg  # a reading further than this off its level
    heat_kJ = cumulative_heat_kJ(heat_kW, t) if heat_kW is not None else None
    since = 0  # the readings before this belong to a fall already told
    k = 1
    while k < len(m):
        if not fast[k]:
            k += 1
            continue
        # the run of fast falls: readings k..end, pauses up to POUR_PAUSE_S in it, as long
        # as it falls faster than any boiler burns over all (a noisy balance's falls, a
        # few seconds apart, joined the whole log: a re-probe)
        end = k
        while True:
            nxt = end + 1
            while nxt < len(m) and not fast[nxt] and tt[nxt] - tt[end] <= POUR_PAUSE_S:
                nxt += 1
            fast_over_all = nxt < len(m) and m[k - 1] - m[nxt] > BURN_MAX_KG_S * (
                tt[nxt] - tt[k - 1]
            )
            if fast_over_all and fast[nxt] and tt[nxt] - tt[end] <= POUR_PAUSE_S:
                end = nxt
            else:
                break
        b0 = max(since, k - n)
        before = np.arange(b0, k)
        level_before = float(np.median(m[before])) if len(before) else float(m[k - 1])
        after = np.arange(end, min(end + n, len(m)))
        # to its lowest reading (a dropout's), beyond what the noise takes one reading
        # (a noisy balance's single low readings were dropouts by the dozen), and to the
        # level after
        depth = level_before - float(m[end])
        dips = depth - wild_kg > REFILL_STEP_KG
        drop = level_before - float(np.median(m[after]))
        if not dips and drop <= REFILL_STEP_KG:  # (noise, fuel burnt: most runs)
            k = end + 1
            continue
        what = f"at time_s {tt[k]:g}, faster than any small boiler burns"
        # its first reading up again whose level is up too (one noisy reading is not)
        # (at most twice the least fuel burnt: no boiler is under 50 % efficient on HHV; a
        # refill after fuel taken off lands above, and was taken for the balance coming
        # back, 1.6 kg put back of 2 taken below: re-probes. A dropout taken instead as fuel
        # taken off and a refill comes out the same fuel.)
        up = level_before - depth / 2.0
        rise = end + np.flatnonzero(m[end:] >= up) if dips else np.zeros(0, dtype=int)
        back: tuple[int, float] | None = None
        padded = np.concatenate((m, np.full(n - 1, np.nan))) if len(rise) else m
        windows = np.lib.stride_tricks.sliding_window_view(padded, n) if len(rise) else None
        for part in range(0, len(rise), 64):  # bounded: 64 candidates' levels at a time
            here = rise[part : part + 64]
            levels = np.nanmedian(windows[here], axis=1)  # type: ignore[index]
            up_again = np.flatnonzero(levels >= up)
            if len(up_again):
                back = (int(here[up_again[0]]), float(levels[up_again[0]]))
                break
        if back is not None:
            j, level_back = back
            # the fuel burnt between the times the two levels stand for (their middles)
            mid_b = before[len(before) // 2] if len(before) else k - 1
            mid_a = min(j + n // 2, len(m) - 1)
            burnt_kg = (
                0.0
                if heat_kJ is None
                else (heat_kJ[ok[mid_a]] - heat_kJ[ok[mid_b]]) / HHV_MAX_KJ_KG
            )
            expected = level_before - burnt_kg
            if expected - burnt_kg - tolerance_kg <= level_back <= expected + tolerance_kg:
                dropouts.append(
                    Unread(
                        int(ok[k]),
                        int(ok[j]),
                        f"falls {depth:.2f} kg in {tt[end] - tt[k - 1]:g} s {what}, and is "
                        f"back at time_s {tt[j]:g}",
                    )
                )
                since = j
                k = j + 1
                continue
        # no dropout: fuel taken off (or a failed balance), sized between the levels
        # sized on a line through all readings of LEVEL_MAX_S either side: its slope (the
        # fuel burnt meanwhile) from few readings of a noisy balance sized a 0.6-kg sample
        # 0.53-0.66 kg, the step's error sigma * sqrt(8 / readings) (a re-probe)
        wide_b = np.arange(int(np.searchsorted(tt, tt[k - 1] - LEVEL_MAX_S)), k)
        wide_a = np.arange(end, int(np.searchsorted(tt, tt[end] + LEVEL_MAX_S, "right")))
        fall, slope = _line_step(m, tt, wide_b, wide_a, wild_kg)
        # where the levels change: a run of noise just before a fall is not it
        at = _split(m, b0, after[-1] + 1, slope, tt) if len(before) else k
        lo = int(np.searchsorted(tt, tt[k - 1] - POUR_DETECT_S))
        lows = np.lib.stride_tricks.sliding_window_view(m[max(lo - n + 1, 0) : k], min(n, k))
        lowest = float(np.median(lows, axis=1).min()) if len(lows) else level_before
        level_after = level_before - drop
        if (
            fall <= REFILL_STEP_KG
            or not k - 1 <= at <= end + 1
            or level_after >= min(lowest, level_before) - REFILL_STEP_KG
        ):
            k = end + 1
            continue
        what = f"falls {fall:.2f} kg in {tt[end] - tt[k - 1]:g} s {what}"
        if tt[end] - tt[k - 1] > POUR_MAX_S:  # longer than anyone pours
            per_s = fall / (tt[end] - tt[k - 1])
            dropouts.append(
                Unread(
                    int(ok[k]),
                    len(mass_kg),
                    f"{what}, {per_s:.2g} kg/s for longer than anyone takes fuel off by "
                    "hand: is the column in another unit than its name's "
                    "(balance_mass_kg; grams?)",
                )
            )
            break
        heat_after = 0.0 if heat_kJ is None else heat_kJ[-1] - heat_kJ[ok[end]]
        needed_kg = max(heat_after - BODY_STORE_KJ, 0.0) / HHV_MAX_KJ_KG
        # what it lost after, its refills taken out (one counted against the loss made a
        # sample taken and a hopper refilled later a failed balance: a re-probe)
        last = float(np.median(m[max(end, len(m) - n) :]))
        lost_kg = level_after - last + sum(r.rise_kg for r in refills(m[end:], tt[end:]))
        if lost_kg + STUCK_STEPS * step_kg + tolerance_kg < needed_kg:  # no fuel read after
            dropouts.append(
                Unread(
                    int(ok[k]),
                    len(mass_kg),
                    f"{what}, and never comes back, losing less after than the water's heat "
                    "needs (a failed balance)",
                )
            )
            break
        if end > k:  # (the readings while it fell)
            dropouts.append(Unread(int(ok[k]), int(ok[end]), f"{what}, by hand"))
        removals.append(
            Removal(
                int(ok[end]),
                fall,
                f"{what} and stays there: fuel taken off by hand (a sample, a tare)"
                + ("" if needed_kg > 0 else ", or a failed balance (no firing after to tell)")
                + ", not counted as fuel",
            )
        )
        since = end
        k = end + 1
    return dropouts, removals


def stuck_stretches(
    mass_kg: np.ndarray, t: np.ndarray, firing: np.ndarray, heat_kW: np.ndarray | None = None
) -> list[Unread]:
    """Where the balance reads exactly the same through :data:`STUCK_FIRING_S` of firing
    (by ``firing``, per row; the steps of the record's gaps not counted) and, where the
    heat to the water is known (``heat_kW``, per row), through the heat of at least
    :data:`STUCK_STEPS` of its smallest steps of fuel (at :data:`HHV_MAX_KJ_KG`): its
    readings after the first of them are none (the first is where it stuck)."""
    ok = np.flatnonzero(~np.isnan(mass_kg))
    if len(ok) < 2:
        return []
    m = mass_kg[ok]
    dt, gap = record_steps(t)
    fired = np.concatenate(([0.0], np.cumsum(np.where(firing & ~gap, dt, 0.0))))
    step_kg = balance_step_kg(m)
    heat = np.concatenate(([0.0], cumulative_heat_kJ(heat_kW, t))) if heat_kW is not None else None
    starts = np.flatnonzero(np.concatenate(([True], m[1:] != m[:-1])))
    ends = np.concatenate((starts[1:], [len(m)])) - 1  # each run's last reading
    out = []
    for a, b in zip(starts, ends, strict=True):
        r0, r1 = int(ok[a]), int(ok[b])
        firing_s = fired[r1 + 1] - fired[r0 + 1]  # the rows after the first, to the last
        heat_kJ = math.inf if heat is None else heat[r1 + 1] - heat[r0 + 1]
        if b > a and firing_s >= STUCK_FIRING_S and heat_needs_a_fall(heat_kJ, step_kg):
            end = r1 + 1 if b + 1 < len(m) else len(mass_kg)
            out.append(
                Unread(
                    r0 + 1,
                    end,
                    f"reads {m[a]:g} kg from time_s {t[r0]:g} to {t[r1]:g}, through "
                    f"{firing_s / 60:.0f} min of firing (stuck)",
                )
            )
    return out


#: The balance's level is the median of its readings over this long before a refill
#: began and over :data:`LEVEL_AFTER_S` after it ended [s]: noise, a single wild reading or
#: someone leaning on the balance for up to half a minute moves no level (each was counted
#: as a refill: a balance with 0.1 kg of noise gave 127 "refills" and three times the
#: fuel, a stranger's probe).
LEVEL_S = 30.0


LEVEL_AFTER_S = 60.0


#: A refill is looked for where the smoothed reading (a median of
#: :data:`SMOOTH_READINGS` readings) stands :data:`REFILL_STEP_KG` above its lowest of the
#: last :data:`POUR_DETECT_S` [s]: a hopper topped up from a bag over one or two minutes,
#: by scoops or a slow pour of a few hundredths of a kilogram per reading.
POUR_DETECT_S = 120.0


SMOOTH_READINGS = 5


#: A pour goes on as long as the smoothed reading reaches a new high within this many
#: seconds of the last one [s] (scoops a few seconds apart), for at most
#: :data:`POUR_MAX_S` [s] (a bag after a bag).
POUR_PAUSE_S = 30.0


POUR_MAX_S = 600.0


#: The reading the pour rose from is the last within this much of the lowest [kg]: two
#: steps of the balance.
POUR_FOOT_KG = 0.04


@dataclass(frozen=True, slots=True)
class Refill:
    """One refill of the balance: rows of the last reading before it and of its highest
    reading, its rise between the levels before and after [kg], and the times the levels
    stand for [s] (their windows' middles)."""

    start: int
    peak: int
    rise_kg: float
    before_s: float
    after_s: float


def _smoothed(m: np.ndarray) -> np.ndarray:
    """The running median of :data:`SMOOTH_READINGS` readings (ends kept as they are)."""
    n, k = len(m), SMOOTH_READINGS
    if n < k:
        return m.copy()
    out = m.copy()
    half = k // 2
    out[half : n - half] = np.median(np.lib.stride_tricks.sliding_window_view(m, k), axis=1)
    return out


def _rolling_min_before(x: np.ndarray, t: np.ndarray, span_s: float) -> np.ndarray:
    """Per row, the lowest of ``x`` over the ``span_s`` before it (itself included)."""
    out = np.empty_like(x)
    window: deque[int] = deque()
    for i in range(len(x)):
        while window and x[window[-1]] >= x[i]:
            window.pop()
        window.append(i)
        while t[window[0]] < t[i] - span_s:
            window.popleft()
        out[i] = x[window[0]]
    return out


def refills(mass_kg: np.ndarray, t: np.ndarray) -> list[Refill]:
    """Every refill of the balance (:class:`Refill`): where the smoothed reading stands
    :data:`REFILL_STEP_KG` above its lowest of the last :data:`POUR_DETECT_S`, the pour is
    followed back to the last reading near that lowest and on to its highest as long as
    the smoothed reading reaches a new high within :data:`POUR_PAUSE_S`; it is a refill if
    the level after it (the median of :data:`LEVEL_AFTER_S` of readings from its highest) stands
    :data:`REFILL_STEP_KG` above the level before it (of the :data:`LEVEL_S` to its foot).
    One jump between two readings, scoops, a slow pour: a rise that stays; a reading
    that jumps and comes back is none."""
    ok = np.flatnonzero(~np.isnan(mass_kg))
    m, tt = mass_kg[ok], t[ok]
    if len(m) < 2:
        return []
    smooth = _smoothed(m)
    low = _rolling_min_before(smooth, tt, POUR_DETECT_S)
    found: list[Refill] = []
    done = 0  # readings up to here belong to a refill found already
    for k in np.flatnonzero(smooth - low > REFILL_STEP_KG):
        if k <= done:
            continue
        lo = max(done, int(np.searchsorted(tt, tt[k] - POUR_DETECT_S)))
        foot = lo + int(np.argmin(smooth[lo : k + 1]))
        near = np.flatnonzero(smooth[foot : k + 1] <= smooth[foot] + POUR_FOOT_KG)
        start = foot + int(near[-1])
        peak = j = k
        while (
            j + 1 < len(m)
            and tt[j + 1] - tt[peak] <= POUR_PAUSE_S
            and tt[j + 1] - tt[start] <= POUR_MAX_S
        ):
            j += 1
            if smooth[j] > smooth[peak]:
                peak = j
        before = (tt >= tt[start] - LEVEL_S) & (tt <= tt[start])
        before[: done + 1 if done else 0] = False
        after = (tt >= tt[peak]) & (tt <= tt[peak] + LEVEL_AFTER_S)
        if not before.any():  # the last refill ended where this one begins
            before[start] = True
        level_after = float(np.median(m[after]))
        rise = level_after - float(np.median(m[before]))
        # the pour ended at the first reading at the level after it (one jump: the first
        # reading after it), not where the smoothed reading, a few readings late, tops
        top = np.flatnonzero(m[start + 1 : peak + 1] >= level_after - POUR_FOOT_KG)
        if len(top):
            peak = start + 1 + int(top[0])
        if rise > REFILL_STEP_KG:
            found.append(
                Refill(
                    int(ok[start]),
                    int(ok[peak]),
                    rise,
                    float(np.median(tt[before])),
                    float(np.median(tt[after])),
                )
            )
            done = int(np.flatnonzero(after)[-1])
        else:
            done = k
    return found


#: The fuel burnt while a refill was poured is read from the balance's fall over this
#: long before it [s], from at least :data:`POUR_RATE_MIN_READINGS` readings: the pour
#: hides it, and a minute at 2.7 kg/h is 0.05 kg, more than two steps of the balance.
POUR_RATE_FROM_S = 300.0


POUR_RATE_MIN_READINGS = 30


def _fuel_rate_before(mass_kg: np.ndarray, t: np.ndarray, row: int, since: int) -> float:
    """The balance's fall per second over :data:`POUR_RATE_FROM_S` up to ``row`` (not
    before row ``since``: the last refill), 0 where it rises or has too few readings."""
    lo = max(since, int(np.searchsorted(t, t[row] - POUR_RATE_FROM_S)))
    rows = np.arange(lo, row + 1)
    rows = rows[~np.isnan(mass_kg[rows])]
    if len(rows) < POUR_RATE_MIN_READINGS or t[rows[-1]] <= t[rows[0]]:
        return 0.0
    return max(-float(np.polyfit(t[rows], mass_kg[rows], 1)[0]), 0.0)


def without_refills(mass_kg: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The balance reading with every refill (:func:`refills`) taken out, so that it only
    ever shows fuel leaving: the readings after a refill less its rise between the levels
    and the fuel burnt between the times they stand for (at the rate the balance fell
    before it), the readings while it was poured missing (the mass on a balance being
    filled is no reading of the fuel); gaps stay."""
    out = mass_kg.astype(float)
    since = 0
    for refill in refills(mass_kg, t):
        rate = _fuel_rate_before(mass_kg, t, refill.start, since)
        out[refill.start + 1 : refill.peak] = np.nan
        out[refill.peak :] -= refill.rise_kg + rate * (refill.after_s - refill.before_s)
        since = refill.peak
    return out
