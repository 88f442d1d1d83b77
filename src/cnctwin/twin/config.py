"""The running twin's configuration file: machining, connection, machine, historian, rules.

One TOML file holds everything ``cnctwin run`` needs. :class:`RunConfig` is the machining
root :class:`~cnctwin.config.MachiningConfig` (``[machine]``, ``[[tools]]``, ``[stock]``,
``[material]``, ``[simulation]``) plus the tables each runtime package owns:

- ``[connection]`` (:class:`cnctwin.thread.config.ConnectionConfig`): how to reach the machine;
- ``[virtual]`` (:class:`cnctwin.virtual.config.VirtualMachineConfig`, optional): the
  simulated machine ``cnctwin demo`` starts;
- ``[historian]`` (:class:`cnctwin.store.config.HistorianConfig`): where runs are recorded;
- ``[[rules]]`` and ``[control]`` (:mod:`cnctwin.control.config`): what the twin decides and
  whether it may command the machine;
- ``[twin]`` (:class:`cnctwin.twin.settings.TwinSettings`): cycle time, filters, windows and
  the monitoring models;
- ``[mqtt]`` (:class:`cnctwin.thread.MqttConfig`, off by default): the broker the twin
  publishes to and the external sensor signals it takes in (docs/mqtt.md).

Load it with ``cnctwin.config.load_config(path, model=RunConfig)`` or :func:`load_run_config`.
"""

from __future__ import annotations

import os

from pydantic import Field, field_validator
from pydantic_core import PydanticCustomError

from cnctwin.config import MachiningConfig, load_config
from cnctwin.control import ControlConfig, RuleConfig
from cnctwin.store import HistorianConfig
from cnctwin.thread import ConnectionConfig, MqttConfig
from cnctwin.twin.settings import TwinSettings
from cnctwin.virtual import VirtualMachineConfig

__all__ = ["RunConfig", "load_run_config"]


class RunConfig(MachiningConfig):
    """A running twin's whole configuration (see the module notes for the tables).

    Attributes
    ----------
    connection
        The machine's address and protocol.
    virtual
        The virtual machine to start (``cnctwin demo``); ``None`` for a real machine.
    historian
        Where the run is recorded.
    rules
        Rules, evaluated every cycle in order.
    control
        Whether commands reach the machine, and their bounds.
    twin
        The runtime.
    mqtt
        The MQTT link (publish and sensor input only).
    """

    connection: ConnectionConfig = Field(default_factory=ConnectionConfig)
    virtual: VirtualMachineConfig | None = None
    historian: HistorianConfig = Field(default_factory=HistorianConfig)
    rules: list[RuleConfig] = Field(default_factory=list)
    control: ControlConfig = Field(default_factory=ControlConfig)
    twin: TwinSettings = Field(default_factory=TwinSettings)
    mqtt: MqttConfig = Field(default_factory=MqttConfig)

    @classmethod
    def from_machining(cls, machining: MachiningConfig, **tables: object) -> RunConfig:
        """A run configuration of a machining configuration and the runtime's tables.

        Parameters
        ----------
        machining
            Machine, tools, stock, material, simulation.
        **tables
            ``connection``, ``virtual``, ``historian``, ``rules``, ``control``, ``twin``,
            ``mqtt`` as
            models or as the dictionaries their TOML tables would give.
        """
        data: dict[str, object] = {
            name: getattr(machining, name) for name in MachiningConfig.model_fields
        }
        data.update(tables)
        return cls.model_validate(data)

    @field_validator("rules")
    @classmethod
    def _unique_rule_names(cls, rules: list[RuleConfig]) -> list[RuleConfig]:
        seen: dict[str, int] = {}
        for index, rule in enumerate(rules):
            if rule.name in seen:
                raise PydanticCustomError(
                    "duplicate_rule",
                    "rule name '{name}' is given twice, in rules[{a}] and rules[{b}]",
                    {"name": rule.name, "a": seen[rule.name], "b": index},
                )
            seen[rule.name] = index
        return rules


def load_run_config(path: str | os.PathLike[str]) -> RunConfig:
    """Read and validate a twin configuration file.

    Raises
    ------
    cnctwin.errors.ConfigError
        One line naming the file, the key and what would be valid.
    """
    return load_config(path, model=RunConfig)
