"""A request held by delay faults waits only as long as they last: each that ends (cleared,
its for_s elapsed, a reset) drops out of its hold, which then asks the longest delay of
those still active (a stranger's probe: a cleared 20 s delay still held its read 19 s)."""

from __future__ import annotations

from rig_emulator.faults import FaultEngine, faults_from_list
from rig_emulator.faults.engine import holding


def _engine() -> FaultEngine:
    return FaultEngine(
        faults_from_list(
            [
                {"kind": "delay", "unit": 0, "delay_ms": 20000, "at_s": 0, "for_s": 5},
                {"kind": "delay", "unit": 3, "delay_ms": 1000, "at_s": 0},
            ]
        )
    )


def test_a_hold_asks_the_delays_still_active_and_says_when_one_ends():
    engine = _engine()
    engine.apply({}, 0.0)
    changes: list[float] = []
    with holding() as holds:
        decision = engine.decide(3)
    assert decision is not None and decision.delay_s == 20.0
    (hold,) = holds
    hold.on_change = lambda: changes.append(hold.delay_s)
    assert hold.delay_s == 20.0
    engine.apply({}, 6.0)  # the 20 s delay's for_s elapsed: the 1 s one still holds
    assert changes == [1.0] and hold.delay_s == 1.0
    engine.clear()
    assert changes == [1.0, 0.0] and hold.delay_s == 0.0


def test_a_reset_ends_the_hold_and_an_answered_request_is_forgotten():
    engine = _engine()
    engine.apply({}, 1.0)
    with holding() as holds:
        engine.decide(1)  # the delay on every unit only
    (hold,) = holds
    assert hold.delay_s == 20.0
    hold.close()  # answered: the faults forget it
    assert all(not f.holds for f in engine.active.values())
    with holding() as holds:
        engine.decide(1)
    engine.apply({}, 0.0)  # the plant was reset
    assert holds[0].delay_s == 0.0


def test_a_delay_decided_outside_holding_is_a_plain_number():
    engine = _engine()
    engine.apply({}, 0.0)
    assert engine.decide(3).delay_s == 20.0  # (the RTU line waits it out itself)
    assert all(not f.holds for f in engine.active.values())
