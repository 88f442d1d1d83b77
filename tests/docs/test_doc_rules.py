"""The rules shown in docs/control.md are rules the twin builds: every name they use is one the
twin provides (the check ``cnctwin run`` makes before its first cycle, with the demo's filters,
windows and models)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from cnctwin.control import RuleEngine
from cnctwin.errors import ConfigError
from cnctwin.examples import example_file
from cnctwin.twin.config import load_run_config
from cnctwin.twin.pipeline import signal_names

REPO = Path(__file__).resolve().parents[2]
RULES = re.compile(r"(?ms)^\[\[rules\]\].*?(?=^\[(?!\[rules)|\Z)")


def _engine(rules_toml: str, tmp_path: Path) -> RuleEngine:
    """The rule engine of the demo's twin configuration with ``rules_toml`` as its rules."""
    demo = Path(str(example_file("demo_twin.toml")))
    config = tmp_path / "twin.toml"
    config.write_text(RULES.sub("", demo.read_text("utf-8")) + "\n" + rules_toml, "utf-8")
    (tmp_path / "demo_twin.ngc").write_text(
        Path(str(example_file("demo_twin.ngc"))).read_text("utf-8"), "utf-8"
    )
    run = load_run_config(config)
    return RuleEngine(run.rules, valid_names=signal_names(run))


def test_the_rules_of_control_md_are_accepted(tmp_path: Path) -> None:
    page = (REPO / "docs" / "control.md").read_text("utf-8")
    block = re.search(r"```toml\n(\[\[rules\]\].*?)```", page, re.S)
    assert block is not None
    assert block[1].count("[[rules]]") >= 4
    _engine(block[1], tmp_path)


def test_a_rule_on_a_name_the_twin_does_not_provide_is_refused(tmp_path: Path) -> None:
    rule = '[[rules]]\nname = "r"\ncondition = "chatter_amplitude_um > 5"\naction = "notify"\n'
    with pytest.raises(ConfigError, match="unknown name.*chatter_amplitude_um"):
        _engine(rule, tmp_path)
