"""The transports' endpoint URLs: one splitter, the same refusals for each transport."""

from __future__ import annotations

import pytest

from cnctwin.errors import ConfigError
from cnctwin.thread.linuxcnc import parse_endpoint as linuxcnc_endpoint
from cnctwin.thread.modbus import parse_endpoint as modbus_endpoint
from cnctwin.thread.mtconnect import parse_endpoint as mtconnect_endpoint


def test_host_port_and_the_default_port() -> None:
    assert modbus_endpoint("modbus://10.0.0.7:5020") == ("10.0.0.7", 5020)
    assert modbus_endpoint("modbus://plc/") == ("plc", 502)
    assert linuxcnc_endpoint("linuxcncrsh://mill") == ("mill", 5007)
    assert mtconnect_endpoint("http://agent:5000/VMC-3Axis/") == ("agent", 5000, "/VMC-3Axis")
    assert mtconnect_endpoint("http://agent") == ("agent", 80, "")


@pytest.mark.parametrize(
    ("parse", "endpoint", "form"),
    [
        (modbus_endpoint, "opc.tcp://plc:4840", "modbus://HOST:PORT"),
        (modbus_endpoint, "modbus://:502", "modbus://HOST:PORT"),
        (modbus_endpoint, "modbus://plc:99999", "modbus://HOST:PORT"),
        (modbus_endpoint, "modbus://plc:50x", "modbus://HOST:PORT"),
        (modbus_endpoint, "modbus://plc:502/unit", "modbus://HOST:PORT"),
        (modbus_endpoint, "modbus://plc:502?unit=1", "modbus://HOST:PORT"),
        (linuxcnc_endpoint, "linuxcnc://mill:5007", "linuxcncrsh://HOST[:PORT]"),
        (mtconnect_endpoint, "http://agent:5000/a/b", "http://HOST:PORT[/DEVICE]"),
        (mtconnect_endpoint, "https://agent:5000", "http://HOST:PORT[/DEVICE]"),
        (mtconnect_endpoint, "http://agent:5000/?from=1", "http://HOST:PORT[/DEVICE]"),
    ],
)
def test_a_bad_endpoint_is_one_line_naming_it_and_the_form(
    parse: object, endpoint: str, form: str
) -> None:
    with pytest.raises(ConfigError) as caught:
        parse(endpoint)  # type: ignore[operator]
    message = str(caught.value)
    assert repr(endpoint) in message and form in message and "\n" not in message
