"""Assembling the twin: the stages of a :class:`~cnctwin.twin.config.RunConfig`, in cycle order."""

from __future__ import annotations

import asyncio
import os
import time
from collections.abc import Awaitable, Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from cnctwin.control import Expression, RuleEngine, SafetyFilter
from cnctwin.thread import SIGNALS, MachineConnection
from cnctwin.twin.actions import ActionStage, RuleStage
from cnctwin.twin.adaptive_feed import AdaptiveFeedStage, program_engagement_map
from cnctwin.twin.chatter_live import ChatterRequest, chatter_stage
from cnctwin.twin.config import RunConfig
from cnctwin.twin.mirs import MirsStage
from cnctwin.twin.model_stage import LoadedModel, ModelStage, load_models
from cnctwin.twin.monitoring import ForceBand
from cnctwin.twin.mqtt import MqttOutlet, MqttSignalStage
from cnctwin.twin.physics import TwinPhysics
from cnctwin.twin.program import ProgramMap
from cnctwin.twin.recorder import Recorder
from cnctwin.twin.roughness import ROUGHNESS_PREDICTIONS, RoughnessStage
from cnctwin.twin.runtime import TwinRuntime
from cnctwin.twin.stages import (
    PREDICTIONS,
    CutStage,
    EngagementStage,
    FeatureStage,
    FilterStage,
    ForceBandStage,
    ForceStage,
    FormErrorStage,
    KinematicsStage,
    ReadStage,
    Stage,
)
from cnctwin.twin.tool_wear import WearStage

if TYPE_CHECKING:  # paho-mqtt loads only with an enabled [mqtt]
    from cnctwin.thread import MqttPublisher, MqttSource

__all__ = ["SHED_ORDER", "Twin", "build_twin", "shed_order", "signal_names"]

#: The optional work of the cycle, first shed first when the twin is overloaded
#: (docs/twin.md, "Overload"): the historian's per-cycle detail, the windowed features, the
#: form-error and roughness predictions. The reading, kinematics, cut, engagement, forces, filters,
#: force band, rules and actions (the chain that decides a stop) are never shed.
SHED_ORDER = ("historian_detail", "features", "form_error", "roughness")

#: What each optional stage adds that a rule could read (features: by configuration).
_FORM_ERROR_NAMES = ("deflection_um", "form_error_um", "form_error_tolerance_um", "form_error_out")


def signal_names(config: RunConfig) -> list[str]:
    """Every name a rule may read with this configuration: signals, filtered signals,
    features and predictions."""
    names = list(SIGNALS)
    if config.mqtt.enabled:
        names += [s.signal for s in config.mqtt.signals if s.signal not in SIGNALS]
    names += [f"filtered_{name}" for name in config.twin.filters]
    names += [f"{w.signal}_{f}" for w in config.twin.windows for f in w.features]
    names += list(PREDICTIONS)
    return names


def shed_order(config: RunConfig) -> tuple[str, ...]:
    """The stages of :data:`SHED_ORDER` this configuration may shed, in order.

    A stage whose output a protective rule (``stop`` or ``feed_hold``) reads is not
    optional: it is kept whatever the load. The roughness stage is shed only where it runs
    (``[twin.roughness] enabled``).
    """
    protective: set[str] = set()
    for rule in config.rules:
        if rule.action in ("stop", "feed_hold"):
            protective.update(Expression(rule.condition, logical=True).names)
            if isinstance(rule.value, str):
                protective.update(Expression(rule.value).names)
    outputs = {
        "historian_detail": (),
        "features": tuple(f"{w.signal}_{f}" for w in config.twin.windows for f in w.features),
        "form_error": _FORM_ERROR_NAMES,
        "roughness": ROUGHNESS_PREDICTIONS,
    }
    running = [name for name in SHED_ORDER if name != "roughness" or config.twin.roughness.enabled]
    return tuple(name for name in running if not protective.intersection(outputs[name]))


@dataclass
class Twin:
    """A twin ready to run: its runtime and the parts tests look into.

    Attributes
    ----------
    runtime
        The cycle.
    physics
        The twin's stock, tools and material.
    actions
        The action stage (decisions, writes, read-backs, stop reactions).
    safety
        The safety filter.
    models
        The learned models of ``[[twin.models]]``, loaded and checked.
    """

    runtime: TwinRuntime
    physics: TwinPhysics
    actions: ActionStage
    safety: SafetyFilter
    models: tuple[LoadedModel, ...] = ()


def build_twin(
    config: RunConfig,
    connection: MachineConnection,
    *,
    recorder: Recorder | None = None,
    program: str | os.PathLike[str] | None = None,
    program_text: str | None = None,
    realtime: bool = True,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], Awaitable[None]] = asyncio.sleep,
    mqtt_source: MqttSource | None = None,
    mqtt_publisher: MqttPublisher | None = None,
    t0_s: float | None = None,
    models: Sequence[LoadedModel] | None = None,
) -> Twin:
    """The twin cycle's stages (docs/twin.md) for ``config``, reading and writing ``connection``.

    Parameters
    ----------
    config
        The whole configuration.
    connection
        The machine (connected by the caller).
    recorder
        The historian's recorder, or ``None``.
    program, program_text
        The NC program the machine runs (file or text), for the tool offsets per line;
        neither: G43 with the tool's length is assumed.
    realtime
        Keep the cycle period (``False``: back to back, for lockstep tests).
    clock, sleep
        The runtime's clock (s) and wait (s); tests give a fake clock (see
        :class:`~cnctwin.twin.runtime.TwinRuntime`).
    mqtt_source, mqtt_publisher
        The started MQTT sensor source and publisher of ``[mqtt]`` (docs/mqtt.md), or
        ``None``: the source's signals join each sample after the read, the publisher gets
        every cycle after the watchdog.
    t0_s
        ``time.monotonic()`` of the run's start, for the published times (default: now).
    models
        The ``[[twin.models]]`` already loaded (:func:`~cnctwin.twin.model_stage.load_models`);
        ``None`` loads them.

    Raises
    ------
    cnctwin.errors.ConfigError
        For an unknown material, a tool without fluted length, a rule that reads an unknown
        name, a bad filter or window, a model whose features the twin cannot supply.
    cnctwin.errors.NCError
        For an error in the program.
    """
    twin_cfg = config.twin
    cycle_s = twin_cfg.cycle_s
    physics = TwinPhysics(config, density_per_mm=twin_cfg.density_per_mm, default_dt_s=cycle_s)
    physics.warm_up()
    models = load_models(twin_cfg) if models is None else models
    model_outputs = [name for model in models for name in model.outputs]
    valid_names = signal_names(config) + model_outputs
    engine = RuleEngine(config.rules, valid_names=valid_names)
    safety = SafetyFilter(config.control)
    actions = ActionStage(
        connection, safety, recorder, stop_confirmation=twin_cfg.stop_confirmation
    )
    stages: list[Stage] = [ReadStage.from_config(connection, config)]
    if mqtt_source is not None:
        stages.append(MqttSignalStage(mqtt_source, config.mqtt.signals))
    chatter = chatter_stage(config, connection, program) if twin_cfg.chatter.enabled else None
    if chatter is not None:  # its read goes out now; the machine answers meanwhile
        stages.append(ChatterRequest(chatter))
    stages += [
        KinematicsStage(
            ProgramMap(config, program, text=program_text), twin_cfg.position_deadband_mm
        ),
        CutStage(physics, twin_cfg.attach_s),
        EngagementStage(),
        ForceStage(physics),
        FilterStage(twin_cfg.filters, cycle_s),
        FeatureStage(twin_cfg.windows, cycle_s),
    ]
    if twin_cfg.force_band.enabled:
        stages.append(ForceBandStage(ForceBand(twin_cfg.force_band), physics))
    if twin_cfg.form_error.enabled:
        stages.append(FormErrorStage(twin_cfg.form_error, physics))
    if twin_cfg.wear.enabled:
        stages.append(WearStage(twin_cfg.wear, physics))
    stages += [ModelStage(model) for model in models]
    if twin_cfg.roughness.enabled:  # after the models: one may give the vibration
        stages.append(RoughnessStage(twin_cfg.roughness, config.tools, valid_names))
    if chatter is not None:  # before the rules: they may read its predictions
        stages.append(chatter)
    stages.append(RuleStage(engine))
    adaptive = twin_cfg.adaptive_feed
    if adaptive.enabled:  # after the rules: a rule's lower override goes first
        feed = config.control.feed_override
        emap = None
        if adaptive.lookahead_mm > 0.0 and (program is not None or program_text is not None):
            emap = program_engagement_map(
                config, physics.cutters, adaptive.map_step_mm, program, program_text
            )
        stages.append(AdaptiveFeedStage(adaptive, feed.min_pct, feed.max_pct, emap))
    if twin_cfg.mirs.enabled:  # after the rules and the adaptive feed: the lower override wins
        limits = config.control
        stages.append(
            MirsStage(
                twin_cfg.mirs,
                physics.coefficients,
                (limits.feed_override.min_pct, limits.feed_override.max_pct),
                (limits.spindle_override.min_pct, limits.spindle_override.max_pct),
            )
        )
    stages.append(actions)
    outlets: list[MqttOutlet] = []
    if mqtt_source is not None or mqtt_publisher is not None:
        outlets.append(
            MqttOutlet(
                mqtt_publisher,
                mqtt_source,
                telemetry_hz=config.mqtt.publish.telemetry_hz,
                t0_s=time.monotonic() if t0_s is None else t0_s,
            )
        )
    runtime = TwinRuntime(
        stages,
        actions,
        cycle_s=cycle_s,
        watchdog_s=twin_cfg.watchdog_s,
        recorder=recorder,
        realtime=realtime,
        overload=twin_cfg.overload,
        shed_order=shed_order(config),
        clock=clock,
        sleep=sleep,
        outlets=outlets,
    )
    return Twin(runtime, physics, actions, safety, tuple(models))
