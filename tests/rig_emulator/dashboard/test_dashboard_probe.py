"""A stranger's probe of the live dashboard (CONTRACT section 8), against a real
`rig-emulator serve` over real HTTP and Modbus sockets: the controls meet Modbus's clock
guard, the trends' cadence and what they show inside a long advance, the values as the
wire serves them, the axes and the faults in a real headless browser, and HTTP details."""

from __future__ import annotations

import html
import itertools
import json
import math
import re
import socket
import subprocess
import threading
import time
from types import SimpleNamespace

import pytest

from rig_emulator.dashboard.http import PUSH_PERIOD_S
from rig_emulator.dashboard.state import TREND_SIGNALS, Trend
from rig_emulator.modbus.server import ADVANCE_SAMPLES
from rig_emulator.registers import MAP_DIR, invalid_value, load_map
from tests.modbus_helpers import ADVANCE, client, point, read_point, start_boiler, write
from tests.rig_emulator.dashboard.test_dashboard import CHROMIUM, MAP, _get, _post


def _state(http: int) -> dict:
    return json.loads(_get(http, "/api/state")[2])


def _raw(http: int, request: bytes) -> bytes:
    """The whole answer to ``request`` (the server closes after each)."""
    with socket.create_connection(("127.0.0.1", http), timeout=10) as s:
        s.sendall(request)
        answer = b""
        while chunk := s.recv(65536):
            answer += chunk
    return answer


def test_the_dashboard_is_refused_what_modbus_refuses(served):
    """A stranger's probe: on a real-time server started without --allow-control, Modbus
    refused speed_factor with exception 01, but the dashboard's POST answered 200 and
    applied it. Now its controls meet the same guard: 403 naming --allow-control, nothing
    changes, and the state says why the page disables the control (faults too, as the
    Modbus fault block)."""
    port, http = served("--http-control")
    status, body = _post(http, b'{"signal": "speed_factor", "value": 50}')
    assert status == 403 and "--allow-control" in body["error"] and "01" in body["error"]
    status, body = _post(http, b'{"inject": {"kind": "no_reply", "unit": 2}}', "/api/faults")
    assert status == 403 and "--allow-control" in body["error"]
    c = client(port)
    try:
        dev, p = point(MAP, "sim_control", "speed_factor")
        assert read_point(c, dev, p) == 1.0  # unchanged
    finally:
        c.close()
    state = _state(http)
    assert state["clock"]["speed"] == 1.0 and state["faults"] == []
    refused = {c["signal"]: c["refused"] for c in state["controls"]}
    assert "--allow-control" in refused["speed_factor"]
    assert refused["water_flow_setpoint_kg_h"] is None  # a plant setpoint is not guarded
    assert "--allow-control" in state["fault_controls"]["refused"]

    port, http = served("--http-control", "--allow-control")
    assert _post(http, b'{"signal": "speed_factor", "value": 50}')[0] == 200
    c = client(port)
    try:
        assert read_point(c, dev, p) == 50.0
    finally:
        c.close()


def test_every_writable_setpoint_is_offered_through_the_write_path(served):
    """A stranger's probe: CONTRACT lists "setpoints" among the controls, but only the
    flow setpoint was offered (return_setpoint_C and boiler_set_temp_C, writable points of
    the map, were refused as unknown signals)."""
    port, http = served("--lockstep", "--http-control")
    offered = {c["signal"] for c in _state(http)["controls"]}
    writable_plant = {"water_flow_setpoint_kg_h", "return_setpoint_C", "boiler_set_temp_C",
                      "boiler_command", "pump_on", "return_heating"}  # fmt: skip
    assert writable_plant | {"speed_factor"} == offered
    c = client(port)
    try:
        for signal, device, name, value in (
            ("return_setpoint_C", "bench_plc", "return_setpoint", 60.0),
            ("boiler_set_temp_C", "boiler_controller", "set_temp", 65.5),
        ):
            status, _ = _post(http, json.dumps({"signal": signal, "value": value}).encode())
            assert status == 200, signal
            assert read_point(c, *point(MAP, device, name)) == pytest.approx(value, abs=1e-9)
        # the map's 40..80 for the boiler's set temperature: Modbus exception 03
        status, body = _post(http, b'{"signal": "boiler_set_temp_C", "value": 95}')
        assert status == 400 and "03" in body["error"]
    finally:
        c.close()


def _trend_times(http: int, seconds: float) -> list[float]:
    """The simulated times of the trend samples the stream pushes over ``seconds``."""
    times: list[float] = []
    with socket.create_connection(("127.0.0.1", http), timeout=10) as s:
        s.sendall(b"GET /api/stream HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        stream = s.makefile("rb")
        b"".join(iter(stream.readline, b"\r\n"))
        stream.readline()  # the first event: the state of the moment
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            line = stream.readline()
            if line.startswith(b"data: "):
                times += json.loads(line.removeprefix(b"data: "))["trend_point"]["time_s"]
    return times


def test_at_real_time_the_trends_get_a_point_every_wall_second(served):
    """A stranger's probe: at real time x1 the trends got a new point only every ~11 s
    (12 h / 4000 points); CONTRACT 8 says at least once per simulated-or-wall second."""
    _, http = served()
    times = sorted(set(_trend_times(http, 4.0)))  # (the old stream sent its last again)
    assert len(times) >= 4  # 4 s of wall time: at least one new point a second
    gaps = [b - a for a, b in itertools.pairwise(times)]
    assert max(gaps) <= 1.0, times  # x1: a simulated second is a wall second


def test_the_trend_is_bounded_with_the_recent_past_in_full():
    """A stranger's probe: the trend kept one point per 10.8 s at most. Now every sample of
    the recent past is kept and older ones thinned: 12 h of samples twice a second stay
    within the bound, the 12 h window is covered, the newest minutes at full resolution."""
    trend = Trend()
    values = dict.fromkeys(TREND_SIGNALS, 1.0)
    for i in range(2 * 13 * 3600):  # 13 h of samples every 0.5 s
        trend.add(i * 0.5, values)
    history = trend.as_dict()
    times = history["time_s"]
    assert len(times) <= 2760  # the tiers' sum: 600 + 720 + 1440
    assert times[-1] - times[0] >= 12 * 3600 - 60  # the window, less one thinned step
    assert times[-300:] == [times[-1] - 0.5 * k for k in range(299, -1, -1)]  # 2.5 min
    assert all(b > a for a, b in itertools.pairwise(times))
    assert len(trend.as_dict(3600.0)["time_s"]) < len(times)


def test_a_long_lockstep_advance_shows_what_the_plant_did_inside(served):
    """A stranger's probe: one advance of 3600 s became one straight segment from its
    start to its end on the trends (time_s [0, 3600]), over a start-up. Now the trend is
    sampled inside the advance (at most ADVANCE_SAMPLES points), and the flue gas rises in
    minutes, not as a ramp over the hour."""
    port, http = served("--lockstep")
    c = client(port)
    try:
        start_boiler(c, MAP, seconds=3600)
        fg = read_point(c, *point(MAP, "flue_gas_probe", "flue_gas_temp"))
    finally:
        c.close()
    time.sleep(1.2)  # a push period and more
    trend = _state(http)["trend"]
    times, flue = trend["time_s"], trend["flue_gas_temp_C"]
    inside = [t for t in times if 0 < t < 3600]
    assert 100 <= len(inside) <= 200  # ADVANCE_SAMPLES = 200 per advance at most
    assert times[-1] == pytest.approx(3600) and flue[-1] == pytest.approx(fg, abs=1e-9)
    # a straight line from the start to the end would be half way at 1800 s; the plant
    # was hot long before (a start-up takes minutes: 20 °C of margin is far above noise)
    at_half = flue[min(range(len(times)), key=lambda i: abs(times[i] - 1800))]
    assert at_half > (flue[0] + flue[-1]) / 2 + 20, (flue[0], at_half, flue[-1])


def test_the_state_right_after_a_lockstep_advance_is_the_advances_end(served):
    """A stranger's probe: /api/state right after an advance showed the time and readings
    of before it (the last push's, up to half a second old) beside a trend already at its
    end."""
    port, http = served("--lockstep")
    c = client(port)
    try:
        start_boiler(c, MAP, seconds=600)
        fg = read_point(c, *point(MAP, "flue_gas_probe", "flue_gas_temp"))
        state = _state(http)  # at once: no push since the advance
    finally:
        c.close()
    assert state["time_s"] == pytest.approx(600) == state["trend"]["time_s"][-1]
    probe = next(u for u in state["units"] if u["name"] == "flue_gas_probe")
    shown = next(r["value"] for r in probe["readings"] if r["name"] == "flue_gas_temp")
    assert shown == pytest.approx(fg, abs=1e-9)


def test_the_api_shows_each_reading_as_its_registers_carry_it(served):
    """A stranger's probe: with the clean profile /api/state showed the plant's values,
    not the wire's (the FID's int16 x0.1 served 3.1, the API said 3.0731...; the flue gas
    118.71 on the wire, 118.70835... in the API and its trend)."""
    port, http = served("--lockstep")
    c = client(port)
    try:
        start_boiler(c, MAP, seconds=1665)
        time.sleep(1.2)  # a push period and more: the dashboard samples the new state
        state = _state(http)
        for unit in state["units"]:
            dev = MAP.map.device(unit["name"])
            for r in unit["readings"]:
                p = next(p for p in dev.points if p.name == r["name"])
                wire = read_point(c, dev, p)
                if r["value"] is None:
                    assert math.isnan(wire) or wire == invalid_value(p), (p.name, wire)
                elif p.datatype.startswith("float"):  # its float32's shortest decimal
                    assert r["value"] == pytest.approx(wire, rel=2**-24), (p.name, wire)
                else:  # a scaled integer: exactly its step's decimals
                    assert r["value"] == round(wire, r["decimals"]), (p.name, wire)
        wire_fg = read_point(c, *point(MAP, "flue_gas_probe", "flue_gas_temp"))
        assert state["trend"]["flue_gas_temp_C"][-1] == round(wire_fg, 2)
    finally:
        c.close()


@pytest.mark.parametrize(
    ("request_bytes", "expect"),
    [
        # HEAD of a page: its head, no body (RFC 9110 9.3.2)
        (b"HEAD / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n", (b"200", b"text/html", None)),
        (
            b"HEAD /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n",
            (b"200", b"application/json", None),
        ),
        # 405 names what is allowed (RFC 9110 15.5.6)
        (
            b"PUT /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n",
            (b"405", b"Allow: GET, HEAD", b"PUT"),
        ),
        (b"GET /api/control HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n", (b"405", b"Allow: POST", b"GET")),
        # the method before the body's type: a POST to a page that takes none is 405
        # (a re-probe: 403 "Content-Type none"), with or without a body
        (
            b"POST /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n",
            (b"405", b"Allow: GET, HEAD", b"POST"),
        ),
        (
            b"POST / HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 2\r\n\r\n{}",
            (b"405", b"Allow: GET, HEAD", b"POST"),
        ),
        # the path asked for, not a host "api" and a path "/state"
        (b"GET //api/state HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n", (b"404", b"", b"//api/state")),
        (
            b"GET /api/state?window=" + b"9" * 5000 + b" HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n",
            (b"414", b"", b"4096"),
        ),
        (
            b"GET /" + b"a" * 70_000 + b" HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n",
            (b"414", b"", b"4096"),
        ),
    ],
)
def test_http_methods_paths_and_lengths(served_once, request_bytes, expect):
    """A stranger's probe: HEAD / got 405, a 405 carried no Allow, GET //api/state said
    "no such page: /state", a URL of 5000 bytes got 400 "headers too long"."""
    _, http = served_once("--lockstep")
    status, header, in_body = expect
    answer = _raw(http, request_bytes)
    head, _, body = answer.partition(b"\r\n\r\n")
    assert head.split(b" ")[1] == status, answer[:300]
    assert header in head
    if in_body is None:  # HEAD: the length of the body it would get, and no body
        length = int(head.split(b"Content-Length: ")[1].split(b"\r\n")[0])
        assert length > 0 and body == b""
    else:
        assert in_body in body, body


@pytest.mark.parametrize("body", [b"", b"  ", b"signal=speed_factor"])
def test_an_empty_or_non_json_control_body_says_not_json(served_once, body):
    """A stranger's probe: an empty body to /api/control was read as {} and answered
    "signal: expected one of ...", as if the signal were missing."""
    _, http = served_once("--lockstep", "--http-control")
    for path in ("/api/control", "/api/faults"):
        status, answer = _post(http, body, path)
        assert status == 400 and "not JSON" in answer["error"], (path, answer)


@pytest.mark.parametrize("signal", [b'["speed_factor"]', b'{"a": 1}'])
def test_a_control_signal_that_is_no_name_is_a_400(served_once, signal):
    """A stranger's probe: a list or an object as the signal was a traceback in the
    server's log ("unhashable type") and an empty reply."""
    _, http = served_once("--lockstep", "--http-control")
    status, answer = _post(http, b'{"signal": ' + signal + b', "value": 1}', "/api/control")
    assert status == 400 and answer["error"].startswith("signal: expected one of"), answer


@pytest.mark.parametrize(
    "lengths",
    [[b"+2"], [b"2_0"], [b"\xd9\xa2"], [b"2", b"99"]],  # (an Arabic-Indic two too)
)
def test_a_content_length_that_is_no_number_of_bytes_or_given_twice_is_a_400(served_once, lengths):
    """A stranger's probe: Content-Length +30 and 3_0 were taken (Python's int() reads
    them; RFC 9110 8.6 allows digits only), and two differing ones waited for the larger,
    then dropped the connection with no reply (RFC 9112 6.3: a 400)."""
    _, http = served_once("--lockstep", "--http-control")
    fields = b"".join(b"Content-Length: " + n + b"\r\n" for n in lengths)
    request = b"POST /api/control HTTP/1.1\r\nHost: 127.0.0.1\r\n" + fields + b"\r\n{}"
    with socket.create_connection(("127.0.0.1", http), timeout=10) as s:
        s.sendall(request)
        assert s.recv(64).split(b" ")[1] == b"400"


@pytest.mark.parametrize(
    ("request_bytes", "status", "said"),
    [
        # RFC 9112 3.2: an HTTP/1.1 request without Host, or with two, is a 400
        (b"GET /api/state HTTP/1.1\r\n\r\n", b"400", b"without a Host"),
        (b"GET / HTTP/1.1\r\nHost: a\r\nHost: 127.0.0.1\r\n\r\n", b"400", b"Host given 2"),
        (b"GET / HTTP/1.1\r\nHost: 127.0.0.1/x\r\n\r\n", b"400", b"not a host and port"),
        # a malformed IP literal, in Host or in an absolute target: a traceback, no reply
        (b"GET / HTTP/1.1\r\nHost: [::1\r\n\r\n", b"400", b"not a host and port"),
        (b"GET / HTTP/1.1\r\nHost: [::1]x\r\n\r\n", b"400", b"not a host and port"),
        (b"GET http://[::1/ HTTP/1.1\r\n\r\n", b"400", b"not a URL"),
        (b"GET / HTTP/1.1\r\nHost: localhost:99999\r\n\r\n", b"400", b"not a host"),
        (b"GET /api/state HTTP/1.1\r\nHost: [::1]:8080\r\n\r\n", b"200", b'"units"'),
        (b"GET /api/state HTTP/1.0\r\n\r\n", b"200", b'"units"'),  # 1.0 may omit it
        # an absolute target's authority is the host (RFC 9112 3.2.2), Host ignored
        (b"GET http://localhost/api/state HTTP/1.1\r\n\r\n", b"200", b'"units"'),
        # RFC 9112 5.1: whitespace before the colon MUST be a 400; 5.2: a folded line (a
        # re-probe: both were taken, the first as the Host)
        (b"GET / HTTP/1.1\r\nHost : 127.0.0.1\r\n\r\n", b"400", b"malformed header"),
        (b"GET / HTTP/1.1\r\nHost:\r\n 127.0.0.1\r\n\r\n", b"400", b"folded"),
        (b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nno colon\r\n\r\n", b"400", b"malformed"),
        # RFC 9112 2.2: a bare LF may end a line (typed into nc: it waited 10 s for a CRLF
        # and said 408, a stranger's probe); a TLS hello is told at once, not after 10 s
        (b"GET /api/state HTTP/1.0\n\n", b"200", b'"units"'),
        (b"GET /api/state HTTP/1.1\nHost: 127.0.0.1\r\n\n", b"200", b'"units"'),
        (b"\x16\x03\x01\x00\xa5\x01\x00\x00\xa1\x03\x03", b"400", b"a TLS handshake"),
    ],
)
def test_the_host_is_one_field_or_the_targets_authority(served_once, request_bytes, status, said):
    """A stranger's probe: HTTP/1.1 requests without a Host field were answered; two
    differing Host fields were read as the last."""
    _, http = served_once("--lockstep")
    answer = _raw(http, request_bytes)
    assert answer.split(b" ")[1] == status and said in answer, answer[:300]


@pytest.mark.parametrize(
    ("target", "headers"),
    [
        # a proxy's absolute form names another host: that is the host, whatever Host says
        ("http://attacker.example/api/control", {"Host": "127.0.0.1"}),
        # a page of https://127.0.0.1:PORT is another origin (RFC 6454 4: the scheme too)
        ("/api/control", {"Host": "127.0.0.1:{http}", "Origin": "https://127.0.0.1:{http}"}),
        ("/api/control", {"Host": "127.0.0.1:{http}", "Origin": "null"}),  # a sandbox, a file
    ],
)
def test_a_control_from_another_origin_by_another_path_is_refused(served_once, target, headers):
    """A re-probe: the Origin's scheme was not compared (https://host was taken for the
    page's own), and a control in absolute form was judged by its Host field alone."""
    _, http = served_once("--lockstep", "--http-control")
    fields = "".join(f"{k}: {v.format(http=http)}\r\n" for k, v in headers.items())
    body = b'{"signal": "speed_factor", "value": 2}'
    request = (
        f"POST {target} HTTP/1.1\r\n{fields}Content-Type: application/json\r\n"
        f"Content-Length: {len(body)}\r\n\r\n"
    ).encode() + body
    assert _raw(http, request).split(b" ")[1] == b"403"


def test_a_request_that_never_ends_is_told_408(served_once):
    """A stranger's probe: a request whose end never came was closed after 10 s without a
    word; RFC 9110 15.5.9 has the server say 408 and close."""
    _, http = served_once("--lockstep")
    with socket.create_connection(("127.0.0.1", http), timeout=30) as s:
        s.sendall(b"GET /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\n")  # no blank line
        answer = b""
        while chunk := s.recv(4096):
            answer += chunk
    assert answer.split(b" ")[1] == b"408" and b"incomplete" in answer, answer[:300]


@pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed (make tools installs it)")
def test_axes_and_faults_are_readable_in_a_real_browser(served, tmp_path):
    """A stranger's probe (lab profile, steady state): the flue gas axis read 118 118 118
    118 118 while the line swung over the plot's whole height (sensor noise of a tenth of
    a degree), the heat axis 12.4 12.3 12.3 ...; the y axes had no units and the time axis
    only its two ends; the active faults were raw JSON at the bottom of the page, and a
    fault set from the dashboard said "source": "python"."""
    journal = tmp_path / "journal.jsonl"
    port, http = served(
        "--lockstep", "--profile", "lab", "--http-control", "--fault-log", str(journal)
    )
    c = client(port)
    try:
        start_boiler(c, MAP, seconds=3 * 3600)
        assert not write(c, MAP, "sim_control", "lockstep_advance", 3600).isError()
    finally:
        c.close()
    fault = b'{"inject": {"kind": "no_reply", "unit": 2, "for_s": 600}}'
    assert _post(http, fault, "/api/faults")[0] == 200
    assert [f["source"] for f in _state(http)["faults"]] == ["dashboard"]
    started = [json.loads(x) for x in journal.read_text().splitlines()]
    assert [e["source"] for e in started if e["event"] == "start"] == ["dashboard"]

    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1400,1000",
             "--timeout=10000"]  # fmt: skip
    url = f"http://127.0.0.1:{http}/"
    dom = subprocess.run(
        [CHROMIUM, *flags, "--dump-dom", url], capture_output=True, timeout=120, text=True
    ).stdout
    for canvas in ("c_temp", "c_heat", "c_o2", "c_mass"):
        tag = dom.split(f'id="{canvas}"', 1)[1].split(">", 1)[0]
        ticks = json.loads(html.unescape(tag.split('data-ticks="', 1)[1].split('"', 1)[0]))
        for side in ("left", "right"):
            if ticks[side]:
                unit, *labels = ticks[side]
                assert unit.startswith("[") and len(labels) >= 2, (canvas, ticks)
                assert len(set(labels)) == len(labels), (canvas, ticks)  # all distinct
        assert len(ticks["time"]) >= 3, (canvas, ticks)  # intermediate times too
    # the faults near the top, before the readings, each as words, not JSON
    bar = dom.split('id="faultbar"', 1)[1].split("</section>", 1)[0]
    assert dom.index('id="faultbar"') < dom.index('id="units"')
    text = re.sub(r"<[^>]+>", " ", bar)
    assert "no_reply" in text and "unit 2" in text and "from dashboard" in text
    assert '"kind"' not in text and "{" not in text


def _stream_events(http: int, stop: threading.Event, events: list[dict]) -> None:
    """Collect the stream's events into ``events`` until ``stop`` is set."""
    with socket.create_connection(("127.0.0.1", http), timeout=30) as s:
        s.sendall(b"GET /api/stream HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        stream = s.makefile("rb")
        b"".join(iter(stream.readline, b"\r\n"))
        while not stop.is_set():
            line = stream.readline()
            if not line:
                return
            if line.startswith(b"data: "):
                events.append(json.loads(line.removeprefix(b"data: ")))


def _inside(times: list[float], start: float, end: float) -> int:
    return sum(start < t < end for t in times)


def test_a_push_inside_a_long_advance_keeps_the_trend(served):
    """A stranger's re-probe: lockstep with the lab profile, six advances of 21600 s: after
    each, the trend held only the last advance (184, 158, ..., 7 points), two of 86400 s
    78 points and a jump. A push landing inside an advance added the state published
    before it, older than the samples already taken inside, and the trend read the time
    going back as a plant reset. Now only a reset (the server's count of them) starts a
    new history: every advance keeps its samples, and a real reset still starts over."""
    port, http = served("--lockstep", "--profile", "lab")
    events: list[dict] = []
    stop = threading.Event()
    reader = threading.Thread(target=_stream_events, args=(http, stop, events), daemon=True)
    reader.start()
    day = 86400
    c = client(port, timeout_s=120.0)
    try:
        assert not write(c, MAP, "boiler_controller", "on_command", 1).isError()
        began = time.monotonic()
        for _ in range(3):  # each about 0.9 s of wall time here: pushes land inside
            assert not write(c, MAP, *ADVANCE, day).isError()
        advancing_s = time.monotonic() - began
        time.sleep(2 * PUSH_PERIOD_S)
        times = _state(http)["trend"]["time_s"]
        assert times[0] == 0.0 and times[-1] == 3 * day, (times[:3], times[-3:])
        assert all(b > a for a, b in itertools.pairwise(times))
        counts = [_inside(times, i * day, (i + 1) * day) for i in range(3)]
        # the same advance thrice: as many samples inside each, ADVANCE_SAMPLES at most
        # (the existing probe's bound: at least half of them)
        assert len(set(counts)) == 1 and ADVANCE_SAMPLES // 2 <= counts[0] <= ADVANCE_SAMPLES
        # the case was met: an event pushed while an advance ran (the state it carries is
        # the one published before the advance, its new samples are later)
        pushed_inside = [
            e
            for e in events
            if e["trend_point"]["time_s"] and max(e["trend_point"]["time_s"]) > e["time_s"]
        ]
        assert pushed_inside, (advancing_s, len(events))

        # a reset is one: the trend starts over, of the new run; the state says so at once,
        # before the next push (a re-probe: it named the run before the reset for up to a
        # push while its trend was the new run's, and a page threw the points away)
        assert not write(c, MAP, "sim_control", "reset", 1).isError()
        for _ in range(10):
            assert not write(c, MAP, *ADVANCE, 60).isError()
        at_once = _state(http)
        assert at_once["run"]["resets"] == 1 and at_once["trend"]["time_s"][0] == 0.0
        assert not write(c, MAP, *ADVANCE, 3000).isError()
        time.sleep(2 * PUSH_PERIOD_S)
        state = _state(http)
        times = state["trend"]["time_s"]
        assert state["run"]["resets"] == 1
        assert times[0] == 0.0 and times[-1] == 3600.0 and max(times) == 3600.0
        assert _inside(times, 0, 3600) >= ADVANCE_SAMPLES // 2
    finally:
        c.close()
        stop.set()
        reader.join(timeout=5)


def _custom_map(tmp_path) -> str:
    """The bench's map with the return setpoint as int32 CDAB x0.05 +0.025 (range 10..90,
    the signal's): its steps carry 9.975 and 10.025, 89.975 and 90.025, not the ends."""
    text = (MAP_DIR / "wieselburg_bench.yaml").read_text(encoding="utf-8")
    custom = text.replace(
        "address: 2,\n         datatype: float32, access: rw}",
        "address: 2,\n         datatype: int32, word_order: CDAB, scale: 0.05, offset: 0.025,"
        " access: rw}",
    )
    assert custom != text
    path = tmp_path / "map.yaml"
    path.write_text(custom, encoding="utf-8")
    return str(path)


def test_controls_offer_and_answer_what_the_point_carries(served, tmp_path):
    """A stranger's re-probe, on a map with the return setpoint as int32 CDAB x0.05 +0.025
    in 10..90: the control offered min 10.0, and a write of 10 was refused with a bare
    "exception 03 (ILLEGAL_VALUE)" (its step carries 9.975, outside the range); 65.123
    was answered 65.12500000000001, a speed the float32 clock holds otherwise answered as
    asked; a refusal named its signal twice. Now the controls offer what the point sets,
    a value it cannot set is refused naming why and the nearest it can, an answer is the
    value held as /api/state serves it."""
    custom = _custom_map(tmp_path)
    port, http = served("--lockstep", "--http-control", "--map", custom)
    dev, p = point(SimpleNamespace(map=load_map(custom)), "bench_plc", "return_setpoint")
    control = next(c for c in _state(http)["controls"] if c["signal"] == "return_setpoint_C")
    assert (control["min"], control["max"]) == (10.025, 89.975)

    def post(signal: str, value: float) -> tuple[int, dict]:
        return _post(http, json.dumps({"signal": signal, "value": value}).encode())

    c = client(port)
    try:
        for offered in (control["min"], control["max"]):  # the ends offered are taken
            assert post("return_setpoint_C", offered) == (
                200,
                {"ok": True, "signal": "return_setpoint_C", "value": offered},
            )
            assert read_point(c, dev, p) == pytest.approx(offered, abs=1e-9)  # (float64)
        status, body = post("return_setpoint_C", 10)
        assert status == 400, body
        error = body["error"]
        assert "9.975" in error and "10.025" in error and "03" in error, error
        assert error.count("return_setpoint_C") == 1, error
        assert read_point(c, dev, p) == pytest.approx(89.975, abs=1e-9)  # unchanged
        assert post("return_setpoint_C", 65.123)[1]["value"] == 65.125
        # the clock holds the float32 of what was asked: the answer says what it holds,
        # as the state serves it
        for asked, held in ((1000.3, 1000.3), (1000.0000001, 1000.0)):
            status, body = post("speed_factor", asked)
            assert (status, body["value"]) == (200, held), body
            offered = next(c for c in _state(http)["controls"] if c["signal"] == "speed_factor")
            assert offered["value"] == held
        status, body = post("water_flow_setpoint_kg_h", 2001)
        assert status == 400 and body["error"].count("water_flow_setpoint_kg_h") == 1, body
        assert "2000" in body["error"]
    finally:
        c.close()
