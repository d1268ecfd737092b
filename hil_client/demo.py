"""``make demo``: the load cycle through Modbus, end to end, as a lab would run it.

1. starts ``rig-emulator serve --lockstep`` as a separate process on a free port;
2. runs ``hil-client run load_cycle`` against it over Modbus TCP (the client advances the
   server itself, so the run is as fast as the wire allows and fully deterministic);
3. stops the server;
4. writes the energy balance and a short report with a figure like the paper's Fig. 7
   under ``out/demo/`` and prints where everything is.

``python -m hil_client.demo [OUT_DIR] [--protocol P] [--boiler B]`` (tests use a short
protocol). With ``--dashboard`` (``make demo DEMO_ARGS=--dashboard``) the server runs in
real time (``--speed``, default x60) with its live dashboard (``serve --http``), whose
address is printed and opened in a browser where there is one.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import signal
import subprocess
import sys
import time
import webbrowser
from collections.abc import Iterator, Sequence
from pathlib import Path

from hil_client.analysis.balance import energy_balance
from hil_client.analysis.balance import table as balance_table
from hil_client.analysis.figures import energy_and_temperatures
from hil_client.analysis.logio import read_log
from hil_client.analysis.phases import find_phases
from hil_client.cli import main as hil_client_main
from hil_client.protocol.definition import ProtocolError, load_protocol
from hil_client.wait_for_port import free_port, wait_for_port
from rig_emulator.boilers import load_boiler
from rig_emulator.model.params import ParameterError


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
        boiler = load_boiler(args.boiler)
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
    log_path = out_dir / f"{Path(args.protocol).stem}.csv"
    started = time.monotonic()
    pace = ["--lockstep"]
    if args.dashboard:
        http = free_port()
        pace = ["--speed", f"{args.speed:g}", "--http", str(http)]
    with (
        (out_dir / "server.log").open("w") as server_log,
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
                str(log_path),
            ]
        )
    if code != 0:
        return code
    params = boiler
    log = read_log(log_path)
    phases = find_phases(log)
    rows = energy_balance(log, params, phases)
    figure = energy_and_temperatures(
        log,
        phases,
        out_dir / "fig7_energy_temperatures.png",
        f"{args.protocol} of {params.name} through Modbus (lockstep)",
    )
    table = balance_table(rows)
    report = out_dir / "report.md"
    report.write_text(
        f"# Demo: {args.protocol} of {params.name} through Modbus TCP\n\n"
        f"Emulator: `rig-emulator serve --boiler {args.boiler} {' '.join(pace)}` (separate "
        "process);"
        f" client: `hil-client run {args.protocol} --rig modbus://127.0.0.1:{port}`.\n\n"
        f"Phases (from the {phases.source}): "
        + ", ".join(f"{k[:2]} = {v / 3600:.3f} h" for k, v in phases.as_dict().items())
        + "\n\n## Energy balance from the instruments (Eq. 3-7)\n\n```\n"
        + table
        + "\n```\n\n## Energy flows and temperatures (cf. Fig. 7 of the paper)\n\n"
        + f"![energy and temperatures]({figure.name})\n\n"
        + "Meta file:\n\n```json\n"
        + json.dumps(log.meta, indent=2)
        + "\n```\n",
        encoding="utf-8",
    )
    print(f"\ndemo finished in {time.monotonic() - started:.0f} s; results in {out_dir.resolve()}/")
    for path in (
        log_path,
        log_path.with_name(log_path.stem + ".meta.json"),
        report,
        figure,
        out_dir / "server.log",
    ):
        print(f"  {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
