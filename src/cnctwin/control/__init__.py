"""Decisions for the machine: rules from the twin's TOML and the safety filter of every command.

Control is off unless ``[control] enabled = true``; every decision is recorded with its rule and
the values that caused it, whether it reached the machine or not (see docs/control.md).
"""

from cnctwin.control.config import (
    ACTION_COMMANDS,
    ControlConfig,
    OffsetLimits,
    OverrideLimits,
    RuleAction,
    RuleConfig,
)
from cnctwin.control.expression import Expression
from cnctwin.control.rules import Decision, RuleEngine
from cnctwin.control.safety import (
    OFFSET_COMMANDS,
    Commanded,
    LostMachinePolicy,
    Outcome,
    ReconnectAction,
    SafetyFilter,
    Verdict,
)

__all__ = [
    "ACTION_COMMANDS",
    "Commanded",
    "ControlConfig",
    "Decision",
    "Expression",
    "LostMachinePolicy",
    "OFFSET_COMMANDS",
    "OffsetLimits",
    "Outcome",
    "OverrideLimits",
    "ReconnectAction",
    "RuleAction",
    "RuleConfig",
    "RuleEngine",
    "SafetyFilter",
    "Verdict",
]
