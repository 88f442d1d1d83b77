"""The ``[connection]`` table of a twin configuration: which machine, over what, mapped how."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from cnctwin.config import Section

__all__ = ["ConnectionConfig", "LinuxCncConfig", "OpcUaSecurityConfig"]


class OpcUaSecurityConfig(Section):
    """OPC UA security (``[connection.security]``).

    Attributes
    ----------
    policy
        ``"None"`` (loopback demos) or ``"Basic256Sha256"``.
    mode
        ``"None"``, ``"Sign"`` or ``"SignAndEncrypt"`` (``"None"`` only with policy None).
    certificate, private_key
        This client's certificate (DER or PEM) and key (PEM), paths relative to the config file.
    server_certificate
        The server's certificate, pinned: the twin accepts only this one.
    trust_folder
        Folder of the server certificates (or their CAs) to accept (``.der``/``.pem``). With
        policy Basic256Sha256, ``server_certificate`` or ``trust_folder`` is required: an
        unknown server certificate is refused (docs/security.md).
    trust_on_first_use
        Opt-in: with an empty ``trust_folder``, trust the first server certificate seen and
        write it into the folder; afterwards only that one is accepted.
    username, password
        User identity; ``None`` for anonymous.
    """

    policy: Literal["None", "Basic256Sha256"] = "None"
    mode: Literal["None", "Sign", "SignAndEncrypt"] = "None"
    certificate: str | None = None
    private_key: str | None = None
    server_certificate: str | None = None
    trust_folder: str | None = None
    trust_on_first_use: bool = False
    username: str | None = None
    password: str | None = None


class LinuxCncConfig(Section):
    """LinuxCNC's linuxcncrsh session (``[connection.linuxcnc]``; docs/linuxcnc.md).

    Attributes
    ----------
    connect_password
        linuxcncrsh's connect password (its ``--connectpw``; LinuxCNC's default ``"EMC"``).
    enable_password
        linuxcncrsh's enable password (its ``--enablepw``), which lets this session command
        the machine. ``None`` (the default): the session never asks to command, and every
        command is refused; the environment variable ``CNCTWIN_LINUXCNC_ENABLE`` gives it
        when the file does not.
    client_name
        The name this client gives in its ``hello`` (no whitespace).
    spindle
        The spindle whose override is read and commanded (LinuxCNC numbers them from 0).
    """

    connect_password: str = Field(default="EMC", pattern=r"^\S{1,64}$")
    enable_password: str | None = Field(default=None, pattern=r"^\S{1,64}$")
    client_name: str = Field(default="cnctwin", pattern=r"^\S{1,64}$")
    spindle: int = Field(default=0, ge=0, le=7)


class ConnectionConfig(Section):
    """How the twin reaches the machine (``[connection]``).

    Attributes
    ----------
    transport
        ``"opcua"``, ``"modbus"``, ``"mtconnect"`` (read-only: docs/mtconnect.md), ``"ads"``
        (Beckhoff TwinCAT: docs/ads.md) or ``"linuxcnc"`` (docs/linuxcnc.md).
    endpoint
        ``opc.tcp://HOST:PORT/PATH``, ``modbus://HOST:PORT``, for an MTConnect agent
        ``http://HOST:PORT[/DEVICE]``, for ADS ``ads://AMSNETID[:AMSPORT]@HOST[:PORT]``, for
        LinuxCNC ``linuxcncrsh://HOST[:PORT]``.
    timeout_s
        Timeout of one request, s.
    reconnect_initial_s, reconnect_max_s
        Capped exponential backoff between reconnection attempts, s.
    unit_id
        Modbus unit (slave) id.
    sample_count
        MTConnect: observations asked for per ``/sample`` request.
    security
        OPC UA security.
    symbol_map
        ADS: the symbol map TOML (canonical signal -> PLC symbol, type, scale), a path
        relative to the configuration file; ``None`` takes the packaged ``ads_symbols.toml``.
    local_net_id
        ADS: this computer's AMS Net ID, as the PLC's static route names it; ``None`` takes
        the IPv4 address this computer reaches the PLC from, plus ``.1.1``.
    linuxcnc
        LinuxCNC's session: passwords, client name, spindle.
    mapping
        Canonical signal name -> protocol address, overriding the transport's default map
        (the virtual machine's). OPC UA: a NodeId string (``"ns=2;s=Machine.X"``), a browse
        path, or ``"none"`` (a machine without the signal; presets in examples/opcua/);
        Modbus: ``"TABLE:ADDRESS:TYPE[:SCALE]"`` (see docs/modbus.md); MTConnect: a data
        item selector, ``"TYPE[:SUBTYPE][@COMPONENT]"`` or ``"id=DATA_ITEM"`` (see
        docs/mtconnect.md).
    """

    transport: Literal["opcua", "modbus", "mtconnect", "ads", "linuxcnc"] = "opcua"
    endpoint: str = "opc.tcp://127.0.0.1:4840/cnctwin"
    timeout_s: float = Field(default=2.0, ge=0.001, le=600.0)
    reconnect_initial_s: float = Field(default=0.1, ge=0.001, le=3600.0)
    reconnect_max_s: float = Field(default=5.0, ge=0.001, le=3600.0)
    unit_id: int = Field(default=1, ge=0, le=247)
    sample_count: int = Field(default=1000, ge=1, le=100_000)
    security: OpcUaSecurityConfig = Field(default_factory=OpcUaSecurityConfig)
    symbol_map: str | None = None
    local_net_id: str | None = None
    linuxcnc: LinuxCncConfig = Field(default_factory=LinuxCncConfig)
    mapping: dict[str, str] = Field(default_factory=dict)
