"""``make demo``: the load cycle through Modbus, end to end, as a lab would run it.

1. starts ``rig-emulator serve --lockstep`` as a separate process on a free port;
2. runs ``hil-client run load_cycle`` against it over Modbus TCP (the client advances the
   server itself, so the run is as fast as the wire allows and fully deterministic);
3. stops the server;
4. writes the energy balance and a short report with a figure like the paper's Fig. 7
   under ``out/demo/`` and prints where everything is.

A demo writes in ``out/demo/.running/`` and moves its files into ``out/demo/`` (replacing
the earlier demo's) only once its run completed and its report is written, so
``out/demo/`` always holds one whole demo; one that did not complete (Ctrl-C, SIGTERM, a
failed run, a demo killed and found at the next start) is kept in ``out/demo/incomplete/``
instead, which holds only the last such demo. Two demos on one ``out_dir`` at once: the
second is refused (exit 2) before it starts or opens anything.

``python -m hil_client.demo [OUT_DIR] [--protocol P] [--boiler B]`` (tests use a short
protocol). With ``--dashboard`` (``make demo DEMO_ARGS=--dashboard``) the server runs in
real time (``--speed``, default x60) with its live dashboard (``serve --http``), whose
address is printed and opened in a browser where there is one; the load cycle (16.5 h
simulated) then takes about 16.5 min at x60.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import shutil
import signal
import subprocess
import sys
import threading
import time
import webbrowser
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from hil_client.analysis.balance import energy_balance
from hil_client.analysis.balance import table as balance_table
from hil_client.analysis.balance import warnings_by_reason as balance_warnings
from hil_client.analysis.figures import energy_and_temperatures
from hil_client.analysis.logio import read_log
from hil_client.analysis.phases import find_phases
from hil_client.cli import main as hil_client_main
from hil_client.protocol.definition import ProtocolError, load_protocol
from hil_client.run_lock import RunBusy, run_lock
from hil_client.wait_for_port import free_port, wait_for_port
from rig_emulator.boilers import load_boiler
from rig_emulator.model.params import BoilerParams, ParameterError


@contextlib.contextmanager
def rig_emulator_serve(
    boiler: str, *options: str, stderr=subprocess.DEVNULL, timeout_s: float = 60.0
) -> Iterator[tuple[int, subprocess.Popen]]:
    """``rig-emulator serve --boiler BOILER OPTIONS`` in its own process on a free port.

    Yields ``(port, process)`` once 127.0.0.1:port accepts connections; SIGTERM on exit.
    """
    port = free_port()
    server = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "rig_emulator.cli",
            "serve",
            "--boiler",
            boiler,
            "--port",
            str(port),
            *options,
        ],
        stderr=stderr,
    )
    try:
        if not wait_for_port("127.0.0.1", port, timeout_s, alive=lambda: server.poll() is None):
            if server.returncode is not None:
                raise RuntimeError(f"rig-emulator serve exited with code {server.returncode}")
            raise RuntimeError(f"rig-emulator serve did not listen on port {port}")
        yield port, server
    finally:
        server.send_signal(signal.SIGTERM)
        server.wait(timeout=30)


#: The folder inside ``out_dir`` a demo writes in until its run completes: its files are
#: moved into ``out_dir`` only then, so ``out_dir`` never mixes two runs (a stranger's
#: probe: a demo interrupted after a complete one left the earlier report and figure
#: beside the interrupted log, the earlier log set aside as ``NAME.previousN.csv``, one
#: more 10-MB copy per interrupted demo).
RUNNING = ".running"
#: Where the files of the last demo that did not complete are kept: one such run, replaced
#: by the next one that does not complete.
INCOMPLETE = "incomplete"
#: The demo's files besides the lab log's (log, meta and Modbus events).
REPORT, FIGURE, SERVER_LOG = "report.md", "fig7_energy_temperatures.png", "server.log"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="demo", description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", nargs="?", default="out/demo", type=Path)
    parser.add_argument("--protocol", default="load_cycle")
    parser.add_argument("--boiler", default="windhager_12kw")
    parser.add_argument(
        "--dashboard", action="store_true", help="real time with the live dashboard"
    )
    parser.add_argument("--speed", type=float, default=60.0, help="with --dashboard [60]")
    args = parser.parse_args(argv)
    if not 0 < args.speed <= 10_000:
        parser.error("--speed must be in (0, 10000]")
    out_dir: Path = args.out_dir
    try:
        load_boiler(args.boiler)
    except ParameterError as exc:
        parser.error(f"--boiler: {exc}")
    try:  # before a server is started for it (a stranger's probe)
        load_protocol(args.protocol)
    except ProtocolError as exc:
        parser.error(f"--protocol: {exc}")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:  # a file in the way, no permission
        parser.error(f"out_dir: cannot make '{out_dir}' ({exc.strerror})")
    log_name = f"{Path(args.protocol).stem}.csv"
    started = time.monotonic()
    stopping = _stop_on_sigterm()
    try:
        with contextlib.ExitStack() as held:
            # before anything is started or opened: a second demo on the same out_dir
            # started its server, whose log truncated the live run's server.log (a
            # stranger's probe); the log's own lock keeps a hil-client run off it too
            held.enter_context(run_lock(out_dir / REPORT, "writing", out_dir))
            held.enter_context(run_lock(out_dir / log_name))
            return _demo(args, out_dir, log_name, started)
    except RunBusy as busy:
        parser.error(
            f"out_dir: '{out_dir}' is being written by another run ({busy}); wait until it "
            "ends, or give another out_dir"
        )
    finally:
        if stopping is not None:
            signal.signal(signal.SIGTERM, stopping)


def _stop_on_sigterm() -> Any:
    """SIGTERM ends the demo as Ctrl-C does (its files are put where :func:`_keep_incomplete`
    says); the handler it replaces (None off the main thread, where none can be set)."""
    if threading.current_thread() is not threading.main_thread():
        return None

    def interrupt(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    return signal.signal(signal.SIGTERM, interrupt)


def _demo(args: argparse.Namespace, out_dir: Path, log_name: str, started: float) -> int:
    """The run, its report and figure, written in :data:`RUNNING` and moved into
    ``out_dir`` once all are written (the demo's locks held)."""
    running = out_dir / RUNNING
    if running.exists():  # a demo killed (-9, a power cut) before it completed
        _keep_incomplete(out_dir, "a demo killed before it completed")
    running.mkdir()
    try:
        code, port, pace = _run(args, running, log_name)
        if code != 0:
            return _keep_incomplete(out_dir, f"the run did not complete (exit {code})", code)
        written = [*_log_names(log_name), *_report(args, running, log_name, port, pace)]
    except KeyboardInterrupt:
        return _keep_incomplete(out_dir, "interrupted", 1)
    for name in written:  # (each replaces the earlier run's file of that name)
        with contextlib.suppress(FileNotFoundError):  # (an events file a run had no use for)
            (running / name).replace(out_dir / name)
    shutil.rmtree(running, ignore_errors=True)  # (the client's lock file went already)
    print(f"\ndemo finished in {time.monotonic() - started:.0f} s; results in {out_dir.resolve()}/")
    for name in written:
        if (out_dir / name).exists():
            print(f"  {out_dir / name}")
    print(_fuel_note(load_boiler(args.boiler)))
    return 0


def _fuel_note(params: BoilerParams) -> str:
    """What the two fuel figures of a demo are: the run's summary gives the balance's loss,
    the report the fuel as received (a stranger read 7.44 kg and 7.47 kg for one phase)."""
    factor = params.fuel.as_received_per_kg_dry / params.fuel.balance_loss_per_kg_dry
    return (
        "Fuel: the run's summary ('fuel (balance)') gives what the balance lost; the report's "
        "'fuel kg (a.r.)' is the fuel as received, that loss with the ash left in the boiler "
        f"added back (x{factor:.4f} for this fuel), so it is a little more."
    )


def _log_names(log_name: str) -> list[str]:
    """The lab log's files (log, meta, Modbus events) as ``hil-client run`` names them."""
    stem = Path(log_name).stem
    return [log_name, f"{stem}.meta.json", f"{stem}.modbus_events.jsonl"]


def _report(
    args: argparse.Namespace, running: Path, log_name: str, port: int, pace: list[str]
) -> list[str]:
    """The energy balance and the figure of the log in ``running``, and the report giving
    both; the names of the files written (the server's log with them)."""
    params = load_boiler(args.boiler)
    log = read_log(running / log_name)
    phases = find_phases(log)
    rows = energy_balance(log, params, phases)
    pacing = "lockstep" if "--lockstep" in pace else f"real time x{args.speed:g}"
    figure = energy_and_temperatures(
        log,
        phases,
        running / FIGURE,
        f"{args.protocol} of {params.name} through Modbus ({pacing})",
    )
    # the reasons for what the table leaves unknown, under it (a re-probe: the report's
    # table showed "-" without a word once the warnings left it for standard error)
    table = "\n".join([balance_table(rows), *(f"warning: {w}" for w in balance_warnings(rows))])
    (running / REPORT).write_text(
        f"# Demo: {args.protocol} of {params.name} through Modbus TCP\n\n"
        f"Emulator: `rig-emulator serve --boiler {args.boiler} {' '.join(pace)}` (separate "
        "process);"
        f" client: `hil-client run {args.protocol} --rig modbus://127.0.0.1:{port}`.\n\n"
        f"Phases (from the {phases.source}): "
        + ", ".join(f"{k[:2]} = {v / 3600:.3f} h" for k, v in phases.as_dict().items())
        + "\n\n## Energy balance from the instruments (Eq. 3-7)\n\n```\n"
        + table
        + f"\n```\n\n{_fuel_note(params)}\n\n"
        + "## Energy flows and temperatures (cf. Fig. 7 of the paper)\n\n"
        + f"![energy and temperatures]({figure.name})\n\n"
        + "Meta file:\n\n```json\n"
        + json.dumps(log.meta, indent=2)
        + "\n```\n",
        encoding="utf-8",
    )
    return [REPORT, figure.name, SERVER_LOG]


def _run(args: argparse.Namespace, running: Path, log_name: str) -> tuple[int, int, list[str]]:
    """The server and ``hil-client run`` against it, writing in ``running``: the client's
    exit code, the server's port and its pace options."""
    pace = ["--lockstep"]
    if args.dashboard:
        http = free_port()
        pace = ["--speed", f"{args.speed:g}", "--http", str(http)]
    with (
        (running / SERVER_LOG).open("w") as server_log,
        rig_emulator_serve(args.boiler, *pace, stderr=server_log) as (port, server),
    ):
        print(f"rig-emulator serve {' '.join(pace)} started on 127.0.0.1:{port} (pid {server.pid})")
        if args.dashboard:
            url = f"http://127.0.0.1:{http}/"
            wait_for_port("127.0.0.1", http, 30.0)
            print(f"live dashboard: {url}")
            with contextlib.suppress(Exception):  # no browser on a server: the URL is printed
                webbrowser.open(url)
        code = hil_client_main(
            [
                "run",
                args.protocol,
                "--boiler",
                args.boiler,
                "--rig",
                f"modbus://127.0.0.1:{port}",
                "--out",
                str(running / log_name),
            ]
        )
    return code, port, pace


def _keep_incomplete(out_dir: Path, why: str, code: int = 0) -> int:
    """Move what a demo that did not complete wrote (:data:`RUNNING`) to
    :data:`INCOMPLETE`, replacing the one kept there before, and say exactly what is kept
    where; ``code`` is returned."""
    running, incomplete = out_dir / RUNNING, out_dir / INCOMPLETE
    shutil.rmtree(incomplete, ignore_errors=True)
    running.replace(incomplete)
    kept = ", ".join(sorted(p.name for p in incomplete.iterdir() if not p.name.startswith(".")))
    earlier = (
        f"{out_dir}/ keeps the last complete demo's files as they were"
        if (out_dir / REPORT).exists()
        else f"{out_dir}/ holds no complete demo yet"
    )
    print(
        f"demo: {why}: its files ({kept or 'none'}) are kept in {incomplete}/, replacing those "
        f"of the demo that did not complete before it (one such demo is kept); {earlier}",
        file=sys.stderr,
    )
    return code


if __name__ == "__main__":
    sys.exit(main())
