"""Rules from TOML and the rule engine: hold durations, cooldowns, values, reasons, ordering."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from pydantic import Field

from cnctwin.config import load_config
from cnctwin.config.machining import MachiningConfig
from cnctwin.control import ControlConfig, Decision, RuleConfig, RuleEngine
from cnctwin.errors import ConfigError

CYCLE_S = 0.0125
NAMES = {
    "force_resultant_n",
    "force_band_low_n",
    "feed_mm_min",
    "form_error_um",
    "feed_override_pct",
    "spindle_override_pct",
}


class RulesFile(MachiningConfig):
    """A twin file with the two tables of this package (what RunConfig composes)."""

    rules: list[RuleConfig] = Field(default_factory=list)
    control: ControlConfig = Field(default_factory=ControlConfig)


EXAMPLE = """
[control]
enabled = true
[control.feed_override]
min_pct = 30
max_pct = 100
max_rise_pct_per_s = 10

[[rules]]
name = "hole_in_blank"
condition = "force_resultant_n < force_band_low_n and feed_mm_min > 10"
for_s = 0.025
action = "stop"
reason = "force {force_resultant_n:.0f} N below band {force_band_low_n:.0f} N"

[[rules]]
name = "form_error"
condition = "form_error_um > 40"
action = "feed_override"
step = -10
cooldown_s = 0.5
"""


def rule(**kwargs) -> RuleConfig:
    return RuleConfig.model_validate(
        {"name": "r", "condition": "form_error_um > 40", "action": "notify", **kwargs}
    )


def run(engine: RuleEngine, frames: list[dict], t0: float = 0.0) -> list[Decision]:
    out = []
    for i, values in enumerate(frames):
        out += engine.evaluate(values, t0 + i * CYCLE_S)
    return out


def test_example_file_loads(tmp_path: Path) -> None:
    path = tmp_path / "twin.toml"
    path.write_text(EXAMPLE)
    config = load_config(path, model=RulesFile)
    assert [r.name for r in config.rules] == ["hole_in_blank", "form_error"]
    assert config.control.enabled and config.control.feed_override.min_pct == 30
    assert config.control.spindle_override.max_pct == 110  # default kept
    RuleEngine(config.rules, NAMES)


@pytest.mark.parametrize(
    ("table", "match"),
    [
        ('action = "feed_override"', "needs exactly one of 'value'"),
        ('action = "feed_override"\nvalue = 50\nstep = -10', "needs exactly one of 'value'"),
        ('action = "stop"\nvalue = 1', "takes no 'value'"),
        ('action = "tool_change"\nvalue = 1', "action 'tool_change' takes no 'value'"),
        ('action = "notify"\nstep = 5', "'step' applies to overrides only"),
        ('action = "feed_hold"\nvalue = 3', "give 1 \\(hold\\) or 0 \\(release\\)"),
        ('action = "explode"', r"rules\[0\].action: must be .stop."),
        ('action = "stop"\nfor_s = -1', r"rules\[0\].for_s"),
        ('action = "stop"\nwhen = 3', "when"),
        ('action = "feed_override"\nvalue = "feed_override_pct ** 2"', "Pow"),
    ],
)
def test_bad_rules_are_one_line_config_errors(tmp_path: Path, table: str, match: str) -> None:
    path = tmp_path / "twin.toml"
    path.write_text(f'[[rules]]\nname = "x"\ncondition = "form_error_um > 40"\n{table}\n')
    with pytest.raises(ConfigError, match=match) as err:
        load_config(path, model=RulesFile)
    assert "\n" not in str(err.value) and str(path) in str(err.value)


def test_control_bounds_outside_machine_range_are_rejected(tmp_path: Path) -> None:
    path = tmp_path / "twin.toml"
    path.write_text("[control.spindle_override]\nmin_pct = 40\nmax_pct = 100\n")
    with pytest.raises(ConfigError, match="give 50 <= min_pct <= max_pct <= 120"):
        load_config(path, model=RulesFile)
    path.write_text("[control.feed_override]\nmin_pct = 90\nmax_pct = 80\n")
    with pytest.raises(ConfigError, match="give 0 <= min_pct"):
        load_config(path, model=RulesFile)


def test_unknown_name_in_condition_names_the_rule() -> None:
    with pytest.raises(ConfigError, match=r"rule 'r' condition 'form_eror_um > 40' uses unknown"):
        RuleEngine([rule(condition="form_eror_um > 40")], NAMES)
    with pytest.raises(ConfigError, match="rule 'r' reason .* unknown field"):
        RuleEngine([rule(reason="error {form_error_mm}")], NAMES)
    with pytest.raises(ConfigError, match="'r' appear more than once"):
        RuleEngine([rule(), rule()], NAMES)
    with pytest.raises(ConfigError, match="relative to 'feed_override_pct'"):
        RuleEngine([rule(action="feed_override", step=-5)], NAMES - {"feed_override_pct"})


def test_condition_must_hold_for_its_duration() -> None:
    """for_s = 0.025 s at a 12.5 ms cycle: fires on the third consecutive true cycle; a false
    cycle restarts the timer."""
    engine = RuleEngine([rule(for_s=0.025, action="stop", cooldown_s=10)], NAMES)
    hi, lo = {"form_error_um": 50.0}, {"form_error_um": 10.0}
    times = [d.time_s for d in run(engine, [hi, hi, lo, hi, hi, hi, hi])]
    assert times == [pytest.approx(5 * CYCLE_S)]


def test_cooldown_repeats_a_step_until_the_condition_clears() -> None:
    """Use case (b): a form error above 40 um lowers the override by 10 % every 0.5 s."""
    engine = RuleEngine([rule(action="feed_override", step=-10, cooldown_s=0.5)], NAMES)
    override = 100.0
    decisions = []
    t = 0.0
    for _ in range(400):  # 5 s
        error_um = 0.8 * override - 20  # form error falls with the feed: 60 um at 100 %
        new = engine.evaluate({"form_error_um": error_um, "feed_override_pct": override}, t)
        for d in new:
            override = d.value  # the machine applies it
        decisions += new
        t += CYCLE_S
    assert [d.value for d in decisions] == [90.0, 80.0, 70.0]  # 0.8*70-20 = 36 um: inside
    gaps = [b.time_s - a.time_s for a, b in zip(decisions, decisions[1:], strict=False)]
    assert all(gap >= 0.5 - 1e-9 for gap in gaps)


def test_value_expression_and_reason_carry_the_causing_values() -> None:
    engine = RuleEngine(
        [
            rule(
                name="halve",
                action="feed_override",
                value="feed_override_pct * 0.5",
                reason="{rule}: form error {form_error_um:.1f} um -> {value:g} %",
            ),
            rule(name="plain", condition="force_resultant_n < force_band_low_n"),
        ],
        NAMES,
    )
    values = {
        "form_error_um": 52.34,
        "feed_override_pct": 90.0,
        "force_resultant_n": 10.0,
        "force_band_low_n": 120.0,
        "feed_mm_min": 600.0,
    }
    halve, plain = engine.evaluate(values, 1.0)
    assert (halve.rule, halve.action, halve.value, halve.command) == (
        "halve",
        "feed_override",
        45.0,
        "feed_override_pct",
    )
    assert halve.reason == "halve: form error 52.3 um -> 45 %"
    assert halve.values == {"form_error_um": 52.34, "feed_override_pct": 90.0}
    assert plain.value is None and plain.command is None
    assert plain.reason == (
        "force_resultant_n < force_band_low_n held 0.000 s "
        "(force_resultant_n=10, force_band_low_n=120)"
    )


def test_missing_or_garbage_values_never_fire() -> None:
    engine = RuleEngine([rule(action="stop", for_s=0.02)], NAMES)
    frames = [
        {"form_error_um": 50.0},
        {"form_error_um": math.nan},
        {},
        {"form_error_um": 50.0},
        {"form_error_um": math.inf},
    ]
    assert run(engine, frames) == []
    stepper = RuleEngine([rule(action="feed_override", step=-10)], NAMES)
    assert stepper.evaluate({"form_error_um": 50.0}, 0.0) == []  # no override reading
    assert stepper.skipped == {"r": 1}
    divider = RuleEngine([rule(condition="feed_mm_min / form_error_um > 1")], NAMES)
    assert divider.evaluate({"feed_mm_min": 5.0, "form_error_um": 0.0}, 0.0) == []


def test_decisions_come_most_conservative_first() -> None:
    engine = RuleEngine(
        [
            rule(name="note", condition="form_error_um > 0"),
            rule(name="change", action="tool_change", condition="form_error_um > 0"),
            rule(name="fast", action="feed_override", value=90, condition="form_error_um > 0"),
            rule(name="slow", action="feed_override", value=50, condition="form_error_um > 0"),
            rule(name="spin", action="spindle_override", value=95, condition="form_error_um > 0"),
            rule(name="release", action="feed_hold", value=0, condition="form_error_um > 0"),
            rule(name="hold", action="feed_hold", condition="form_error_um > 0"),
            rule(name="halt", action="stop", condition="form_error_um > 0"),
        ],
        NAMES,
    )
    order = [d.rule for d in engine.evaluate({"form_error_um": 1.0}, 0.0)]
    assert order == ["halt", "hold", "release", "slow", "fast", "spin", "change", "note"]


def test_reset_forgets_hold_timers() -> None:
    engine = RuleEngine([rule(for_s=0.03, action="stop")], NAMES)
    run(engine, [{"form_error_um": 50.0}] * 2)
    engine.reset()
    assert engine.evaluate({"form_error_um": 50.0}, 2 * CYCLE_S) == []
