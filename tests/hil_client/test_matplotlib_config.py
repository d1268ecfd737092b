"""The commands where the home directory cannot be written (a service account with
HOME=/nonexistent, ``docker compose run --user`` with HOME=/): one-line messages stay one
line, figures are drawn without matplotlib's warnings, and no cache lands where another
user could plant it."""

from __future__ import annotations

import os
import pwd
import re
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import urllib.request
from pathlib import Path

import pytest

import rig_emulator
from hil_client.wait_for_port import free_port, wait_for_port

BIN = Path(sys.executable).parent
SHORT_PROTOCOL = Path(__file__).resolve().parents[1] / "data" / "short_protocol.yaml"
#: where the tools find a writable home: none of these may point anywhere in the probes
HOME_VARIABLES = ("HOME", "XDG_CONFIG_HOME", "XDG_CACHE_HOME", "MPLCONFIGDIR")


def _homeless_env(tmp_path: Path, **extra: str) -> dict[str, str]:
    """The environment with a HOME that cannot be created, even by root (a path under a
    regular file), no XDG directories nor MPLCONFIGDIR, and a temporary directory of the
    test's own (for the private directories made there). NUMBA_CACHE_DIR stays as this
    process set it, so that the commands load compiled kernels rather than compile them."""
    blocker = tmp_path / "not_a_directory"
    blocker.touch()
    temp = tmp_path / "tmp"
    temp.mkdir(exist_ok=True)
    env = {k: v for k, v in os.environ.items() if k not in HOME_VARIABLES}
    return env | {"HOME": str(blocker / "home"), "TMPDIR": str(temp)} | extra


def _private_dir(tmp_path: Path, *parts: str) -> Path:
    """Where :func:`rig_emulator.private_temp_dir` puts ``parts`` under ``_homeless_env``."""
    return tmp_path.joinpath("tmp", f"rig-emulator-{os.getuid()}", *parts)


def _command(script: str, *args: str) -> list[str]:
    """The console script ``script`` of this environment with ``args``."""
    return [str(BIN / script), *args]


def _run(script: str, *args: str, env: dict[str, str], cwd: Path | str | None = None):
    """The console script run to its end (300 s: pytest's own timeout per test)."""
    return subprocess.run(
        _command(script, *args), capture_output=True, text=True, env=env, cwd=cwd, timeout=300
    )


def _assert_only(result: subprocess.CompletedProcess, code: int, message: str | None) -> None:
    """The command exited with ``code``, and stderr is the one line starting with
    ``message``, or empty (then the command printed its help)."""
    assert result.returncode == code, result.stderr
    lines = result.stderr.splitlines()
    if message is None:
        assert lines == []
        assert result.stdout.startswith("usage: hil-client")
    else:
        assert len(lines) == 1 and lines[0].startswith(message), result.stderr


@pytest.fixture(scope="module")
def short_log(tmp_path_factory) -> Path:
    """A lab log of the short test method, written by ``hil-client run --rig local``."""
    log = tmp_path_factory.mktemp("short") / "short.csv"
    result = _run(
        "hil-client",
        "run",
        str(SHORT_PROTOCOL),
        "--boiler",
        "windhager_12kw",
        "--rig",
        "local",
        "--quiet",
        "--out",
        str(log),
        env=dict(os.environ),
    )
    assert result.returncode == 0, result.stderr
    return log


@pytest.mark.parametrize(
    ("args", "code", "message"),
    [
        (["--help"], 0, None),
        (["run", "stationary", "--boiler", "nope"], 2, "hil-client: error: unknown boiler 'nope'"),
        (["balance", "missing.csv"], 2, "hil-client balance: error: argument log: missing.csv"),
    ],
)
def test_no_matplotlib_noise_on_stderr_without_a_writable_home(tmp_path, args, code, message):
    """A stranger's probe: with HOME not writable, every ``hil-client`` command, --help and
    one-line errors too, first wrote two lines of matplotlib's ("mkdir -p failed for path
    /nonexistent/.config/matplotlib", "Matplotlib created a temporary cache directory").
    Now stderr holds the command's own line and nothing else."""
    out = ["--out", str(tmp_path / "z.csv")] if args[0] == "run" else []
    result = _run("hil-client", *args, *out, env=_homeless_env(tmp_path), cwd=tmp_path)
    _assert_only(result, code, message)
    assert not (tmp_path / "z.csv").exists()


def test_commands_that_draw_nothing_do_not_import_matplotlib():
    """A stranger's probe: the CLI imported matplotlib with its figures module, for every
    command, --help too; it is imported where a figure is drawn."""
    modules = (
        "hil_client.cli, hil_client.launch, hil_client.demo, hil_client.analysis.gap_benchmark"
    )
    result = subprocess.run(
        [
            sys.executable,
            "-c",
            f"import sys, {modules}; "
            "print(sorted(m for m in sys.modules if m.partition('.')[0] == 'matplotlib'))",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


def _validate(log: Path, out: Path, env: dict[str, str]) -> list[Path]:
    """``hil-client validate`` (it draws two PNGs): the PNGs, after checking that it
    succeeded with nothing on stderr."""
    result = _run(
        "hil-client", "validate", str(log), "--boiler", "windhager_12kw", "--out", str(out), env=env
    )
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    pngs = sorted(out.glob("*.png"))
    assert [p.name for p in pngs] == ["validation_scatter.png", "validation_timeseries.png"]
    for png in pngs:
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", png
    return pngs


def test_a_figure_is_drawn_quietly_with_matplotlibs_files_in_a_private_directory(
    tmp_path, short_log
):
    """A stranger's probe: where a figure is drawn without a writable home, matplotlib
    warned twice and built its font cache anew in a throwaway directory on every run. Its
    files now go to the user's own directory under the temporary directory, mode 0700, and
    stay there for the next run."""
    _validate(short_log, tmp_path / "v", _homeless_env(tmp_path))
    private = _private_dir(tmp_path, "matplotlib")
    assert stat.S_IMODE(private.parent.stat().st_mode) == 0o700
    assert stat.S_IMODE(private.stat().st_mode) == 0o700
    assert list(private.glob("fontlist-*.json")), "matplotlib's font cache not kept"


def test_an_explicit_mplconfigdir_is_respected(tmp_path, short_log):
    """Where the user named matplotlib's directory, that is the one it uses, writable home
    or not (a guard of the fix above: it passed before it too)."""
    mine = tmp_path / "mine"
    _validate(short_log, tmp_path / "v", _homeless_env(tmp_path, MPLCONFIGDIR=str(mine)))
    assert list(mine.glob("fontlist-*.json"))
    assert not _private_dir(tmp_path, "matplotlib").exists()


def test_private_temp_dir_is_this_users_own(tmp_path, monkeypatch):
    """The private directory is under the temporary directory everybody writes in: made
    0700 (the numba cache's, made before with the umask's 0755, is tightened), and a name
    someone else holds there, a symlink or another user's directory, is not used: through
    it they could plant a cache the user's processes load."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    base = tmp_path / f"rig-emulator-{os.getuid()}"
    made = rig_emulator.private_temp_dir("matplotlib")
    assert made == base / "matplotlib" and made.is_dir()
    assert stat.S_IMODE(base.stat().st_mode) == 0o700
    base.chmod(0o755)
    assert rig_emulator.private_temp_dir("numba", "key") == base / "numba" / "key"
    assert stat.S_IMODE(base.stat().st_mode) == 0o700
    shutil.rmtree(base)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    base.symlink_to(elsewhere)
    assert rig_emulator.private_temp_dir("matplotlib") is None
    assert list(elsewhere.iterdir()) == []
    if os.getuid() == 0:  # only root can give a directory to another user
        base.unlink()
        base.mkdir(mode=0o700)
        os.chown(base, 65534, 65534)
        assert rig_emulator.private_temp_dir("matplotlib") is None
        assert list(base.iterdir()) == []


def _uid_without_passwd_entry() -> int:
    """A user id no passwd entry names (as ``docker run --user 12345`` gives)."""
    uid = 54321
    while True:
        try:
            pwd.getpwuid(uid)
        except KeyError:
            return uid
        uid += 1


@pytest.fixture
def shared_temp():
    """A world-writable temporary directory (sticky, like /tmp) another user can reach:
    pytest's tmp_path lies under root's own 0700 directory."""
    path = Path(tempfile.mkdtemp())
    path.chmod(0o1777)
    yield path
    shutil.rmtree(path)


@pytest.mark.skipif(
    os.getuid() != 0 or shutil.which("setpriv") is None, reason="needs root and setpriv"
)
@pytest.mark.parametrize(
    ("args", "code", "message"),
    [
        (["--help"], 0, None),
        (["run", "stationary", "--boiler", "nope"], 2, "hil-client: error: unknown boiler 'nope'"),
    ],
)
def test_a_user_without_a_home_gets_one_line_not_a_traceback(shared_temp, args, code, message):
    """A re-probe: HOME unset and a user id without a passwd entry, so that no home
    directory can be named: ``import rig_emulator`` raised "Could not determine home
    directory." (Path.home(), for numba's cache), and every command, --help too, ended in a
    traceback. numba's cache goes to the private temporary directory instead."""
    uid = _uid_without_passwd_entry()
    env = {k: v for k, v in os.environ.items() if k not in (*HOME_VARIABLES, "NUMBA_CACHE_DIR")}
    env["TMPDIR"] = str(shared_temp)
    out = ["--out", str(shared_temp / "z.csv")] if args[0] == "run" else []
    result = subprocess.run(
        [
            "setpriv",
            f"--reuid={uid}",
            f"--regid={uid}",
            "--clear-groups",
            *_command("hil-client", *args, *out),
        ],
        capture_output=True,
        text=True,
        env=env,
        cwd="/",
        timeout=300,
    )
    _assert_only(result, code, message)
    assert (shared_temp / f"rig-emulator-{uid}" / "numba").is_dir()


def test_rig_emulator_serve_and_its_dashboard_log_only_their_own_lines(tmp_path):
    """A stranger's probe looked for the same noise in ``rig-emulator`` (it imports no
    matplotlib; a guard that it stays so): served with its dashboard and without a
    writable home, stderr holds the server's log lines and nothing else."""
    env = _homeless_env(tmp_path)
    assert _run("rig-emulator", "--help", env=env).stderr == ""
    port, http = free_port(), free_port()
    server = subprocess.Popen(
        _command(
            "rig-emulator",
            "serve",
            "--boiler",
            "windhager_12kw",
            "--lockstep",
            "--port",
            str(port),
            "--http",
            str(http),
        ),
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        # 60 s: the server's start with numba's kernels loaded takes a few seconds
        assert wait_for_port("127.0.0.1", http, 60.0, alive=lambda: server.poll() is None)
        for path in ("/", "/api/state"):
            with urllib.request.urlopen(f"http://127.0.0.1:{http}{path}", timeout=10) as reply:
                assert reply.status == 200
    finally:
        server.send_signal(signal.SIGTERM)
        _, stderr = server.communicate(timeout=30)
    lines = stderr.splitlines()
    assert lines and all(re.match(r"\S+ \S+ rig-emulator: ", line) for line in lines), stderr
