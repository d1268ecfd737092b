"""A long log read a chunk of rows at a time (:func:`hil_client.analysis.logio.read_log`)
reads as one read whole: row numbers in messages, a reading code past the first chunk, a
lab's own column that turns to text late, a last row cut short at a chunk's end."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hil_client.analysis.logio import REQUIRED, LogError, read_log

ROWS = 45_000  # more than two chunks of 20,000


def _write(path: Path, rows: int = ROWS, edit=None, end: str = "\n") -> Path:
    header = [*REQUIRED, "operator_note"]
    lines = [",".join(header)]
    for i in range(rows):
        fields = [
            f"{i:.3f}",
            "600.0",
            "50.0",
            "65.0",
            "70.0",
            "150.0",
            "8.0",
            f"{50 - i * 1e-4:.5f}",
        ]
        fields += ["20.0", "1.25"]
        if edit is not None:
            edit(i, fields)
        lines.append(",".join(fields))
    path.write_text("\n".join(lines) + end)
    return path


def test_a_reading_code_past_the_first_chunk_is_named_at_its_row(tmp_path):
    def code(i, fields):
        if i in (30_000, 44_000):
            fields[5] = "-999"

    log = read_log(_write(tmp_path / "log.csv", edit=code))
    assert len(log) == ROWS
    flue = log["flue_gas_temp_C"]
    assert (
        np.isnan(flue[[30_000, 44_000]]).all()
        and np.isfinite(np.delete(flue, [30_000, 44_000])).all()
    )
    (note,) = [n for n in log.notes if "flue_gas_temp_C" in n]
    assert "2 reading(s)" in note and "first row 30002: '-999'" in note, note
    assert log["balance_mass_kg"][-1] == pytest.approx(50 - (ROWS - 1) * 1e-4)


def test_a_field_that_is_no_number_past_the_first_chunk_is_refused_at_its_row(tmp_path):
    def text(i, fields):
        if i == 41_234:
            fields[2] = "warm"

    with pytest.raises(
        LogError, match=r"column 'water_in_temp_C' row 41236: 'warm' is not a number"
    ):
        read_log(_write(tmp_path / "log.csv", edit=text))


def test_a_labs_own_column_that_turns_to_text_late_is_text_throughout(tmp_path):
    def note(i, fields):
        if i == 43_000:
            fields[-1] = "cleaned the probe"

    log = read_log(_write(tmp_path / "log.csv", edit=note))
    assert "operator_note" not in log.columns
    assert (
        log.text["operator_note"][0] == "1.25"
        and log.text["operator_note"][43_000] == "cleaned the probe"
    )
    assert len(log.text["operator_note"]) == ROWS


@pytest.mark.parametrize("rows", [40_001, 40_002, 40_003])
def test_a_last_row_cut_short_at_a_chunks_end_is_left_out(tmp_path, rows):
    """The last two rows wait for the cut-row check whatever the chunks: a number cut in
    two ('1' of '1.25') on a last row without a line end."""
    path = _write(tmp_path / "log.csv", rows=rows, end="")
    text = path.read_text()
    path.write_text(text[:-3])  # the last field cut to '1'

    log = read_log(path)
    assert len(log) == rows - 1
    assert math.isclose(log.t[-1], rows - 2)
