"""The project's YAML reader: numbers as YAML 1.2 writes them, no key twice, one line."""

from __future__ import annotations

from pathlib import Path

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


def test_plain_scalars_are_read_as_yaml_1_2_reads_them(tmp_path):
    """A stranger's probe with register numbers copied from a vendor sheet: YAML 1.1 read
    ``010`` as octal (unit 8), ``1:10`` in base 60 (address 70) and ``on`` as true (a
    point named 'on' became 'True')."""
    data = _read(
        tmp_path,
        "a: 010\nb: 0100\nc: 1:10\nd: on\ne: yes\nf: 0x1F\ng: 0o17\nh: true\ni: -0.5\n"
        "j: .inf\nk: 1_000\nl: 190:20:30.15\n",
    )
    assert data == {
        "a": 10,
        "b": 100,
        "c": "1:10",
        "d": "on",
        "e": "yes",
        "f": 31,
        "g": 15,
        "h": True,
        "i": -0.5,
        "j": float("inf"),
        "k": "1_000",
        "l": "190:20:30.15",
    }


def test_a_tab_in_the_indentation_is_named(tmp_path):
    with pytest.raises(Bad) as info:
        _read(tmp_path, "name: t\ndevices:\n\t- name: plc\n")
    assert str(info.value).endswith("not valid YAML at line 3 (a tab: YAML indents with spaces)")


def test_aliases_that_expand_to_millions_of_values_are_refused(tmp_path):
    """A stranger's probe: 551 bytes of aliases nested ten deep (a "billion laughs") in a
    map's description ran map-doc 24 s in 2.5 GB; any message showing such a value would."""
    levels = ["a: &a [x, x, x, x, x, x, x, x, x, x]"]
    for name, below in zip("bcdefg", "abcdef", strict=True):
        levels.append(f"{name}: &{name} [{', '.join([f'*{below}'] * 10)}]")
    with pytest.raises(Bad, match=r"aliases .* expand to more than 2,000,000 values"):
        _read(tmp_path, "\n".join([*levels, "p_nom_kW: *g"]) + "\n")
    assert _read(tmp_path, "\n".join(levels[:4]) + "\n")["d"][0][0][0] == ["x"] * 10  # 10^4


def test_aliases_through_pairs_and_sets_are_bounded_too(tmp_path):
    """A re-probe: !!pairs and !!omap build tuples, which the bound did not walk (a 1-kB
    boiler file wrote a 58-MB error line)."""
    levels = ["a: &a [x, x, x, x, x, x, x, x, x, x]"]
    for name, below in zip("bcdefg", "abcdef", strict=True):
        levels.append(f"{name}: &{name} !!pairs [{', '.join([f'k: *{below}'] * 10)}]")
    with pytest.raises(Bad, match=r"aliases .* expand to more than 2,000,000 values"):
        _read(tmp_path, "\n".join(levels) + "\n")


@pytest.mark.parametrize(
    "value", ["!!bool maybe", "!!timestamp x", "!!int abc", "!!float abc", "!!float", "!!float ''"]
)
def test_a_tagged_value_its_tag_cannot_read_is_one_line(tmp_path, value):
    """A re-probe: !!bool maybe ended in KeyError's traceback, !!timestamp x in an
    AttributeError, !!int abc was "a number of thousands of digits"."""
    with pytest.raises(Bad, match=r"not valid YAML \(a value its !!tag cannot read\)$"):
        _read(tmp_path, f"a: {value}\n")


def test_dates_are_text_and_what_is_written_reads_back(tmp_path):
    """A re-probe: YAML 1.1's dates were still read (a map named 2024-05-01 was 'a date'),
    and calibrate wrote a boiler named "0o17" bare, read back as the number 15."""
    from rig_emulator.yamlio import dump_yaml

    assert _read(tmp_path, "a: 2024-05-01\n") == {"a": "2024-05-01"}
    names = ["0o17", "1e3", "010", "true", "2024-05-01", "on", " padded", "a: b", "", "-"]
    data = {"names": names, "n": 3, "x": 1.5}
    path = tmp_path / "round.yaml"
    path.write_text(dump_yaml(data))
    assert read_yaml(path, Bad) == data


def test_a_folder_named_as_a_shipped_file_does_not_shadow_it(tmp_path, monkeypatch, capsys):
    """A re-probe: in a directory holding a folder ``clean``, every ``hil-client run`` failed
    with "--profile: clean: cannot read (Is a directory)", ``--profile`` given or not. A
    shipped NAME is the shipped file; ``./clean`` still names the folder (and is refused)."""
    from hil_client.cli import main as hil_client_main
    from rig_emulator.cli import main as rig_emulator_main

    (tmp_path / "clean").mkdir()
    (tmp_path / "windhager_6kw").mkdir()
    monkeypatch.chdir(tmp_path)
    protocol = Path(__file__).parents[1] / "data" / "short_protocol.yaml"
    argv = ["run", str(protocol), "--boiler", "windhager_6kw", "--rig", "local", "--quiet"]
    assert hil_client_main([*argv, "--out", "a.csv"]) == 0
    assert hil_client_main([*argv, "--profile", "clean", "--out", "b.csv"]) == 0
    assert rig_emulator_main(["check", "--boiler", "windhager_6kw"]) == 0
    capsys.readouterr()
    assert hil_client_main([*argv, "--profile", "./clean", "--out", "c.csv"]) == 2
    assert "clean" in capsys.readouterr().err
