"""The project's YAML reader: numbers as YAML 1.2 writes them, no key twice, one line."""

from __future__ import annotations

import pytest

from rig_emulator.yamlio import read_yaml


class Bad(ValueError):
    pass


def _read(tmp_path, text: str):
    path = tmp_path / "data.yaml"
    path.write_text(text)
    return read_yaml(path, Bad)


def test_numbers_in_exponent_form_without_a_dot_are_numbers(tmp_path):
    """YAML 1.1 (PyYAML's default) reads 1e12 and 2E-3 as text, so a file saying
    ``delay_ms: 8e2`` was refused as 'not a number'."""
    data = _read(tmp_path, "a: 1e12\nb: 2E-3\nc: -3e+2\nd: 1.0e308\ne: 12\nf: text\ng: 1e\n")
    assert data == {"a": 1e12, "b": 2e-3, "c": -300.0, "d": 1e308, "e": 12, "f": "text", "g": "1e"}


def test_a_key_given_twice_is_refused_naming_it_and_its_line(tmp_path):
    """PyYAML lets the last of two equal keys win silently: a boiler file with two
    p_nom_kW would use the second."""
    with pytest.raises(Bad) as info:
        _read(tmp_path, "a: 1\nb:\n  c: 2\n  c: 3\n")
    assert "line 4" in str(info.value) and "key 'c' appears twice" in str(info.value)


def test_merge_keys_may_be_overridden(tmp_path):
    data = _read(tmp_path, "base: &b {x: 1, y: 1}\nd:\n  <<: *b\n  x: 2\n")
    assert data["d"] == {"x": 2, "y": 1}


def test_an_integer_of_thousands_of_digits_is_one_line(tmp_path):
    with pytest.raises(Bad) as info:
        _read(tmp_path, "a: " + "9" * 5000 + "\n")
    assert "not valid YAML" in str(info.value) and "\n" not in str(info.value)


def test_a_file_nested_thousands_deep_is_one_line(tmp_path):
    with pytest.raises(Bad) as info:
        _read(tmp_path, "a: " + "[" * 3000 + "]" * 3000 + "\n")
    assert "nested too deeply" in str(info.value)


def test_a_set_up_file_of_many_megabytes_is_refused_before_it_is_parsed(tmp_path):
    """A 20-MB register map parsed for 90 s in 1.2 GB without a word (a stranger's probe):
    a file larger than any set-up file is one line at once."""
    path = tmp_path / "huge.yaml"
    path.write_text("points:\n" + "  - {name: p, address: 1}\n" * 200_000)
    with pytest.raises(ValueError, match=r"huge.yaml: 5 MB, more than any set-up file"):
        read_yaml(path, ValueError)
