"""The fault engine on a real emulator: readings change, the plant never does; the schedule
is exact in simulated time; random faults are seeded; the journal says what was served."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rig_emulator.emulator import Emulator
from rig_emulator.faults import FaultEngine, FaultJournal, faults_from_list, read_journal
from rig_emulator.instruments import load_profile

INSTRUMENT_FAULTS = [
    {"kind": "stuck", "signal": "flue_gas_temp_C", "at_s": 120, "for_s": 300},
    {"kind": "drift", "signal": "water_out_temp_C", "rate_per_h": 36.0, "at_s": 60},
    {"kind": "spike", "signal": "flue_gas_O2_pct", "value": 25.0, "at_s": 200},
    {"kind": "dropout", "signal": "flue_gas_CO_ppm", "at_s": 150, "for_s": 40},
    {"kind": "offset", "signal": "balance_mass_kg", "value": 15.0, "at_s": 250},
]


def _emulator(params, profile="lab") -> Emulator:
    emu = Emulator(params, load_profile(profile), seed=3)
    emu.set_commands(
        {"water_flow_setpoint_kg_h": 600.0, "return_setpoint_C": 55.0, "boiler_command": 1}
    )
    return emu


def _state(emu: Emulator) -> bytes:
    b = emu.bench
    return b.y.tobytes() + b.yb.tobytes() + b.s.tobytes() + np.array(emu._true).tobytes()


def test_instrument_faults_never_touch_the_plant(params_12kw, tmp_path):
    """Bit-identical plant trajectory (state, outputs, true values) with and without every
    instrument fault; the instruments' own noise draws are the same too."""
    plain = _emulator(params_12kw)
    faulty = _emulator(params_12kw)
    engine = FaultEngine(faults_from_list(INSTRUMENT_FAULTS), FaultJournal(tmp_path / "j.jsonl"))
    engine.plant = faulty.plant
    faulty.reading_hook = engine.apply
    differed = set()
    for _ in range(400):
        plain.advance(1.0)
        faulty.advance(1.0)
        a, b = plain.values(), faulty.values()
        assert _state(plain) == _state(faulty)
        assert plain.readings == faulty.readings  # the instruments drew the same noise
        assert {k: v for k, v in a.items() if k.startswith("true_")} == {
            k: v for k, v in b.items() if k.startswith("true_")
        }
        differed |= {k for k in a if not (a[k] == b[k] or (math.isnan(a[k]) and math.isnan(b[k])))}
    # ... while the readings (and the status the instruments report) did change
    assert {f["signal"] for f in INSTRUMENT_FAULTS} <= differed
    assert {"analyser_status", "balance_stable"} <= differed


@pytest.mark.parametrize(
    "before",
    [
        {"kind": "offset", "signal": "balance_mass_kg", "value": 15.0, "at_s": 10},
        {"kind": "drift", "signal": "balance_mass_kg", "rate_per_h": 360.0, "at_s": 10},
    ],
)
def test_a_stuck_reading_freezes_what_was_served_with_the_faults_before_it(params_12kw, before):
    """CONTRACT section 5: "the reading freezes at its value when the fault starts". A stuck
    fault set over an active offset (+15 kg, a refill) or drift froze the instrument's own
    reading instead: the served balance jumped back 15 kg (a stranger's probe)."""
    emu = _emulator(params_12kw, "clean")
    stuck = {"kind": "stuck", "signal": "balance_mass_kg", "at_s": 60, "for_s": 30}
    engine = FaultEngine(faults_from_list([before, stuck]))
    emu.reading_hook = engine.apply
    seen: dict[float, float] = {}
    true: dict[float, float] = {}
    for _ in range(100):
        emu.advance(1.0)
        seen[emu.sim_time_s] = emu.values()["balance_mass_kg"]
        true[emu.sim_time_s] = emu.values()["true_balance_mass_kg"]
    # held at the reading served at 60 s, one step (0.1 kg of the drift) from the one before
    assert seen[60.0] == pytest.approx(seen[59.0], abs=0.15)
    assert all(seen[t] == seen[60.0] for t in np.arange(60.0, 90.0))
    assert seen[60.0] - true[60.0] > 4.0  # the offset or the drift's 5 kg stays in it


def test_each_kind_acts_on_the_reading_from_its_step(params_12kw):
    emu = _emulator(params_12kw, "clean")
    engine = FaultEngine(faults_from_list(INSTRUMENT_FAULTS))
    emu.reading_hook = engine.apply
    seen: dict[float, dict[str, float]] = {}
    for _ in range(460):
        emu.advance(1.0)
        seen[emu.sim_time_s] = emu.values()
    t = seen
    # stuck from t = 120 for 300 s at the reading of t = 120
    held = t[120.0]["true_flue_gas_temp_C"]
    assert all(t[s]["flue_gas_temp_C"] == held for s in np.arange(120.0, 420.0))
    assert t[420.0]["flue_gas_temp_C"] == t[420.0]["true_flue_gas_temp_C"] != held
    # drift 36 K/h from t = 60: +1 K at t = 160
    assert t[160.0]["water_out_temp_C"] - t[160.0]["true_water_out_temp_C"] == pytest.approx(1.0)
    assert t[59.0]["water_out_temp_C"] == t[59.0]["true_water_out_temp_C"]
    # spike: exactly one acquisition at 1 s steps
    spiked = [s for s, v in t.items() if v["flue_gas_O2_pct"] == 25.0]
    assert spiked == [200.0]
    # dropout: NaN, the analyser not measuring (bit 0 off) and flagging it (bit 2)
    assert math.isnan(t[150.0]["flue_gas_CO_ppm"]) and math.isnan(t[189.0]["flue_gas_CO_ppm"])
    assert t[150.0]["analyser_status"] == 4.0 and t[149.0]["analyser_status"] == 1.0
    assert t[190.0]["flue_gas_CO_ppm"] == t[190.0]["true_flue_gas_CO_ppm"]
    assert t[190.0]["analyser_status"] == 1.0
    # offset: a refill, +15 kg; the balance is not stable for 5 s after the jump
    assert t[250.0]["balance_mass_kg"] - t[250.0]["true_balance_mass_kg"] == pytest.approx(15.0)
    assert t[250.0]["balance_stable"] == 0.0


def test_schedule_is_exact_in_simulated_time(tmp_path):
    """CONTRACT section 5: "each entry starts at at_s (simulated seconds) and lasts for_s".
    Evaluated every 7 s, a fault is seen by the evaluations inside its window and gone from
    the first after it; the journal gives the window's own times, in their order."""
    path = tmp_path / "j.jsonl"
    engine = FaultEngine(
        faults_from_list(
            [
                {"kind": "no_reply", "unit": 2, "at_s": 25.0, "for_s": 10.0},
                {"kind": "exception", "unit": 0, "code": 4, "at_s": 30.0},
            ]
        ),
        FaultJournal(path),
    )
    decisions = {}
    for t in np.arange(0.0, 60.0, 7.0):  # steps of 7 s: 21, 28, 35, 42 ...
        engine.apply({}, float(t))
        decisions[float(t)] = (engine.decide(2), engine.decide(5), engine.decide(100))
    assert decisions[21.0] == (None, None, None)
    assert decisions[28.0][0].drop and decisions[28.0][1] is None
    assert not decisions[35.0][0].drop  # 25 to 35: over at 35
    assert decisions[35.0][0].exception_code == 4  # unit 0's exception from 30 on
    assert decisions[35.0][1].exception_code == 4 and decisions[35.0][2] is None
    assert decisions[42.0][0].exception_code == 4
    events = read_journal(path)
    assert [(e["event"], e["kind"], e["t_sim_s"]) for e in events] == [
        ("start", "no_reply", 25.0),
        ("start", "exception", 30.0),
        ("end", "no_reply", 35.0),
    ]
    assert events[1]["served"] == {"exception_code": 4}
    assert events[2]["requests"] == 1  # decide(2) at 28


def test_a_window_inside_one_long_advance_is_over_after_it(tmp_path):
    """One evaluation 880 s after the last (a lockstep advance of 880 s): faults whose
    windows lay inside it are journalled as started and ended at their own times, unseen,
    and act on nothing after it; one that began inside it and lasts beyond is active with
    its own end."""
    path = tmp_path / "j.jsonl"
    engine = FaultEngine(
        faults_from_list(
            [
                {"kind": "delay", "unit": 1, "delay_ms": 800, "at_s": 700, "for_s": 10},
                {"kind": "exception", "unit": 5, "code": 6, "at_s": 740, "for_s": 10},
                {"kind": "dropout", "signal": "flue_gas_temp_C", "at_s": 860, "for_s": 5},
                {"kind": "no_reply", "unit": 2, "at_s": 870, "for_s": 30},
            ]
        ),
        FaultJournal(path),
    )
    engine.apply({"flue_gas_temp_C": 120.0}, 0.0)
    readings = {"flue_gas_temp_C": 120.0}
    engine.apply(readings, 880.0)
    assert readings["flue_gas_temp_C"] == 120.0
    assert engine.decide(1) is None and engine.decide(5) is None
    assert engine.decide(2).drop
    engine.apply({"flue_gas_temp_C": 120.0}, 899.0)
    assert engine.decide(2).drop
    engine.apply({"flue_gas_temp_C": 120.0}, 900.0)
    assert engine.decide(2) is None and not engine.active
    events = [(e["event"], e["kind"], e["t_sim_s"], e["served"]) for e in read_journal(path)]
    unseen = {"seen": False, "why": "its whole window fell between two evaluations"}
    assert events == [
        ("start", "delay", 700.0, unseen),
        ("end", "delay", 710.0, unseen),
        ("start", "exception", 740.0, unseen),
        ("end", "exception", 750.0, unseen),
        ("start", "dropout", 860.0, unseen),
        ("end", "dropout", 865.0, unseen),
        ("start", "no_reply", 870.0, {"reply": "none"}),
        ("end", "no_reply", 900.0, {"reply": "normal"}),
    ]


def test_a_disconnect_window_inside_one_advance_closes_nothing(tmp_path):
    """A disconnect with a window (for_s) wholly inside one evaluation step closes no
    connection after it; a one-shot disconnect (no for_s) still happens, once, late."""
    path = tmp_path / "j.jsonl"
    closed: list[str] = []
    engine = FaultEngine(
        faults_from_list(
            [
                {"kind": "disconnect", "at_s": 300, "for_s": 5},
                {"kind": "disconnect", "at_s": 160},
            ]
        ),
        FaultJournal(path),
    )
    engine.on_disconnect = lambda reason: closed.append(reason) or 1
    engine.apply({}, 0.0)
    engine.apply({}, 1000.0)
    assert len(closed) == 1  # the one-shot only
    events = [(e["event"], e["t_sim_s"], e["served"]) for e in read_journal(path)]
    unseen = {"seen": False, "why": "its whole window fell between two evaluations"}
    assert ("start", 300.0, unseen) in events and ("end", 305.0, unseen) in events
    # the one-shot as it happened, at the evaluation, and the journal in time order (its
    # lines came first, before the 300-s window's: a stranger's probe)
    assert ("start", 1000.0, {"connections_closed": 1}) in events
    times = [t for _, t, _ in events]
    assert times == sorted(times)
    ends = [e for e in read_journal(path) if e["event"] == "end" and e["kind"] == "disconnect"]
    assert sorted(e["reason"] for e in ends) == ["for_s elapsed", "once"]


def test_a_fault_set_after_its_at_s_starts_when_it_is_set(tmp_path):
    """Set at 100 s with at_s 50 and for_s 30: it starts at 100 and lasts 30 s (it was not
    there to be seen from 50 to 80)."""
    engine = FaultEngine(journal=FaultJournal(tmp_path / "j.jsonl"))
    engine.apply({}, 100.0)
    engine.add(faults_from_list([{"kind": "no_reply", "unit": 3, "at_s": 50, "for_s": 30}])[0])
    assert engine.decide(3).drop
    engine.apply({}, 129.0)
    assert engine.decide(3).drop
    engine.apply({}, 130.0)
    assert engine.decide(3) is None
    start, end = read_journal(tmp_path / "j.jsonl")  # the journal says what was asked
    assert (start["t_sim_s"], start["at_s"], start["for_s"]) == (100.0, 50.0, 30.0)
    assert end["t_sim_s"] == 130.0 and "at_s" not in end


def test_random_faults_are_seeded_and_at_the_rate():
    spec = [{"kind": "random", "rate_per_h": 6, "kinds": ["no_reply", "dropout"], "seed": 11}]

    def starts(seed_spec) -> list[tuple[float, str, object]]:
        engine = FaultEngine(faults_from_list(seed_spec))
        out = []
        seen: set[int] = set()
        for t in range(0, 20 * 3600, 10):
            engine.apply({"flue_gas_CO_ppm": 1.0}, float(t))
            for fault in engine.active.values():
                if fault.id not in seen:
                    seen.add(fault.id)
                    out.append(
                        (fault.start_s, fault.spec.kind, fault.spec.unit or fault.spec.signal)
                    )
        return out

    first, again = starts(spec), starts(spec)
    other = starts([{**spec[0], "seed": 12}])
    assert first == again and first != other
    # a Poisson count over 20 h at 6/h: 120 expected, sd 11; 5 sd either side
    assert 65 <= len(first) <= 175
    assert {k for _, k, _ in first} == {"no_reply", "dropout"}


def test_random_faults_are_the_same_whatever_the_advances(tmp_path):
    """One 3-h advance journals the random faults that 180 one-minute advances journal (at
    the same times, the same kinds and targets), those it passed over as unseen: it used to
    skip them, and the draws after them changed too (a user's lab_faulty run found 1 of 4)."""
    spec = [{"kind": "random", "rate_per_h": 4, "kinds": ["no_reply", "spike"], "seed": 5,
             "fault_for_s": 30}]  # fmt: skip

    def journal(times, name) -> list[tuple]:
        path = tmp_path / name
        engine = FaultEngine(faults_from_list(spec), FaultJournal(path))
        for t in times:
            engine.apply({"flue_gas_O2_pct": 8.0}, float(t))
        events = read_journal(path)
        return [
            (e["event"], e["t_sim_s"], e["kind"], e.get("unit"), e.get("signal")) for e in events
        ]

    short = journal(range(60, 3 * 3600 + 1, 60), "short.jsonl")
    long = journal([3 * 3600], "long.jsonl")
    assert len(short) >= 4  # 4/h over 3 h: 12 expected
    assert long == short


def test_reset_rearms_the_schedule_and_clear_ends_everything(tmp_path):
    path = tmp_path / "j.jsonl"
    engine = FaultEngine(
        faults_from_list([{"kind": "dropout", "signal": "room_temp_C", "at_s": 5}]),
        FaultJournal(path),
    )
    readings = {"room_temp_C": 20.0}
    engine.apply(readings, 10.0)
    assert math.isnan(readings["room_temp_C"])
    readings = {"room_temp_C": 20.0}
    engine.apply(readings, 0.0)  # the plant was reset
    assert readings["room_temp_C"] == 20.0 and not engine.active
    engine.apply(readings, 6.0)
    assert len(engine.active) == 1
    assert engine.clear() == 1 and engine.idle
    reasons = [e.get("reason") for e in read_journal(path) if e["event"] == "end"]
    assert reasons == ["reset", "cleared"]


def test_clear_names_the_scheduled_faults_it_drops(tmp_path, caplog):
    """Clearing drops the faults not yet started (a FAULTS.yaml entry due later): the
    journal has lines only for faults that start, so the server's log names them (they
    used to vanish without a word); a reset, which schedules them again, says nothing."""
    path = tmp_path / "j.jsonl"
    engine = FaultEngine(
        faults_from_list([{"kind": "disconnect", "at_s": 40}]), FaultJournal(path), source="file"
    )
    engine.apply({}, 15.0)
    engine.apply({}, 0.0)  # a reset
    assert "dropped" not in caplog.text
    engine.apply({}, 15.0)
    assert engine.clear() == 0 and engine.idle
    assert "dropped before they started: disconnect at 40 s (file)" in caplog.text
    engine.apply({}, 45.0)
    assert read_journal(path) == []  # it never started
