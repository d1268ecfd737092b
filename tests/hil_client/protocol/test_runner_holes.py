"""The protocol runner on a real-time server (real sockets, real time): a client held up
while the server's clock ran on leaves a hole in the rows, and the run says so."""

from __future__ import annotations

import re
import time

from hil_client.protocol.definition import protocol_from_mapping
from hil_client.protocol.runner import run_protocol
from hil_client.rigs.modbus import ModbusRig
from rig_emulator.registers import load_map

TINY = {
    "name": "tiny",
    "test": "stationary",
    "acquisition_period_s": 1,
    "flow_spread_K": 15,
    "preheat": {"temperature_C": 25, "tolerance_K": 1, "hold_s": 5, "load_pct": 100,
                "max_duration_s": 3600},
    "start_up": {"return_setpoint_C": 55, "t1_window_s": 30, "t1_max_rise_K_min": 0.5,
                 "min_duration_s": 30, "max_duration_s": 60},
    "test_sequence": {"return_setpoint_C": 55, "sequences": [
        {"name": "stationary_100", "load_pct": 100, "duration": "00:02:00"}]},
    "cooling_1": {"load_pct": 20, "return_setpoint_C": 55, "until_forward_C": 55,
                  "max_duration_s": 20},
    "cooling_2": {"until_after_t2_s": 30},
}  # fmt: skip
SPEED = 100.0


def test_a_client_held_up_while_the_server_ran_on_is_a_hole_in_a_note(serve):
    """A probe: a client stopped (SIGSTOP) for 6 s against a x10 server left 60 rows
    missing (time_s 68 -> 129) with no gap, note or warning, exit 0. Here the client is
    held up for 2 s of wall time (200 simulated seconds at x100; rows come a 10-Hz tick,
    10 s, apart) at its 40th row."""
    srv = serve(lockstep=False, speed=SPEED)
    rig = ModbusRig(f"modbus://127.0.0.1:{srv.port}", load_map())
    times: list[float] = []

    def sink(row) -> None:
        times.append(row[0])
        if len(times) == 40:
            time.sleep(200.0 / SPEED)

    said: list[tuple[int, list[str]]] = []  # (rows so far, the notes) at each hand-on
    result = run_protocol(
        protocol_from_mapping(TINY, "tiny"),
        12.0,
        rig,
        sink,
        on_phase=lambda r: said.append((len(times), list(r.notes))),
    )
    rig.close()
    # handed on (into the meta file) at once, before the row after the hole: a run
    # stopped before its next phase mark lost it (a re-probe)
    first = next(rows for rows, notes in said if any("no row from" in n for n in notes))
    assert first == 40, said
    holes = [n for n in result.notes if n.startswith("no row from time_s")]
    assert holes, result.notes
    spans = [tuple(map(float, re.findall(r"time_s = ([\d.]+) to ([\d.]+) s", n)[0])) for n in holes]
    # the one after the 40th row, at least the 200 simulated seconds it was held up
    assert any(abs(a - times[39]) < 0.01 and b - a >= 200.0 for a, b in spans), (
        spans,
        times[38:42],
    )
