"""One run of the twin against one machine: connect, build, record, cycle, summarize."""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from cnctwin.errors import CnctwinError
from cnctwin.store import Historian
from cnctwin.thread import ConnectionConfig, ConnectionLost, MachineConnection
from cnctwin.twin.config import RunConfig
from cnctwin.twin.model_stage import load_models, model_meta
from cnctwin.twin.pipeline import Twin, build_twin
from cnctwin.twin.priority import check_cycle_priority, cycle_priority
from cnctwin.twin.recorder import Recorder
from cnctwin.twin.runtime import RunSummary
from cnctwin.twin.state import CycleState

if TYPE_CHECKING:  # paho-mqtt loads only with an enabled [mqtt]
    from cnctwin.thread import MqttPublisher, MqttSource

__all__ = ["MqttLink", "open_connection", "run_session"]

logger = logging.getLogger(__name__)


def open_connection(config: ConnectionConfig, base_dir: Path | None = None) -> MachineConnection:
    """The client of ``[connection]``: OPC UA, Modbus TCP, MTConnect, ADS or LinuxCNC (not yet
    connected).

    Parameters
    ----------
    config
        The table.
    base_dir
        Folder of the configuration file (relative certificate and symbol map paths).
    """
    if config.transport == "modbus":
        from cnctwin.thread import ModbusConnection

        return ModbusConnection(config)
    if config.transport == "mtconnect":
        from cnctwin.thread import MTConnectConnection

        return MTConnectConnection(config)
    if config.transport == "ads":
        from cnctwin.thread import AdsConnection

        return AdsConnection(config, base_dir=base_dir)
    if config.transport == "linuxcnc":
        from cnctwin.thread import LinuxCncConnection

        return LinuxCncConnection(config)
    from cnctwin.thread import OpcUaConnection

    return OpcUaConnection(config, base_dir=base_dir)


async def run_session(
    config: RunConfig,
    *,
    connection: MachineConnection | None = None,
    historian: Historian | None = None,
    duration_s: float | None = None,
    stop_event: asyncio.Event | None = None,
    on_cycle: Callable[[CycleState], None] | None = None,
    on_start: Callable[[Twin], None] | None = None,
    meta: Mapping[str, object] | None = None,
    base_dir: Path | None = None,
    realtime: bool = True,
    connect_timeout_s: float = 10.0,
) -> RunSummary:
    """Connect to the machine, run the twin until the program ends, record the run.

    Parameters
    ----------
    config
        The whole configuration.
    connection
        The machine; ``None`` opens ``[connection]``. It is closed at the end.
    historian
        Where to record; ``None`` records nothing.
    duration_s
        Longest run, s.
    stop_event
        Set to end the run (Ctrl-C).
    on_cycle
        Called with each cycle's state (the live view).
    on_start
        Called with the built twin once connected, before the first cycle.
    meta
        Extra description of the run for the historian.
    base_dir
        Folder of the configuration file.
    realtime
        Keep the cycle period.
    connect_timeout_s
        How long to keep trying to reach the machine at the start, s.

    Raises
    ------
    CnctwinError
        If the machine cannot be reached within ``connect_timeout_s``.
    cnctwin.errors.ConfigError
        Before connecting, for a ``[[twin.models]]`` entry the twin cannot feed or a
        ``[twin] realtime_priority`` the system refuses.
    """
    models = load_models(config.twin)  # a model the twin cannot feed is refused before connecting
    check_cycle_priority(config.twin.realtime_priority)  # so is a priority the system refuses
    conn = connection if connection is not None else open_connection(config.connection, base_dir)
    endpoint = getattr(conn, "endpoint", config.connection.endpoint)
    await _connect(conn, endpoint, connect_timeout_s, stop_event)
    try:
        program = config.twin.program
        if program is None and config.virtual is not None:
            program = config.virtual.program
        t0 = time.monotonic()
        recorder = None
        if historian is not None:
            recorder = Recorder(
                historian,
                {
                    "endpoint": endpoint,
                    "transport": config.connection.transport,
                    "program": str(program) if program is not None else None,
                    "cycle_s": config.twin.cycle_s,
                    "control_enabled": config.control.enabled,
                    "models": model_meta(config.twin.models),
                    **dict(meta or {}),
                },
                t0,
            )
        with MqttLink(config, endpoint) as link:
            twin = build_twin(
                config,
                conn,
                recorder=recorder,
                program=program,
                realtime=realtime,
                mqtt_source=link.source,
                mqtt_publisher=link.publisher,
                t0_s=t0,
                models=models,
            )
            twin.runtime.on_cycle = on_cycle
            twin.runtime.prepare()
            if on_start is not None:
                on_start(twin)
            with cycle_priority(config.twin.realtime_priority):
                summary = await twin.runtime.run(duration_s=duration_s, stop_event=stop_event)
        # the counts after the publisher's final flush (the historian has those before it)
        summary.outlets = {outlet.name: outlet.stats() for outlet in twin.runtime.outlets}
        return summary
    finally:
        await conn.close()


class MqttLink:
    """The MQTT publisher and sensor source of an enabled ``[mqtt]`` (docs/mqtt.md), started
    on entry (they connect in the background) and stopped on exit (the publisher first
    flushes what the broker has not acknowledged, for up to 2 s).

    Parameters
    ----------
    config
        The whole configuration.
    endpoint
        The machine's endpoint, for the retained status message.

    Attributes
    ----------
    publisher, source
        ``None`` when ``[mqtt]`` is off, publishing is off, or there are no signals.
    """

    def __init__(self, config: RunConfig, endpoint: str) -> None:
        self.config = config.mqtt
        self.endpoint = endpoint
        self.publisher: MqttPublisher | None = None
        self.source: MqttSource | None = None

    def __enter__(self) -> MqttLink:
        mqtt = self.config
        if not mqtt.enabled:
            return self
        from cnctwin.thread import MqttPublisher, MqttSource
        from cnctwin.twin.mqtt import SCHEMAS

        try:
            if mqtt.publish.enabled:
                status = {"schema": SCHEMAS["status"], "machine": self.endpoint}
                self.publisher = MqttPublisher(mqtt, status=status)
                self.publisher.start()
            if mqtt.signals:
                self.source = MqttSource(mqtt)
                self.source.start()
        except BaseException:
            self.__exit__(None, None, None)
            raise
        logger.info("MQTT: %s (publish: %s)", mqtt.broker, self.publisher is not None)
        return self

    def __exit__(self, *exc: object) -> None:
        if self.source is not None:
            self.source.stop()
        if self.publisher is not None:
            self.publisher.stop()


async def _connect(
    conn: MachineConnection, endpoint: str, timeout_s: float, stop_event: asyncio.Event | None
) -> None:
    deadline = time.monotonic() + timeout_s
    attempt = 0
    while True:
        if stop_event is not None and stop_event.is_set():
            raise KeyboardInterrupt  # Ctrl-C before the machine answered
        try:
            await conn.connect()
            return
        except ConnectionLost as err:
            if time.monotonic() >= deadline:
                raise CnctwinError(
                    f"cannot reach the machine at {endpoint} within {timeout_s:g} s: {err}; "
                    "check [connection] endpoint and that the machine's server runs"
                ) from None
            await asyncio.sleep(conn.backoff.delay_s(attempt))
            attempt += 1
