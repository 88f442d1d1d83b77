"""Untrusted MQTT input: sensor payloads and the ``[mqtt]`` table refuse what is not valid.

No broker: :func:`parse_sensor_payload` is what the source runs on every message, and the
table's validation is what ``load_run_config`` runs. Each refusal is one line naming the
value and what would be valid.
"""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from cnctwin.errors import ConfigError, DataError
from cnctwin.thread.mqtt import parse_sensor_payload
from cnctwin.thread.mqtt_config import (
    SENSOR_SIGNALS,
    MqttConfig,
    MqttSignalConfig,
    broker_address,
)
from cnctwin.thread.signals import SIGNALS

VIB = MqttSignalConfig(topic="plant/vib", signal="vibration_g", unit="g", low=0.0, high=50.0)
FX = MqttSignalConfig(topic="plant/fx", signal="force_x_n", unit="N")


@pytest.mark.parametrize(
    ("payload", "value"),
    [
        (b"3.5", 3.5),
        (b"0", 0.0),
        (b'{"value": 12}', 12.0),
        (b'{"value": 1.25, "unit": "g"}', 1.25),
        (b'{"seq": 7, "value": 2.0}', 2.0),
        (b" 4.0 \n", 4.0),
    ],
)
def test_valid_payloads_give_their_value(payload: bytes, value: float) -> None:
    assert parse_sensor_payload(payload, VIB, 64) == value


@pytest.mark.parametrize(
    ("payload", "says"),
    [
        (b"1" * 65, "at most 64"),
        (b"NaN", "no JSON"),
        (b"-Infinity", "no JSON"),
        (b'{"value": NaN}', "no JSON"),
        (b"1e999", "not a finite number"),
        (b'{"value": 1e400}', "not a finite number"),
        (b"\xff\xfe", "no JSON"),
        (b"", "no JSON"),
        (b"[1]", "list is no number"),
        (b'"3"', "str is no number"),
        (b"true", "bool is no number"),
        (b"null", "NoneType is no number"),
        (b'{"value": "3"}', "str is no number"),
        (b'{"unit": "g"}', 'no "value"'),
        (b'{"value": 3, "unit": "m/s^2"}', "valid: 'g'"),
        (b'{"value": 3, "command": "stop"}', "unknown keys ['command']"),
        (b'{"value": 3, "seq": 1.5}', "seq float"),
        (b"-0.1", "outside 0 to 50 g"),
        (b"50.5", "outside 0 to 50 g"),
        (b"[" * 60, "no JSON"),
    ],
)
def test_garbage_is_refused_in_one_line(payload: bytes, says: str) -> None:
    with pytest.raises(DataError) as err:
        parse_sensor_payload(payload, VIB, 64)
    assert says in str(err.value) and "\n" not in str(err.value)


def test_without_a_range_values_beyond_1e12_are_refused() -> None:
    assert parse_sensor_payload(b"-1e12", FX, 64) == -1e12
    with pytest.raises(DataError, match="outside"):
        parse_sensor_payload(b"2e12", FX, 64)


@given(st.binary(max_size=80))
def test_any_bytes_give_a_finite_value_or_a_data_error(payload: bytes) -> None:
    try:
        value = parse_sensor_payload(payload, VIB, 64)
    except DataError:
        return
    assert math.isfinite(value) and 0.0 <= value <= 50.0


@given(st.floats(allow_nan=False, allow_infinity=False, min_value=0.0, max_value=50.0))
def test_every_value_in_range_round_trips(value: float) -> None:
    assert parse_sensor_payload(json.dumps({"value": value}).encode(), VIB, 64) == value


@pytest.mark.parametrize(
    ("entry", "says"),
    [
        ({"signal": "x_mm", "unit": "mm"}, "machine's state"),
        ({"signal": "run_state", "unit": "1"}, "machine's state"),
        ({"signal": "feed_override_pct", "unit": "%"}, "machine's state"),
        ({"signal": "heartbeat", "unit": "1"}, "machine's state"),
        ({"signal": "force_x_n", "unit": "kN"}, "valid: 'N'"),
        ({"signal": "Bad-Name", "unit": "1"}, "extra name"),
        ({"signal": "v", "unit": "1", "topic": "plant/#"}, "no wildcards"),
        ({"signal": "v", "unit": "1", "topic": "plant/+/v"}, "no wildcards"),
        ({"signal": "v", "unit": "1", "topic": "$SYS/x"}, "leading $"),
        ({"signal": "v", "unit": "1", "low": 5, "high": 1}, "below high"),
        ({"signal": "v", "unit": "1", "max_age_s": 0}, "greater than 0"),
    ],
)
def test_signal_entries_are_checked(entry: dict[str, object], says: str) -> None:
    with pytest.raises(ValueError, match=None) as err:
        MqttSignalConfig.model_validate({"topic": "plant/v", **entry})
    assert says in str(err.value)


def test_every_sensor_signal_is_a_measurement_not_a_command() -> None:
    assert all(name in SIGNALS and not SIGNALS[name].writable for name in SENSOR_SIGNALS)


def test_the_table_refuses_duplicates_half_tls_and_bad_brokers() -> None:
    sig = {"topic": "a/b", "signal": "v", "unit": "1"}
    with pytest.raises(ValueError, match="given twice"):
        MqttConfig.model_validate({"signals": [sig, {**sig, "signal": "w"}]})
    with pytest.raises(ValueError, match="given twice"):
        MqttConfig.model_validate({"signals": [sig, {**sig, "topic": "a/c"}]})
    for url in ("http://h:1883", "mqtt://", "mqtt://h:99999", "mqtt://u:p@h", "mqtt://h/x"):
        with pytest.raises(ValueError, match="broker"):
            MqttConfig.model_validate({"broker": url})
    with pytest.raises(ValueError, match="topic_prefix"):
        MqttConfig.model_validate({"publish": {"topic_prefix": "a/#"}})
    with pytest.raises(ValueError, match="qos"):
        MqttConfig.model_validate({"publish": {"qos": 2}})
    with pytest.raises(ValueError, match="extra"):
        MqttConfig.model_validate({"password": "secret"})  # only password_env


def test_broker_urls() -> None:
    assert broker_address("mqtt://127.0.0.1") == ("127.0.0.1", 1883, False)
    assert broker_address("mqtts://broker.plant:8884") == ("broker.plant", 8884, True)
    assert broker_address("mqtts://broker.plant") == ("broker.plant", 8883, True)


def test_a_missing_password_variable_is_a_config_error(monkeypatch: pytest.MonkeyPatch) -> None:
    from cnctwin.thread.mqtt import MqttPublisher

    monkeypatch.delenv("CNCTWIN_TEST_NO_SUCH_PASSWORD", raising=False)
    config = MqttConfig(username="twin", password_env="CNCTWIN_TEST_NO_SUCH_PASSWORD")
    with pytest.raises(ConfigError, match="CNCTWIN_TEST_NO_SUCH_PASSWORD"):
        MqttPublisher(config)
