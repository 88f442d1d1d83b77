"""Endpoint URLs of the transports: one splitter for ``SCHEME://HOST[:PORT][/PATH]``."""

from __future__ import annotations

from urllib.parse import urlsplit

from cnctwin.errors import ConfigError

__all__ = ["split_endpoint"]


def split_endpoint(
    endpoint: str,
    *,
    scheme: str,
    default_port: int,
    what: str,
    form: str,
    example: str,
    segments: int = 0,
) -> tuple[str, int, str]:
    """Host, port and path of ``endpoint``, a URL of ``scheme`` with a host.

    Parameters
    ----------
    endpoint
        The URL as configured.
    scheme
        The one scheme accepted (``"modbus"``, ``"http"``, ...).
    default_port
        The port when the URL names none.
    what, form, example
        For the error: the transport's name, the accepted form and an example URL.
    segments
        Most path segments accepted (0: no path but a trailing ``/``).

    Returns
    -------
    tuple
        Host, port, and the path without a trailing ``/`` (``""`` for none).

    Raises
    ------
    ConfigError
        One line naming the endpoint and the accepted form: another scheme, no host, a port
        that is not a number in 0-65535, a query, or more path segments than ``segments``.
    """
    parts = urlsplit(endpoint)
    try:
        port = parts.port
    except ValueError:
        port = -1
    path = parts.path.rstrip("/")
    if (
        parts.scheme != scheme
        or not parts.hostname
        or port == -1
        or parts.query
        or path.count("/") > segments
    ):
        raise ConfigError(
            f"{what} endpoint {endpoint!r} is not of the form {form} (e.g. {example})"
        )
    return parts.hostname, default_port if port is None else port, path
