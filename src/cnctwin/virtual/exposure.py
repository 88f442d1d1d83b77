"""Where a machine server may listen without security: loopback only, unless told otherwise."""

from __future__ import annotations

import ipaddress

from cnctwin.errors import ConfigError

__all__ = ["check_exposure", "is_loopback"]


def is_loopback(host: str) -> bool:
    """Whether ``host`` is a loopback address (``127.0.0.0/8``, ``::1``) or ``localhost``."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def check_exposure(host: str, transport: str, *, secured: bool, insecure: bool) -> None:
    """Refuse to serve ``transport`` unsecured on a non-loopback ``host``.

    Parameters
    ----------
    host
        The address to listen on.
    transport
        ``"opcua"``, ``"modbus"``, ``"mtconnect"`` or ``"ads"`` (Modbus TCP, the MTConnect
        agent and the ADS server have no security: never ``secured``).
    secured
        The server authenticates its peers (OPC UA Sign or SignAndEncrypt with a trust list).
    insecure
        The user asked for an unsecured server on the network (``--insecure``).

    Raises
    ------
    ConfigError
        One line that says what to do.
    """
    if secured or insecure or is_loopback(host):
        return
    if transport in ("modbus", "mtconnect", "ads"):
        name = {"modbus": "Modbus TCP", "mtconnect": "the MTConnect agent", "ads": "ADS"}[transport]
        fix = f"{name} has no security: listen on 127.0.0.1"
    else:
        fix = (
            "give --security-mode SignAndEncrypt with --certificate, --private-key and --trust "
            "(docs/security.md), or listen on 127.0.0.1"
        )
    raise ConfigError(
        f"refusing to serve {transport} without security on {host!r} (not loopback): {fix}, "
        "or pass --insecure on a network you control"
    )
