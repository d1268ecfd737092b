"""The live dashboard (CONTRACT section 8) against a real `rig-emulator serve`: the page and
its JSON over real HTTP, the pushed stream, the controls through the Modbus write checks,
bad requests, and the page in a real headless browser."""

from __future__ import annotations

import json
import logging
import shutil
import socket
import subprocess
import time
import urllib.error
import urllib.request
from types import SimpleNamespace

import pytest

from hil_client.demo import rig_emulator_serve
from hil_client.wait_for_port import free_port, wait_for_port
from rig_emulator.registers import load_map
from tests.modbus_helpers import client, point, read_point, write

MAP = SimpleNamespace(map=load_map())


def _get(http: int, path: str):
    with urllib.request.urlopen(f"http://127.0.0.1:{http}{path}", timeout=10) as r:
        return r.status, r.headers.get("Content-Type"), r.read()


JSON = {"Content-Type": "application/json"}  # what the page's own requests declare


def _post(
    http: int, body: bytes, path: str = "/api/control", headers: dict | None = None
) -> tuple[int, dict]:
    req = urllib.request.Request(
        f"http://127.0.0.1:{http}{path}",
        data=body,
        method="POST",
        headers=JSON if headers is None else headers,
    )
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())


def _reading(state: dict, unit_id: int, signal: str) -> float:
    unit = next(u for u in state["units"] if u["unit_id"] == unit_id)
    return next(r["value"] for r in unit["readings"] if r["signal"] == signal)


def test_state_shows_what_the_wire_shows_and_the_stream_pushes_it(dashboard):
    port, http = dashboard()
    c = client(port)
    try:
        for name, value in (("flow_setpoint", 600.0), ("return_setpoint", 55.0)):
            assert not write(c, MAP, "bench_plc", name, value).isError()
        assert not write(c, MAP, "boiler_controller", "on_command", 1).isError()
        assert not write(c, MAP, "sim_control", "lockstep_advance", 1800).isError()
        time.sleep(1.2)  # one push period and more: the dashboard samples the new state
        status, kind, body = _get(http, "/api/state")
        state = json.loads(body)
        assert status == 200 and kind == "application/json"
        assert {u["unit_id"] for u in state["units"]} == {d.unit_id for d in MAP.map.devices}
        assert state["clock"]["mode"] == "lockstep" and state["time_s"] == pytest.approx(1800)
        dev, p = point(MAP, "bench_plc", "boiler_water_temp")
        assert _reading(state, 1, "boiler_water_temp_C") == pytest.approx(
            read_point(c, dev, p),
            abs=1e-4,  # float32 on the wire
        )
        assert len(state["trend"]["time_s"]) >= 2
        assert state["trend"]["boiler_water_temp_C"][-1] is not None
        # the stream: an event with the state, then another after the next advance
        with socket.create_connection(("127.0.0.1", http), timeout=10) as s:
            s.sendall(b"GET /api/stream HTTP/1.1\r\nHost: x\r\n\r\n")
            stream = s.makefile("rb")
            assert b"text/event-stream" in b"".join(iter(stream.readline, b"\r\n"))
            first = json.loads(stream.readline().removeprefix(b"data: "))
            assert first["time_s"] == pytest.approx(1800)
            assert not write(c, MAP, "sim_control", "lockstep_advance", 600).isError()
            deadline = time.monotonic() + 10.0
            while time.monotonic() < deadline:
                line = stream.readline()
                if line.startswith(b"data: "):
                    event = json.loads(line.removeprefix(b"data: "))
                    if event["time_s"] == pytest.approx(2400):
                        # the samples since the last event: inside the advance, then its end
                        assert event["trend_point"]["time_s"][-1] == pytest.approx(2400)
                        break
            else:
                pytest.fail("no pushed event after the advance")
    finally:
        c.close()


def test_controls_are_off_unless_asked_for(dashboard):
    port, http = dashboard()
    status, body = _post(http, b'{"signal": "water_flow_setpoint_kg_h", "value": 500}')
    assert status == 403 and "--http-control" in body["error"]
    c = client(port)
    try:
        dev, p = point(MAP, "bench_plc", "flow_setpoint")
        assert read_point(c, dev, p) != 500.0
    finally:
        c.close()


def test_controls_take_the_modbus_write_path(dashboard):
    port, http = dashboard("--http-control")
    c = client(port)
    try:
        dev, p = point(MAP, "bench_plc", "flow_setpoint")
        status, _ = _post(http, b'{"signal": "water_flow_setpoint_kg_h", "value": 500}')
        assert status == 200 and read_point(c, dev, p) == 500.0
        # outside the map's 0..2000: the Modbus answer would be exception 03, nothing changes
        status, body = _post(http, b'{"signal": "water_flow_setpoint_kg_h", "value": 5000}')
        assert status == 400 and "03" in body["error"]
        assert read_point(c, dev, p) == 500.0
        status, _ = _post(http, b'{"signal": "boiler_command", "value": 1}')
        dev_b, p_b = point(MAP, "boiler_controller", "on_command")
        assert status == 200 and read_point(c, dev_b, p_b) == 1.0
        for bad in (
            b"not json",
            b'{"signal": "reset", "value": 1}',
            b'{"signal": "water_flow_setpoint_kg_h", "value": "x"}',
            b"[1, 2]",
        ):
            status, body = _post(http, bad)
            assert status == 400 and body["error"]
        assert read_point(c, dev, p) == 500.0
    finally:
        c.close()


def test_another_site_cannot_drive_the_controls(dashboard):
    """Any page open in the lab's browser could set the flow and inject faults: a no-cors
    fetch sends text/plain without asking the server first, and nothing checked where a
    POST came from. Now a control must be declared JSON, from this server's own origin and
    host; a refused one changes nothing."""
    port, http = dashboard("--http-control")
    body = b'{"signal": "water_flow_setpoint_kg_h", "value": 1234}'
    own = f"http://127.0.0.1:{http}"
    for headers, why in (
        ({"Content-Type": "text/plain"}, "Content-Type text/plain"),  # a no-cors fetch
        ({}, "Content-Type application/x-www-form-urlencoded"),  # a form (urllib's default)
        ({**JSON, "Origin": "http://127.0.0.1:18090"}, "Origin"),  # another site, same host
        ({**JSON, "Host": "attacker.example", "Origin": "http://attacker.example"}, "Host"),
    ):
        status, answer = _post(http, body, headers=headers)
        assert status == 403 and why in answer["error"], (headers, answer)
        status, answer = _post(
            http, b'{"inject": {"kind": "no_reply", "unit": 2}}', "/api/faults", headers
        )
        assert status == 403, (headers, answer)
    assert _post(http, body, headers={**JSON, "Origin": own})[0] == 200  # the page's own
    c = client(port)
    try:
        dev, p = point(MAP, "bench_plc", "flow_setpoint")
        assert read_point(c, dev, p) == 1234.0
    finally:
        c.close()
    state = json.loads(_get(http, "/api/state")[2])
    assert state["faults"] == []  # no refused inject got through


def test_a_switch_takes_0_or_1_only_and_numbers_beyond_floats_are_refused(dashboard):
    """boiler_command took any number (7 switched it on, -7 off), and NaN or Infinity were
    applied before the reply failed with a traceback; a 4001-digit integer got no reply."""
    port, http = dashboard("--http-control")
    c = client(port)
    try:
        dev, p = point(MAP, "boiler_controller", "on_command")
        assert _post(http, b'{"signal": "boiler_command", "value": 1}')[0] == 200
        for value in (b"NaN", b"-Infinity", b"Infinity", b"7", b"-7", b"0.5", b"1e308"):
            status, answer = _post(http, b'{"signal": "boiler_command", "value": %s}' % value)
            assert status == 400 and answer["error"], value
            assert read_point(c, dev, p) == 1.0, value  # unchanged
        huge = b'{"signal": "water_flow_setpoint_kg_h", "value": 1' + b"0" * 4000 + b"}"
        status, answer = _post(http, huge)
        assert status == 400 and "too large" in answer["error"]
    finally:
        c.close()


def test_idle_streams_never_lock_a_new_viewer_out(dashboard):
    """64 streams that never read held every place: new viewers got 503 for as long as
    they stayed (and a browser's EventSource gives up after a 503). The oldest now gives
    way to a new one."""
    _, http = dashboard()
    idle = []
    try:
        for _ in range(70):
            s = socket.create_connection(("127.0.0.1", http), timeout=10)
            s.sendall(b"GET /api/stream HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
            idle.append(s)
        with urllib.request.urlopen(f"http://127.0.0.1:{http}/api/stream", timeout=10) as r:
            assert r.status == 200
            assert r.readline().startswith(b"data: ")
    finally:
        for s in idle:
            s.close()
    assert _get(http, "/api/state")[0] == 200


@pytest.mark.parametrize(
    ("request_bytes", "status"),
    [
        (b"GET /nothing HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n", b"404"),
        (b"DELETE /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n", b"405"),
        (b"GARBAGE\r\n\r\n", b"400"),
        (b"GET /api/state?window=abc HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n", b"400"),
        (
            b"POST /api/control HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 99999999\r\n\r\n",
            b"400",
        ),
        (b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nX: " + b"a" * 70_000 + b"\r\n\r\n", b"400"),
    ],
)
def test_bad_requests_get_an_answer_and_the_server_lives_on(served_once, request_bytes, status):
    _, http = served_once("--lockstep")
    with socket.create_connection(("127.0.0.1", http), timeout=10) as s:
        s.sendall(request_bytes)
        assert s.recv(64).split(b" ")[1] == status
    assert _get(http, "/api/state")[0] == 200


def test_the_page_ships_everything_it_needs(served_once):
    _, http = served_once("--lockstep")
    status, kind, page = _get(http, "/")
    assert status == 200 and kind.startswith("text/html")
    # no internet: nothing is loaded from another host
    assert b"http://" not in page and b"https://" not in page and b"<script src" not in page


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed (make tools installs it)")
def test_the_page_shows_live_values_in_a_real_browser(dashboard, tmp_path):
    port, http = dashboard()
    c = client(port)
    try:
        assert not write(c, MAP, "sim_control", "lockstep_advance", 600).isError()
    finally:
        c.close()
    flags = [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={tmp_path / 'profile'}",
        "--timeout=10000",
    ]
    url = f"http://127.0.0.1:{http}/"
    dom = subprocess.run(
        [CHROMIUM, *flags, "--dump-dom", url], capture_output=True, timeout=120, text=True
    ).stdout
    assert 'id="v_1_boiler_water_temp"' in dom
    cell = dom.split('id="v_1_boiler_water_temp"', 1)[1].split(">", 1)[1].split("<", 1)[0]
    float(cell)  # the page's script rendered the live reading into its cell
    assert 'id="simtime">0:10:00<' in dom  # simulated time after the advance
    shot = tmp_path / "dashboard.png"
    subprocess.run(
        [CHROMIUM, *flags, "--window-size=1400,1000", f"--screenshot={shot}", url],
        capture_output=True,
        timeout=120,
    )
    assert shot.exists() and shot.stat().st_size > 20_000


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--http-control"], "--http-control needs --http PORT"),
        (["--http", "70000"], "--http: 70000 is not a TCP port"),
    ],
)
def test_bad_dashboard_options_get_one_line(options, message, capsys):
    from rig_emulator.cli import main

    assert main(["serve", "--boiler", "windhager_12kw", *options]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_faults_are_set_and_cleared_from_the_page_only_with_controls(dashboard):
    """A fault set from the dashboard acts on the wire (the unit stops answering) and shows
    in the state; a bad fault is refused with the reason; without --http-control: 403."""
    _, http = dashboard()
    status, body = _post(http, b'{"clear": true}', "/api/faults")
    assert status == 403 and "--http-control" in body["error"]

    port, http = dashboard("--http-control")
    status, body = _post(http, b'{"inject": {"kind": "exception", "unit": 2, "code": 6}}',
                         "/api/faults")  # fmt: skip
    assert status == 200 and [f["kind"] for f in body["faults"]] == ["exception"]
    c = client(port)
    try:
        r = c.read_input_registers(0, count=2, device_id=2)
        assert r.isError() and r.exception_code == 6  # the analyser answers 06 now
        _, _, raw = _get(http, "/api/state")
        assert [f["kind"] for f in json.loads(raw)["faults"]] == ["exception"]
        status, body = _post(http, b'{"inject": {"kind": "exception", "unit": 2}}', "/api/faults")
        assert status == 400 and "code" in body["error"]  # the same validation as FAULTS.yaml
        status, body = _post(http, b'{"clear": true}', "/api/faults")
        assert status == 200 and body["faults"] == []
        assert not c.read_input_registers(0, count=2, device_id=2).isError()
    finally:
        c.close()


def test_clear_and_inject_in_one_request_replaces_the_faults(dashboard):
    """``{"clear": true, "inject": F}`` clears, then sets F (it used to clear and drop F);
    with a bad F nothing is cleared; a key beside the two is refused, naming the form."""
    _, http = dashboard("--http-control")
    first = b'{"inject": {"kind": "delay", "unit": 3, "delay_ms": 50}}'
    assert _post(http, first, "/api/faults")[0] == 200
    status, body = _post(
        http, b'{"clear": true, "inject": {"kind": "exception", "unit": 2, "code": 4}}',
        "/api/faults",
    )  # fmt: skip
    assert status == 200 and [(f["kind"], f["unit"]) for f in body["faults"]] == [("exception", 2)]
    status, body = _post(http, b'{"clear": true, "inject": {"kind": "no_reply", "unit": 99}}',
                         "/api/faults")  # fmt: skip
    assert status == 400 and "99" in body["error"]
    status, body = _post(http, b'{"clear": true, "injct": {}}', "/api/faults")
    assert status == 400 and "clear, then inject" in body["error"]
    _, _, raw = _get(http, "/api/state")
    assert [f["kind"] for f in json.loads(raw)["faults"]] == ["exception"]  # nothing changed


def test_a_chunked_body_is_refused_for_what_it_is(dashboard):
    """A chunked body was read as no body, and refused as if the signal were missing."""
    _, http = dashboard("--http-control")
    with socket.create_connection(("127.0.0.1", http), timeout=10) as s:
        s.sendall(
            b"POST /api/control HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
            b"Transfer-Encoding: chunked\r\n\r\n5\r\n"
        )
        answer = b""
        while chunk := s.recv(4096):
            answer += chunk
    assert answer.split(b" ")[1] == b"400" and b"Transfer-Encoding" in answer


def test_map_text_cannot_end_or_hide_the_pages_script(dashboard, tmp_path):
    """The page carries the state of the moment inside its script; a map whose text held
    ``<!--<script>`` put the HTML parser in a state that swallowed the script's real end,
    and the page never started (only ``</`` was escaped)."""
    from rig_emulator.registers import MAP_DIR

    text = (MAP_DIR / "wieselburg_bench.yaml").read_text(encoding="utf-8")
    tricky = text.replace(
        "instrument: flame-ionisation detector", "instrument: <!--<script> flame-ionisation"
    )
    assert tricky != text
    (tmp_path / "map.yaml").write_text(tricky, encoding="utf-8")
    _, http = dashboard("--map", str(tmp_path / "map.yaml"))
    status, _, page = _get(http, "/")
    assert status == 200
    assert page.count(b"<script") == 1 and b"<!--" not in page  # the page's own script only
    start = page.index(b"const INITIAL = ") + len(b"const INITIAL = ")
    state = json.loads(page[start : page.index(b";\n", start)])
    fid = next(u for u in state["units"] if u["name"] == "fid")
    assert fid["instrument"].startswith("<!--<script>")  # the text itself is kept


def test_streams_closed_for_new_ones_are_logged_at_most_once_a_minute(serve, caplog):
    """A re-probe: a client opening streams in a loop got a log line per stream closed for
    a new one. The first is said, with a count; the rest wait a minute."""
    from rig_emulator.dashboard.http import MAX_STREAMS, Dashboard

    srv = serve()
    board = Dashboard(srv.server, port=0)
    srv.call(board.start())
    opened = []
    try:
        with caplog.at_level(logging.WARNING, logger="rig_emulator.dashboard"):
            for _ in range(MAX_STREAMS + 40):
                s = socket.create_connection(("127.0.0.1", board.port), timeout=10)
                s.sendall(b"GET /api/stream HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
                assert s.recv(12) == b"HTTP/1.1 200"  # (its place taken: it streams)
                opened.append(s)
        lines = [r.getMessage() for r in caplog.records if "live streams" in r.getMessage()]
        assert len(lines) == 1 and "(1 so since the last such line" in lines[0], lines
    finally:
        for s in opened:
            s.close()
        with caplog.at_level(logging.WARNING, logger="rig_emulator.dashboard"):
            srv.call(board.stop())
    # the rest are counted when the dashboard stops (a re-probe: they never were)
    assert "39 more live stream(s) closed for new streams or requests" in caplog.text


def test_a_stop_with_requests_half_sent_logs_no_traceback():
    """A probe: SIGTERM with dashboard connections that had sent half a request (and a
    live stream) stopped cleanly but logged asyncio's CancelledError traceback twice per
    connection (88 under a storm). The connections are now ended before the loop stops."""
    import signal

    http = free_port()
    with rig_emulator_serve("windhager_12kw", "--http", str(http), stderr=subprocess.PIPE) as (
        _port,
        proc,
    ):
        assert wait_for_port("127.0.0.1", http, 30.0)
        half = [socket.create_connection(("127.0.0.1", http), timeout=5) for _ in range(3)]
        for s in half:
            s.sendall(b"GET / HTTP/1.1\r\n")  # the request's end never comes
        stream = socket.create_connection(("127.0.0.1", http), timeout=5)
        stream.sendall(b"GET /api/stream HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        assert stream.recv(64).startswith(b"HTTP/1.1 200")
        time.sleep(0.5)
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(timeout=30)
        err = proc.stderr.read().decode()
        for s in (*half, stream):
            s.close()
    assert code == 0, err
    assert "Traceback" not in err and "CancelledError" not in err, err
