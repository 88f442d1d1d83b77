"""The safety filter (enable switch, bounds, dedup, interval, token bucket, rate limit) and the
lost-machine policy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnctwin.control import (
    Commanded,
    ControlConfig,
    Decision,
    LostMachinePolicy,
    OverrideLimits,
    SafetyFilter,
)
from cnctwin.errors import InputError

ON = ControlConfig(enabled=True)


def decision(action: str, value: float | None, t: float = 0.0, rule: str = "r") -> Decision:
    return Decision(t, rule, action, value, "test")


def test_disabled_control_blocks_every_command_and_records_notifications() -> None:
    flt = SafetyFilter(ControlConfig())
    for action, value in (("stop", 1.0), ("feed_hold", 1.0), ("feed_override", 50.0)):
        verdict = flt.check(decision(action, value), 0.0)
        assert verdict.outcome == "blocked" and not verdict.send
        assert verdict.note == "control disabled ([control] enabled = false)"
    note = flt.check(decision("notify", None), 0.0)
    assert note.outcome == "recorded" and note.command is None
    assert flt.counts == {"blocked": 3, "recorded": 1}
    assert flt.commanded == {}


def test_overrides_are_clamped_to_bounds() -> None:
    flt = SafetyFilter(ON)  # feed 10-100 %, spindle 80-110 %
    low = flt.check(decision("feed_override", 2.0), 0.0)
    assert (low.outcome, low.value) == ("clamped", 10.0) and "clamped to [10, 100]" in low.note
    high = SafetyFilter(ON).check(decision("feed_override", 140.0), 0.0)
    assert high.value == 100.0
    spin = SafetyFilter(ON).check(decision("spindle_override", 60.0), 0.0)
    assert spin.value == 80.0


def test_lowering_the_feed_is_immediate_raising_it_is_rate_limited() -> None:
    """Feed defaults: fall unlimited, rise 20 %/s. 100 -> 50 at once; back to 100 takes
    46 / 20 = 2.3 s of follow-up steps, each <= 20 %/s times the time since the last."""
    flt = SafetyFilter(ON)
    first = flt.check(decision("feed_override", 50.0), 0.0, {"feed_override_pct": 100.0})
    assert (first.outcome, first.value) == ("sent", 50.0)
    up = flt.check(decision("feed_override", 100.0, 0.2), 0.2)
    assert up.outcome == "clamped" and up.value == pytest.approx(54.0)
    assert flt.pending() == {"feed_override_pct": 100.0}
    sent = [(0.2, up.value)]
    t = 0.2
    while flt.pending() and t < 10:
        t = round(t + 0.0125, 6)
        sent += [(t, v.value) for v in flt.follow_up(t) if v.send]
    assert sent[-1][1] == 100.0 and t == pytest.approx(0.2 + 46.0 / 20.0, abs=1e-6)
    for (t0, v0), (t1, v1) in zip(sent, sent[1:], strict=False):
        assert t1 - t0 >= 0.1 - 1e-9 and v1 - v0 <= 20.0 * (t1 - t0) + 1e-9


def test_a_new_decision_ends_a_ramp() -> None:
    """Ramping the feed back up, a rule asks for 40 % within the interval: the request is
    rate limited, and the ramp toward 100 % ends instead of going on."""
    flt = SafetyFilter(ON)
    flt.check(decision("feed_override", 50.0), 0.0, {"feed_override_pct": 100.0})
    flt.check(decision("feed_override", 100.0), 0.2)
    assert flt.pending() == {"feed_override_pct": 100.0}
    assert flt.check(decision("feed_override", 40.0), 0.25).outcome == "rate_limited"
    assert flt.pending() == {} and flt.follow_up(0.5) == []
    assert flt.check(decision("feed_override", 40.0), 0.5).value == 40.0


def test_spindle_is_rate_limited_both_ways_from_the_readback() -> None:
    flt = SafetyFilter(ON)  # 10 %/s both ways; first reference: the read-back
    verdict = flt.check(decision("spindle_override", 80.0), 0.0, {"spindle_override_pct": 100.0})
    assert verdict.value == pytest.approx(99.0)  # 10 %/s over min_interval_s = 0.1 s


def test_duplicates_and_min_interval() -> None:
    flt = SafetyFilter(ON)
    assert flt.check(decision("feed_override", 60.0), 0.0).outcome == "sent"
    assert flt.check(decision("feed_override", 60.0), 0.05).outcome == "duplicate"
    assert flt.check(decision("feed_override", 55.0), 0.05).outcome == "rate_limited"
    # after the interval: duplicate while the machine shows it, sent again when it does not
    assert (
        flt.check(decision("feed_override", 60.0), 0.5, {"feed_override_pct": 60.2}).outcome
        == "duplicate"
    )
    assert (
        flt.check(decision("feed_override", 60.0), 0.6, {"feed_override_pct": 100.0}).outcome
        == "sent"
    )


def test_stop_passes_at_once_and_is_never_released() -> None:
    flt = SafetyFilter(ON)
    flt.check(decision("feed_override", 60.0), 0.0)
    stop = flt.check(decision("stop", 1.0), 0.001)  # within the override's interval
    assert (stop.outcome, stop.command, stop.value) == ("sent", "stop", 1.0)
    assert flt.check(decision("stop", 1.0), 0.002).outcome == "duplicate"
    assert flt.check(decision("stop", 0.0), 5.0).note == "the twin never releases a stop"
    # operator reset the stop; the rule fires again: it passes
    assert flt.check(decision("stop", 1.0), 6.0, {"stop": 0.0}).outcome == "sent"
    assert flt.check(decision("feed_override", math.nan), 7.0).outcome == "blocked"


@settings(max_examples=12, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    min_interval_s=st.floats(0.01, 0.5),
    max_commands_per_s=st.floats(1.0, 200.0),
    feed_min=st.floats(0.0, 100.0),
    feed_span=st.floats(0.0, 50.0),
)
def test_a_flood_of_commands_is_bounded(
    seed: int,
    min_interval_s: float,
    max_commands_per_s: float,
    feed_min: float,
    feed_span: float,
) -> None:
    """10,000 random decisions in 1 s of simulated time: at most 1 + 1/min_interval_s per
    override target and max_commands_per_s * 2 overrides in all reach the machine, each inside
    its bounds and its rate limit; stops pass once."""
    config = ControlConfig(
        enabled=True,
        min_interval_s=min_interval_s,
        max_commands_per_s=max_commands_per_s,
        feed_override=OverrideLimits(
            min_pct=feed_min, max_pct=feed_min + feed_span, max_rise_pct_per_s=20.0
        ),
    )
    flt = SafetyFilter(config)
    rng = np.random.default_rng(seed)
    times = np.sort(rng.uniform(0.0, 1.0, 10_000))
    actions = rng.choice(
        ["feed_override", "spindle_override", "stop", "notify"], 10_000, p=[0.45, 0.45, 0.05, 0.05]
    )
    values = rng.uniform(-1e3, 1e3, 10_000)
    readback = {"feed_override_pct": 100.0, "spindle_override_pct": 100.0}
    sent: dict[str, list[tuple[float, float]]] = {}
    for t, action, value in zip(times, actions, values, strict=True):
        for verdict in [
            flt.check(decision(str(action), float(value), t), t, readback),
            *flt.follow_up(t),
        ]:
            if verdict.send:
                sent.setdefault(str(verdict.command), []).append((t, float(verdict.value)))
    per_target = 1 + math.floor(1.0 / min_interval_s + 1e-6)
    overrides = 0
    for name, limits in (
        ("feed_override_pct", config.feed_override),
        ("spindle_override_pct", config.spindle_override),
    ):
        writes = sent.get(name, [])
        overrides += len(writes)
        assert len(writes) <= per_target
        for _, value in writes:
            assert limits.min_pct <= value <= limits.max_pct
        for (t0, v0), (t1, v1) in zip(writes, writes[1:], strict=False):
            assert t1 - t0 >= min_interval_s - 1e-9
            if limits.max_rise_pct_per_s is not None:
                assert v1 - v0 <= limits.max_rise_pct_per_s * (t1 - t0) + 1e-9
            if limits.max_fall_pct_per_s is not None:
                assert v0 - v1 <= limits.max_fall_pct_per_s * (t1 - t0) + 1e-9
    assert overrides <= max_commands_per_s * 2 + 1e-9
    assert len(sent.get("stop", [])) <= 1  # later stops are duplicates (the machine stopped)


# -- the lost machine ------------------------------------------------------------------


def test_policy_keeps_a_lowered_feed_and_caps_a_raised_one() -> None:
    policy = LostMachinePolicy()
    lowered = {"feed_override_pct": Commanded(50.0, 1.0, confirmed=True)}
    # restarted control back at 100 %: the twin's 50 % is written again
    (action,) = policy.plan(lowered, {"feed_override_pct": 100.0})
    assert (action.command, action.value) == ("feed_override_pct", 50.0)
    assert "stays lowered" in action.reason
    # an operator went lower still: left alone; and the twin never raises it
    assert policy.plan(lowered, {"feed_override_pct": 30.0}) == []
    assert policy.plan(lowered, {"feed_override_pct": 50.2}) == []
    # unknown read-back: written again (the safe side)
    assert policy.plan(lowered, {})[0].value == 50.0
    raised = {"feed_override_pct": Commanded(120.0, 1.0, confirmed=True)}
    (cap,) = policy.plan(raised, {"feed_override_pct": 120.0})
    assert cap.value == 100.0 and "capped at 100 %" in cap.reason


def test_policy_keeps_stop_and_feed_hold_and_respects_the_operator() -> None:
    policy = LostMachinePolicy()
    unconfirmed = {"stop": Commanded(1.0, 1.0, confirmed=False)}
    (again,) = policy.plan(unconfirmed, {"stop": 0.0})
    assert (again.command, again.value) == ("stop", 1.0)
    assert policy.plan(unconfirmed, {"stop": 1.0}) == []  # still stopped: nothing to do
    confirmed = {"feed_hold": Commanded(1.0, 1.0, confirmed=True)}
    (note,) = policy.plan(confirmed, {"feed_hold": 0.0})
    assert note.value is None and "left to the operator" in note.reason
    assert policy.plan({"feed_hold": Commanded(0.0, 1.0)}, {"feed_hold": 1.0}) == []
    spindle = {"spindle_override_pct": Commanded(90.0, 1.0, confirmed=True)}
    (left,) = policy.plan(spindle, {"spindle_override_pct": 100.0})
    assert left.value is None


@pytest.mark.parametrize("mode", ["feed_hold", "stop"])
def test_policy_blind_gap_modes(mode: str) -> None:
    actions = LostMachinePolicy(on_reconnect=mode).plan({}, {})
    assert [(a.command, a.value) for a in actions] == [(mode, 1.0)]


def test_after_reconnect_through_the_filter() -> None:
    """The twin lowered the feed to 50 % and set a feed hold, the machine's control restarted
    (100 %, no hold): both are written again, and the rate limit restarts from the read-back."""
    flt = SafetyFilter(ON)
    flt.check(decision("feed_override", 50.0), 0.0, {"feed_override_pct": 100.0})
    flt.check(decision("feed_hold", 1.0), 0.0)
    flt.observe({"feed_override_pct": 50.0})  # confirmed; the hold never was
    assert flt.commanded["feed_override_pct"].confirmed
    assert not flt.commanded["feed_hold"].confirmed
    verdicts = flt.after_reconnect({"feed_override_pct": 100.0, "feed_hold": 0.0}, 3.0)
    assert [(v.command, v.value, v.outcome) for v in verdicts] == [
        ("feed_hold", 1.0, "sent"),
        ("feed_override_pct", 50.0, "sent"),
    ]
    assert all(v.decision.rule == "reconnect" for v in verdicts)
    assert SafetyFilter(ControlConfig()).after_reconnect({}, 0.0) == []


def test_after_reconnect_rebases_on_the_machine() -> None:
    flt = SafetyFilter(ON)
    flt.check(decision("spindle_override", 90.0), 0.0, {"spindle_override_pct": 90.0})
    (note,) = flt.after_reconnect({"spindle_override_pct": 100.0}, 5.0)
    assert note.outcome == "recorded" and not note.send
    assert flt.commanded["spindle_override_pct"].value == 100.0  # rate limit from here
    verdict = flt.check(decision("spindle_override", 90.0, 5.2), 5.2)
    assert verdict.value == pytest.approx(98.0)  # 10 %/s x 0.2 s from the machine's 100 %


def test_escalation_to_a_command_that_does_not_latch_is_an_input_error() -> None:
    with pytest.raises(InputError, match="escalation to 'feed_override'; valid: stop"):
        SafetyFilter(ON).escalate("feed_override", 0.0, "test")


def test_a_tool_change_request_is_recorded_and_writes_nothing() -> None:
    # enabled or not, a tool-change request is a record: no machine command carries it, and
    # after a lost connection nothing is re-asserted for it
    for config in (ControlConfig(), ON):
        flt = SafetyFilter(config)
        verdict = flt.check(decision("tool_change", None), 0.0)
        assert (verdict.outcome, verdict.command, verdict.send) == ("recorded", None, False)
        assert verdict.note == "tool change requested"
        assert flt.commanded == {}
        assert flt.after_reconnect({"feed_override_pct": 100.0, "stop": 0.0}, 1.0) == []
