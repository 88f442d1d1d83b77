"""The digital thread: one :class:`MachineConnection` interface over industrial protocols.

The transports (:class:`OpcUaConnection`, :class:`ModbusConnection`, :class:`AdsConnection`,
the read-only :class:`MTConnectConnection` and LinuxCNC's :class:`LinuxCncConnection`) load
asyncua, pymodbus and pyads, the MQTT publisher and sensor source (:class:`MqttPublisher`,
:class:`MqttSource`) paho-mqtt;
they are imported on first use so that the signal catalogue and the connection interface stay
light for the modules that only need those.
"""

from typing import TYPE_CHECKING

from cnctwin import _lazy
from cnctwin.thread.connection import (
    Backoff,
    CommandRejected,
    ConnectionLost,
    ConnectionState,
    MachineConnection,
    ReadBack,
    Reading,
    SampleBlock,
    drop_answer,
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
        measure_broker_latency,
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
        CLIENT_APPLICATION_URI,
        DEFAULT_SUBSCRIPTION_MS,
        NAMESPACE_URI,
        NODE_MAP,
        OpcUaConnection,
        variant_type,
    )
    from cnctwin.thread.opcua_channel import (
        PlainMessage,
        filetime_now,
        frame_message,
        plain_message,
        take_plain_message,
    )
    from cnctwin.thread.opcua_publish import lean_publish_response, use_lean_publish
    from cnctwin.thread.trust import TrustList

# pydantic, asyncio, asyncua, pymodbus and cryptography load with these: imported on first use.
_LAZY = {
    "AdsConnection": "ads",
    "default_symbol_map": "ads",
    "Symbol": "ads_map",
    "SymbolMap": "ads_map",
    "load_symbol_map": "ads_map",
    "ConnectionConfig": "config",
    "OpcUaSecurityConfig": "config",
    "JitterProxy": "latency",
    "LatencyResult": "latency",
    "measure_latency": "latency",
    "measure_read_latency": "latency",
    "DEFAULT_SUBSCRIPTION_MS": "opcua",
    "LatencyStats": "latency",
    "measure_broker_latency": "latency",
    "measure_endpoint_latency": "latency",
    "ModbusConnection": "modbus",
    "Mosquitto": "mosquitto",
    "LinkEvent": "mqtt",
    "MqttPublisher": "mqtt",
    "MqttSource": "mqtt",
    "SensorValue": "mqtt",
    "measure_mqtt_latency": "mqtt",
    "parse_sensor_payload": "mqtt",
    "SENSOR_SIGNALS": "mqtt_config",
    "MqttConfig": "mqtt_config",
    "MqttPublishConfig": "mqtt_config",
    "MqttSignalConfig": "mqtt_config",
    "broker_address": "mqtt_config",
    "LinuxCncConnection": "linuxcnc",
    "MTConnectConnection": "mtconnect",
    "SequenceGap": "mtconnect",
    "AgentError": "mtconnect_documents",
    "DataItem": "mtconnect_documents",
    "Devices": "mtconnect_documents",
    "Observation": "mtconnect_documents",
    "ShdrFeed": "mtconnect_documents",
    "ShdrRecord": "mtconnect_documents",
    "Streams": "mtconnect_documents",
    "parse_devices": "mtconnect_documents",
    "parse_shdr": "mtconnect_documents",
    "parse_streams": "mtconnect_documents",
    "RUN_STATE_EXECUTION": "mtconnect_map",
    "UNIT_FACTORS": "mtconnect_map",
    "READ_MAP": "modbus_map",
    "STATUS_MAP": "modbus_map",
    "WRITE_MAP": "modbus_map",
    "RegisterAddress": "modbus_map",
    "BLOCK_NODE": "opcua",
    "CLIENT_APPLICATION_URI": "opcua",
    "NAMESPACE_URI": "opcua",
    "NODE_MAP": "opcua",
    "OpcUaConnection": "opcua",
    "variant_type": "opcua",
    "PlainMessage": "opcua_channel",
    "filetime_now": "opcua_channel",
    "frame_message": "opcua_channel",
    "plain_message": "opcua_channel",
    "take_plain_message": "opcua_channel",
    "lean_publish_response": "opcua_publish",
    "use_lean_publish": "opcua_publish",
    "TrustList": "trust",
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
    "ReadBack",
    "SampleBlock",
    "RunState",
    "SignalSpec",
    "drop_answer",
    "now_s",
    "ConnectionConfig",
    "OpcUaSecurityConfig",
    "LatencyResult",
    "LatencyStats",
    "measure_broker_latency",
    "measure_endpoint_latency",
    "READ_MAP",
    "STATUS_MAP",
    "WRITE_MAP",
    "RegisterAddress",
    "CLIENT_APPLICATION_URI",
    "NAMESPACE_URI",
    "BLOCK_NODE",
    "NODE_MAP",
    "variant_type",
    "PlainMessage",
    "filetime_now",
    "frame_message",
    "plain_message",
    "take_plain_message",
    "lean_publish_response",
    "use_lean_publish",
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

__getattr__, __dir__ = _lazy.exports(__name__, _LAZY)
