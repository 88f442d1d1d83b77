"""The digital thread: one :class:`MachineConnection` interface over industrial protocols.

The transports (:class:`OpcUaConnection`, :class:`ModbusConnection`, :class:`AdsConnection`,
the read-only :class:`MTConnectConnection` and LinuxCNC's :class:`LinuxCncConnection`) load
asyncua, pymodbus and pyads, the MQTT publisher and sensor source (:class:`MqttPublisher`,
:class:`MqttSource`) paho-mqtt;
they are imported on first use so that the signal catalogue and the connection interface stay
light for the modules that only need those.
"""

from typing import TYPE_CHECKING, Any

from cnctwin.thread.connection import (
    Backoff,
    CommandRejected,
    ConnectionLost,
    ConnectionState,
    MachineConnection,
    Reading,
    SampleBlock,
    now_s,
)
from cnctwin.thread.signals import COMMANDS, SIGNALS, RunState, SignalSpec

if TYPE_CHECKING:
    from cnctwin.thread.ads import AdsConnection, default_symbol_map
    from cnctwin.thread.ads_map import Symbol, SymbolMap, load_symbol_map
    from cnctwin.thread.config import ConnectionConfig, OpcUaSecurityConfig
    from cnctwin.thread.latency import (
        JitterProxy,
        LatencyResult,
        LatencyStats,
        measure_endpoint_latency,
        measure_latency,
        measure_read_latency,
    )
    from cnctwin.thread.linuxcnc import LinuxCncConnection
    from cnctwin.thread.modbus import ModbusConnection
    from cnctwin.thread.modbus_map import READ_MAP, STATUS_MAP, WRITE_MAP, RegisterAddress
    from cnctwin.thread.mosquitto import Mosquitto
    from cnctwin.thread.mqtt import (
        LinkEvent,
        MqttPublisher,
        MqttSource,
        SensorValue,
        measure_mqtt_latency,
        parse_sensor_payload,
    )
    from cnctwin.thread.mqtt_config import (
        SENSOR_SIGNALS,
        MqttConfig,
        MqttPublishConfig,
        MqttSignalConfig,
        broker_address,
    )
    from cnctwin.thread.mtconnect import MTConnectConnection, SequenceGap
    from cnctwin.thread.mtconnect_documents import (
        AgentError,
        DataItem,
        Devices,
        Observation,
        ShdrFeed,
        ShdrRecord,
        Streams,
        parse_devices,
        parse_shdr,
        parse_streams,
    )
    from cnctwin.thread.mtconnect_map import RUN_STATE_EXECUTION, UNIT_FACTORS
    from cnctwin.thread.opcua import (
        BLOCK_NODE,
        DEFAULT_SUBSCRIPTION_MS,
        NAMESPACE_URI,
        NODE_MAP,
        OpcUaConnection,
        variant_type,
    )
    from cnctwin.thread.trust import TrustList

# pydantic, asyncio, asyncua, pymodbus and cryptography load with these: imported on first use.
_LAZY = {
    "AdsConnection": "cnctwin.thread.ads",
    "default_symbol_map": "cnctwin.thread.ads",
    "Symbol": "cnctwin.thread.ads_map",
    "SymbolMap": "cnctwin.thread.ads_map",
    "load_symbol_map": "cnctwin.thread.ads_map",
    "ConnectionConfig": "cnctwin.thread.config",
    "OpcUaSecurityConfig": "cnctwin.thread.config",
    "JitterProxy": "cnctwin.thread.latency",
    "LatencyResult": "cnctwin.thread.latency",
    "measure_latency": "cnctwin.thread.latency",
    "measure_read_latency": "cnctwin.thread.latency",
    "DEFAULT_SUBSCRIPTION_MS": "cnctwin.thread.opcua",
    "LatencyStats": "cnctwin.thread.latency",
    "measure_endpoint_latency": "cnctwin.thread.latency",
    "ModbusConnection": "cnctwin.thread.modbus",
    "Mosquitto": "cnctwin.thread.mosquitto",
    "LinkEvent": "cnctwin.thread.mqtt",
    "MqttPublisher": "cnctwin.thread.mqtt",
    "MqttSource": "cnctwin.thread.mqtt",
    "SensorValue": "cnctwin.thread.mqtt",
    "measure_mqtt_latency": "cnctwin.thread.mqtt",
    "parse_sensor_payload": "cnctwin.thread.mqtt",
    "SENSOR_SIGNALS": "cnctwin.thread.mqtt_config",
    "MqttConfig": "cnctwin.thread.mqtt_config",
    "MqttPublishConfig": "cnctwin.thread.mqtt_config",
    "MqttSignalConfig": "cnctwin.thread.mqtt_config",
    "broker_address": "cnctwin.thread.mqtt_config",
    "LinuxCncConnection": "cnctwin.thread.linuxcnc",
    "MTConnectConnection": "cnctwin.thread.mtconnect",
    "SequenceGap": "cnctwin.thread.mtconnect",
    "AgentError": "cnctwin.thread.mtconnect_documents",
    "DataItem": "cnctwin.thread.mtconnect_documents",
    "Devices": "cnctwin.thread.mtconnect_documents",
    "Observation": "cnctwin.thread.mtconnect_documents",
    "ShdrFeed": "cnctwin.thread.mtconnect_documents",
    "ShdrRecord": "cnctwin.thread.mtconnect_documents",
    "Streams": "cnctwin.thread.mtconnect_documents",
    "parse_devices": "cnctwin.thread.mtconnect_documents",
    "parse_shdr": "cnctwin.thread.mtconnect_documents",
    "parse_streams": "cnctwin.thread.mtconnect_documents",
    "RUN_STATE_EXECUTION": "cnctwin.thread.mtconnect_map",
    "UNIT_FACTORS": "cnctwin.thread.mtconnect_map",
    "READ_MAP": "cnctwin.thread.modbus_map",
    "STATUS_MAP": "cnctwin.thread.modbus_map",
    "WRITE_MAP": "cnctwin.thread.modbus_map",
    "RegisterAddress": "cnctwin.thread.modbus_map",
    "NAMESPACE_URI": "cnctwin.thread.opcua",
    "BLOCK_NODE": "cnctwin.thread.opcua",
    "NODE_MAP": "cnctwin.thread.opcua",
    "OpcUaConnection": "cnctwin.thread.opcua",
    "variant_type": "cnctwin.thread.opcua",
    "TrustList": "cnctwin.thread.trust",
}

__all__ = [
    "AdsConnection",
    "Symbol",
    "SymbolMap",
    "default_symbol_map",
    "load_symbol_map",
    "COMMANDS",
    "SIGNALS",
    "Backoff",
    "CommandRejected",
    "ConnectionLost",
    "ConnectionState",
    "MachineConnection",
    "LinuxCncConnection",
    "ModbusConnection",
    "Mosquitto",
    "LinkEvent",
    "MqttPublisher",
    "MqttSource",
    "SensorValue",
    "measure_mqtt_latency",
    "parse_sensor_payload",
    "SENSOR_SIGNALS",
    "MqttConfig",
    "MqttPublishConfig",
    "MqttSignalConfig",
    "broker_address",
    "MTConnectConnection",
    "OpcUaConnection",
    "Reading",
    "SampleBlock",
    "RunState",
    "SignalSpec",
    "now_s",
    "ConnectionConfig",
    "OpcUaSecurityConfig",
    "LatencyResult",
    "LatencyStats",
    "measure_endpoint_latency",
    "READ_MAP",
    "STATUS_MAP",
    "WRITE_MAP",
    "RegisterAddress",
    "NAMESPACE_URI",
    "BLOCK_NODE",
    "NODE_MAP",
    "variant_type",
    "TrustList",
    "JitterProxy",
    "measure_latency",
    "measure_read_latency",
    "DEFAULT_SUBSCRIPTION_MS",
    "SequenceGap",
    "AgentError",
    "DataItem",
    "Devices",
    "Observation",
    "ShdrFeed",
    "ShdrRecord",
    "Streams",
    "parse_devices",
    "parse_shdr",
    "parse_streams",
    "RUN_STATE_EXECUTION",
    "UNIT_FACTORS",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
