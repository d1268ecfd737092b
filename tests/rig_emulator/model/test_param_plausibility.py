"""Parameter files that pass every range check but describe a boiler physics does not allow
(a stranger's probe): each is refused in one line naming the key and why, exit 2, by every
command that loads it; the unusual but possible ones still load."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

from hil_client.cli import main as hil_client_main
from rig_emulator.boilers import BOILER_DIR
from rig_emulator.cli import main as rig_emulator_main
from rig_emulator.model import params as model_params


def _variant(tmp_path: Path, fuel: dict[str, Any] | None = None, **changes: Any) -> Path:
    """The shipped 12-kW file with ``changes`` (and ``fuel`` changes), as a file."""
    data = yaml.safe_load((BOILER_DIR / "windhager_12kw.yaml").read_text())
    data.update(changes)
    data["fuel"].update(fuel or {})
    path = tmp_path / "variant.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _refused(capsys, argv: list[str], *fragments: str) -> str:
    """``rig-emulator ARGV`` exits 2 with one line holding every fragment."""
    assert rig_emulator_main(argv) == 2
    captured = capsys.readouterr()
    err = captured.err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for fragment in fragments:
        assert fragment in err, err
    assert captured.out == ""  # (steady printed the split with Q_water < 0)
    return err


#: The stranger's one-key variants of windhager_12kw.yaml (each accepted by `check`, and
#: `steady` printed sub-zero water, negative heat to water, efficiencies over 100 %), and
#: what the refusal names
IMPOSSIBLE = [
    ({"fuel": {"moisture": 0.9}}, ("'fuel.moisture' (0.9)", "no net heat")),
    ({"fuel": {"moisture": 0.99}}, ("'fuel.moisture' (0.99)", "below 0.885")),
    ({"dt_nom_K": 2000.0}, ("key 'dt_nom_K'", "2055 C at Pmax", "hotter than its flame")),
    ({"dt_nom_K": 5000.0}, ("key 'dt_nom_K'", "hotter than its flame")),
    ({"fac_b_lambda_h_kg": 20.0}, ("'fac_b_lambda_h_kg'", "lambda above 10")),
    ({"fac_b_lambda_h_kg": 100.0}, ("'fac_b_lambda_h_kg'", "lambda above 10")),
    ({"fac_a_lambda": 100.0}, ("'fac_a_lambda'", "lambda above 10", "97.5 at Pmax")),
    ({"restart_temp_C": -300.0}, ("'restart_temp_C' (-300 C)", "below absolute zero")),
]


@pytest.mark.parametrize(("changes", "fragments"), IMPOSSIBLE)
def test_check_and_steady_refuse_a_physically_impossible_file(tmp_path, capsys, changes, fragments):
    """A stranger's probe: moisture 0.9 gave -4.8 kW to the water (-33.8 %) and 0.99 a
    boiler at -163.5 C; dt_nom_K 2000 a flue gas of 2055 C; facB 20 -17 kW; facA 100 water
    at 3.35 C; a restart temperature of -300 C was accepted; all with exit 0."""
    path = str(_variant(tmp_path, **changes))
    _refused(capsys, ["check", "--boiler", path], path, *fragments)
    _refused(capsys, ["steady", "--boiler", path], path, *fragments)


def test_a_run_on_the_local_rig_refuses_it_before_any_row(tmp_path, capsys):
    """A stranger's probe: `hil-client run stationary --rig local` with facA 100 logged
    sub-zero liquid water while firing and exited 0."""
    boiler = _variant(tmp_path, fac_a_lambda=100.0)
    out = tmp_path / "log.csv"
    argv = ["run", "stationary", "--boiler", str(boiler), "--rig", "local", "--out", str(out)]
    assert hil_client_main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "'fac_a_lambda'" in err and "lambda above 10" in err, err
    assert not out.exists()


def test_serve_refuses_it_before_serving(tmp_path):
    """A stranger's probe: `rig-emulator serve` with facA 100 served a burner firing at
    13.2 kW while the water fell to -43 C. The server process ends with exit 2 and the
    reason, and nothing listens on its port."""
    boiler = _variant(tmp_path, fac_a_lambda=100.0)
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    argv = ["serve", "--boiler", str(boiler), "--lockstep", "--port", str(port)]
    done = subprocess.run(
        [sys.executable, "-m", "rig_emulator.cli", *argv],
        capture_output=True,
        text=True,
        timeout=120,  # (a refusal takes about a second; the import of numba most of it)
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and "lambda above 10" in done.stderr, done.stderr
    with socket.socket() as c, pytest.raises(ConnectionRefusedError):
        c.connect(("127.0.0.1", port))


@pytest.mark.parametrize(
    ("changes", "fragments"),
    [
        # Eq. 8 below the return water: the water would heat the flue gas
        (
            {"dt_hx_wat_K": -500.0},
            ("key 'dt_hx_wat_K'", "at Pmax (13.2 kW) and no flow", "colder than the return"),
        ),
        ({"dt_hx_fg_K": -500.0}, ("key 'dt_hx_fg_K'", "at Pmin", "colder than the return")),
        # Eq. 8 above the flame at no flow
        ({"dt_hx_wat_K": 900.0}, ("'dt_hx_wat_K'", "no flow", "hotter than its flame")),
        # the water the hydrogen forms takes more than the gross heat (LHV -663 kJ/kg)
        ({"fuel": {"c": 0.0, "h": 0.95, "o": 0.0462}}, ("'fuel.h' (0.95)", "no net heat")),
        # the start-up at Pstart (19 kW, within 1.5 Pmax) burns at lambda 0.32
        ({"p_start_kW": 19.0}, ("lambda <= 1", "at Pstart (19 kW")),
        # the water freezes, or boils
        ({"restart_temp_C": -10.0}, ("'restart_temp_C' (-10 C)", "freezes")),
        ({"shutoff_temp_C": 150.0}, ("'shutoff_temp_C' (150 C)", "boils")),
        # a flame of 0.75 kW to the exchanger at nominal load, 1.4 kW lost to the room
        (
            {
                "fac_a_lambda": 2.0,
                "fac_b_lambda_h_kg": 0.0,
                "ua_amb_off_W_K": 40.0,
                "ua_amb_on_W_K": 40.0,
                "dt_nom_K": 1250.0,
            },
            ("'ua_amb_on_W_K'", "at nominal load", "delivers -0.621 kW to the water"),
        ),
    ],
)
def test_the_rest_of_the_firing_range_and_the_controller(tmp_path, capsys, changes, fragments):
    """The same physics where the stranger did not look: Eq. 8 at the other corners of the
    firing range and the flow (a flue gas of -348 C at no flow), Eq. 9 at Pstart, the
    controller's temperatures outside liquid water, and a boiler whose steady state at
    nominal load cools its water. Each passed `check` before."""
    path = str(_variant(tmp_path, **changes))
    _refused(capsys, ["check", "--boiler", path], path, *fragments)


@pytest.mark.parametrize(
    "changes",
    [
        {"fuel": {"moisture": 0.3}},  # wet fuel: the fuel_energy_bias effect's realm
        {"fuel": {"moisture": 0.7}},  # 55 % to the water, consistent
        {"dt_nom_K": 300.0},
        {"fac_a_lambda": 9.8, "fac_b_lambda_h_kg": -0.1},  # lambda 9.7 at Pmin
        {"set_temp_C": 95.0, "shutoff_temp_C": 105.0, "restart_temp_C": 1.0},
        {"p_start_kW": 15.0},
    ],
)
def test_unusual_but_possible_files_still_load(tmp_path, capsys, changes):
    """The limits are physics, not the shipped values: a wet fuel, a hot flue gas, much
    excess air and unusual controller temperatures are a boiler still."""
    path = str(_variant(tmp_path, **changes))
    assert rig_emulator_main(["check", "--boiler", path]) == 0, capsys.readouterr().err


def test_calibration_and_the_files_share_the_lambda_bound():
    """`hil-client calibrate` refused its own fits outside lambda 1..10; input files got no
    such check (a stranger's probe). One bound for both."""
    from hil_client.analysis import calibrate

    assert calibrate.LAMBDA_MAX is model_params.LAMBDA_MAX


def test_a_typo_in_the_fuel_block_names_the_unknown_key(tmp_path, capsys):
    """A stranger's probe: `ashh` in `fuel` reported only `missing required key
    'fuel.ash'`, where a top-level typo got its `unknown key`. Both are named."""
    text = (BOILER_DIR / "windhager_12kw.yaml").read_text()
    path = tmp_path / "typo.yaml"
    path.write_text(text.replace("  ash:", "  ashh:"))
    _refused(
        capsys,
        ["check", "--boiler", str(path)],
        "unknown key 'fuel.ashh' (and required key 'fuel.ash' is missing)",
    )
    path.write_text(text.replace("p_nom_kW:", "p_nom_kw:"))
    _refused(
        capsys,
        ["check", "--boiler", str(path)],
        "unknown key 'p_nom_kw' (and required key 'p_nom_kW' is missing)",
    )


def test_a_second_yaml_document_is_named(tmp_path, capsys):
    """A stranger's probe: a file holding the boiler twice, `---` between, got only `not
    valid YAML at line 30`."""
    text = (BOILER_DIR / "windhager_12kw.yaml").read_text()
    path = tmp_path / "two.yaml"
    path.write_text(text + "---\n" + text)
    line = text.count("\n") + 1
    _refused(
        capsys,
        ["check", "--boiler", str(path)],
        f"not valid YAML at line {line} (a second document starts there",
    )


@pytest.mark.parametrize(
    ("name", "fragment"),
    [
        ("wind\u202eager", "'wind\\u202eager' holds U+202E RIGHT-TO-LEFT OVERRIDE"),
        ("wind\nhager", "'wind\\nhager' holds U+000A: a control character"),
        # a stranger's probe: 100,000 characters went into every message naming the boiler
        ("w" * 100_000, "key 'name' is 100000 characters long: a boiler's name is at most 200"),
    ],
)
def test_a_name_with_control_or_format_characters_is_refused(tmp_path, capsys, name, fragment):
    """A stranger's probe: a boiler `name` holding U+202E (right-to-left override) or a
    line break was accepted and printed raw. Refused as role names are, shown escaped."""
    err = _refused(capsys, ["check", "--boiler", str(_variant(tmp_path, name=name))], fragment)
    assert "\u202e" not in err


@pytest.mark.parametrize(
    "name",
    [
        "\u0645\u06cc\u200c\u062e\u0648\u0627\u0647\u0645",  # a zero-width non-joiner
        "\u05d3\u05d5\u05d3 \u200e6kW",  # a left-to-right mark (a re-probe)
        "\u0645\u0631\u062c\u0644 \u061c12kW",  # an Arabic letter mark (a re-probe)
        "Kessel \U0001f3f4\U000e0067\U000e0062\U000e0065\U000e006e\U000e0067\U000e007f",
    ],
)
def test_a_name_spelt_with_a_joiner_a_direction_mark_or_an_emoji_tag_loads(tmp_path, capsys, name):
    """As for role names, the format characters that are part of a name's spelling are
    text: the joiners, the direction marks of a mixed-direction name, an emoji flag's tags
    (the last three were refused: a re-probe)."""
    path = str(_variant(tmp_path, name=name))
    assert rig_emulator_main(["check", "--boiler", path]) == 0, capsys.readouterr().err
