"""MTConnect documents and SHDR lines, parsed without I/O.

An MTConnect agent answers HTTP requests with XML documents (MTConnect Standard, Part 1,
"Fundamentals", and the 2.7 schemas in ``../shared/data/mtconnect/schemas``):

* ``MTConnectDevices`` (``/probe``): the devices and their data items (:func:`parse_devices`);
* ``MTConnectStreams`` (``/current``, ``/sample``): observations of data items, each with a
  ``sequence`` number the agent assigns and a ``timestamp`` (:func:`parse_streams`);
* ``MTConnectError``: why a request was refused (:class:`AgentError`).

An adapter feeds an agent SHDR lines, ``TIMESTAMP|KEY|VALUE|KEY|VALUE...`` (conditions take
five fields, ``KEY|LEVEL|NATIVE_CODE|NATIVE_SEVERITY|QUALIFIER|MESSAGE``; ``@ASSET@``
commands may carry a ``--multiline--TAG`` block): :func:`parse_shdr`.

The input is untrusted. :func:`parse_xml` refuses documents larger than a bound and any
document type declaration (so no entity can be declared, let alone expanded: the defence of
defusedxml's ``forbid_dtd``, done here with the standard library's expat), and reads element
names without their namespace prefix, so that a document of any MTConnect version -- and a
real one whose extension prefix is undeclared, as NIST's test bed agent serves -- reads alike.

Times are POSIX seconds (UTC, float); an MTConnect timestamp without a zone is UTC.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from xml.parsers import expat

from cnctwin.errors import CnctwinError, DataError

__all__ = [
    "MAX_DOCUMENT_BYTES",
    "UNAVAILABLE",
    "AgentError",
    "DataItem",
    "Devices",
    "Header",
    "Observation",
    "ShdrFeed",
    "ShdrRecord",
    "Streams",
    "element_type",
    "latest",
    "number",
    "parse_devices",
    "parse_document",
    "parse_shdr",
    "parse_streams",
    "parse_timestamp",
    "parse_xml",
]

#: Largest document accepted, bytes (an agent's probe of a big cell is a few MB).
MAX_DOCUMENT_BYTES = 32 * 1024 * 1024
#: Deepest element nesting accepted (a probe nests a dozen levels).
MAX_DEPTH = 64

#: The value an agent reports for a data item whose value is not known.
UNAVAILABLE = "UNAVAILABLE"

_CATEGORY_OF_GROUP = {"Samples": "SAMPLE", "Events": "EVENT", "Condition": "CONDITION"}
_CONDITION_LEVELS = {"Normal", "Warning", "Fault", "Unavailable"}


class AgentError(CnctwinError):
    """The agent answered with an ``MTConnectError`` document.

    Attributes
    ----------
    code
        The first error's code (``OUT_OF_RANGE``, ``NO_DEVICE``, ``INVALID_REQUEST``, ...).
    text
        The first error's message.
    header
        The document's header (its ``instanceId`` tells a restarted agent).
    """

    def __init__(self, code: str, text: str, header: Header | None = None) -> None:
        self.code = code
        self.text = text
        self.header = header
        super().__init__(f"MTConnect agent error {code}: {text}")


# XML ----------------------------------------------------------------------------------
def _local(name: str) -> str:
    return name.rsplit(":", 1)[-1]


def parse_xml(data: bytes, *, max_bytes: int = MAX_DOCUMENT_BYTES) -> ET.Element:
    """Parse an untrusted XML document into an element tree of local names.

    Element and attribute names lose their namespace prefix (``m:Position`` -> ``Position``,
    ``xsi:schemaLocation`` -> ``schemaLocation``); ``xmlns`` declarations are dropped.

    Raises
    ------
    DataError
        The document is larger than ``max_bytes``, nests deeper than 64 elements, declares
        a document type (DTD, entities), or is not well-formed XML; one line with where.
    """
    if len(data) > max_bytes:
        raise DataError(f"MTConnect document of {len(data)} bytes; the limit is {max_bytes}")
    builder = ET.TreeBuilder()
    parser = expat.ParserCreate()  # no namespace processing: prefixes are stripped below
    depth = 0

    def refuse_dtd(*_: object) -> int:
        raise DataError("MTConnect document declares a document type (DTD); refused")

    def start(name: str, attrs: dict[str, str]) -> None:
        nonlocal depth
        depth += 1
        if depth > MAX_DEPTH:
            raise DataError(f"MTConnect document nests deeper than {MAX_DEPTH} elements")
        plain = {
            _local(k): v for k, v in attrs.items() if k != "xmlns" and not k.startswith("xmlns:")
        }
        builder.start(_local(name), plain)

    def end(name: str) -> None:
        nonlocal depth
        depth -= 1
        builder.end(_local(name))

    parser.StartDoctypeDeclHandler = refuse_dtd
    parser.EntityDeclHandler = refuse_dtd
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = builder.data
    try:
        parser.Parse(data, True)
    except expat.ExpatError as err:
        raise DataError(f"MTConnect document is not well-formed XML: {err}") from None
    root = builder.close()
    return root


# Documents ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Header:
    """The ``Header`` of a document.

    Attributes
    ----------
    instance_id
        Changes whenever the agent restarts (its buffer and sequence numbers start anew).
    version
        The agent's MTConnect version.
    creation_time_s
        When the document was made, POSIX s.
    sender
        The agent's host name.
    buffer_size
        Observations the agent keeps.
    first_sequence, last_sequence, next_sequence
        Oldest and newest sequence number in the agent's buffer, and the one to ask for
        next (Streams only; ``None`` elsewhere).
    """

    instance_id: int
    version: str
    creation_time_s: float | None
    sender: str
    buffer_size: int | None = None
    first_sequence: int | None = None
    last_sequence: int | None = None
    next_sequence: int | None = None


@dataclass(frozen=True)
class DataItem:
    """One ``DataItem`` of a probe.

    Attributes
    ----------
    id, name
        Its id (unique in the agent) and optional name; SHDR keys name one of the two.
    type, sub_type
        ``POSITION``, ``ACTUAL``, ...
    category
        ``SAMPLE``, ``EVENT`` or ``CONDITION``.
    units, native_units
        The units the agent reports in (``MILLIMETER/SECOND``) and those of the adapter's
        feed, ``None`` when not given.
    device, device_uuid
        Name and uuid of its device.
    component, component_name, component_id
        The element, the name (else id) and the id of the component that holds it
        (``Linear``, ``X``, ``x``).
    """

    id: str
    name: str | None
    type: str
    sub_type: str | None
    category: str
    units: str | None
    native_units: str | None
    device: str
    component: str
    component_name: str
    component_id: str = ""
    device_uuid: str = ""


@dataclass(frozen=True)
class Devices:
    """An ``MTConnectDevices`` document (the answer to ``/probe``).

    Attributes
    ----------
    header
        Its header.
    devices
        Device names, in document order.
    data_items
        Every data item of every device, in document order.
    """

    header: Header
    devices: tuple[str, ...]
    data_items: tuple[DataItem, ...]

    def item(self, key: str) -> DataItem | None:
        """The data item whose id (else name) is ``key``."""
        for item in self.data_items:
            if item.id == key:
                return item
        for item in self.data_items:
            if item.name == key:
                return item
        return None


@dataclass(frozen=True)
class Observation:
    """One observation of a ``Streams`` document.

    Attributes
    ----------
    data_item_id
        The observed data item.
    element
        The element (``Position``, ``Execution``; for a condition its level element
        ``Normal``/``Warning``/``Fault``/``Unavailable``).
    category
        ``SAMPLE``, ``EVENT`` or ``CONDITION``.
    sequence
        The agent's sequence number.
    timestamp_s
        When the value was observed, POSIX s.
    value
        The text (``"12.5"``, ``"ACTIVE"``, ``"UNAVAILABLE"``); for a condition its level
        upper-cased (``"NORMAL"``, ``"FAULT"``, ...).
    device, component_name
        Where it was observed.
    name, sub_type
        The ``name`` and ``subType`` attributes, when present.
    condition_type, native_code, message
        A condition's ``type``, ``nativeCode`` and text.
    """

    data_item_id: str
    element: str
    category: str
    sequence: int
    timestamp_s: float
    value: str
    device: str
    component_name: str
    name: str | None = None
    sub_type: str | None = None
    condition_type: str | None = None
    native_code: str | None = None
    message: str | None = None

    @property
    def unavailable(self) -> bool:
        """Whether the agent does not know the value."""
        return self.value == UNAVAILABLE


@dataclass(frozen=True)
class Streams:
    """An ``MTConnectStreams`` document (the answer to ``/current`` or ``/sample``)."""

    header: Header
    observations: tuple[Observation, ...]


_CAMEL = re.compile(r"(?<=[a-z0-9])(?=[A-Z])|(?<=[A-Z])(?=[A-Z][a-z])")


def element_type(element: str) -> str:
    """The data item type of a Streams element: ``PathFeedrate`` -> ``PATH_FEEDRATE``."""
    return _CAMEL.sub("_", _local(element)).upper()


def parse_timestamp(text: str) -> float:
    """POSIX s of an MTConnect timestamp (ISO 8601; UTC when it carries no zone).

    Fractions finer than a microsecond (SHDR adapters send seven digits) are cut.

    Raises
    ------
    DataError
        Not a timestamp.
    """
    raw = text.strip()
    match = re.fullmatch(r"(\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2})(\.\d+)?(Z|[+-]\d{2}:\d{2})?", raw)
    if match is None:
        raise DataError(f"timestamp {text!r} is not ISO 8601 (e.g. 2024-01-31T12:00:00.5Z)")
    base, frac, zone = match.groups()
    try:
        moment = datetime.fromisoformat(base + (zone if zone and zone != "Z" else "+00:00"))
    except ValueError:
        raise DataError(f"timestamp {text!r} is not a valid date and time") from None
    if moment.tzinfo is None:  # pragma: no cover - the zone is always added above
        moment = moment.replace(tzinfo=UTC)
    return moment.timestamp() + (float(frac) if frac else 0.0)


def _int(element: ET.Element, name: str, required: bool = True) -> int | None:
    text = element.get(name)
    if text is None:
        if required:
            raise DataError(f"MTConnect <{element.tag}> lacks the attribute {name!r}")
        return None
    try:
        return int(text)
    except ValueError:
        raise DataError(f"MTConnect <{element.tag}> {name}={text!r} is not an integer") from None


def _header(root: ET.Element) -> Header:
    head = root.find("Header")
    if head is None:
        raise DataError(f"MTConnect <{root.tag}> has no <Header>")
    created = head.get("creationTime")
    return Header(
        instance_id=_int(head, "instanceId") or 0,
        version=head.get("version", ""),
        creation_time_s=parse_timestamp(created) if created else None,
        sender=head.get("sender", ""),
        buffer_size=_int(head, "bufferSize", False),
        first_sequence=_int(head, "firstSequence", False),
        last_sequence=_int(head, "lastSequence", False),
        next_sequence=_int(head, "nextSequence", False),
    )


def _raise_error(root: ET.Element) -> None:
    """Raise :class:`AgentError` of an ``MTConnectError`` document."""
    header = _header(root) if root.find("Header") is not None else None
    errors = root.find("Errors")
    first = errors[0] if errors is not None and len(errors) else root.find("Error")
    if first is None:
        raise AgentError("UNKNOWN", "MTConnectError document without an error", header)
    code = first.get("errorCode") or element_type(first.tag)
    message = first.findtext("ErrorMessage")
    text = message if message is not None else (first.text or "")
    raise AgentError(code, " ".join(text.split()), header)


def _root(data: bytes | ET.Element, expected: str) -> ET.Element:
    root = data if isinstance(data, ET.Element) else parse_xml(data)
    if root.tag == "MTConnectError":
        _raise_error(root)
    if root.tag != expected:
        raise DataError(f"expected an {expected} document, got <{root.tag}>")
    return root


def parse_devices(data: bytes | ET.Element) -> Devices:
    """The devices and data items of an ``MTConnectDevices`` document (a probe).

    Raises
    ------
    AgentError
        The document is an ``MTConnectError``.
    DataError
        It is not a Devices document, or a data item lacks id, type or category.
    """
    root = _root(data, "MTConnectDevices")
    devices: list[str] = []
    items: list[DataItem] = []

    def walk(component: ET.Element, device: str, uuid: str) -> None:
        label = component.get("name") or component.get("id") or component.tag
        for item in component.findall("DataItems/DataItem"):
            ident, kind, category = item.get("id"), item.get("type"), item.get("category")
            if not ident or not kind or not category:
                raise DataError(
                    f"MTConnect DataItem {item.attrib} of {label} lacks id, type or category"
                )
            items.append(
                DataItem(
                    id=ident,
                    name=item.get("name"),
                    type=kind,
                    sub_type=item.get("subType"),
                    category=category,
                    units=item.get("units"),
                    native_units=item.get("nativeUnits"),
                    device=device,
                    component=component.tag,
                    component_name=label,
                    component_id=component.get("id") or label,
                    device_uuid=uuid,
                )
            )
        for child in component.findall("Components/*"):
            walk(child, device, uuid)

    for device in root.findall("Devices/*"):
        name = device.get("name") or device.get("uuid") or device.get("id") or device.tag
        devices.append(name)
        walk(device, name, device.get("uuid") or name)
    return Devices(_header(root), tuple(devices), tuple(items))


def parse_streams(data: bytes | ET.Element) -> Streams:
    """The observations of an ``MTConnectStreams`` document, in sequence order.

    Raises
    ------
    AgentError
        The document is an ``MTConnectError``.
    DataError
        It is not a Streams document, or an observation lacks ``dataItemId``, ``sequence``
        or ``timestamp``, or carries a malformed one.
    """
    root = _root(data, "MTConnectStreams")
    found: list[Observation] = []
    for device in root.findall("Streams/DeviceStream"):
        device_name = device.get("name") or device.get("uuid") or ""
        for component in device.findall("ComponentStream"):
            where = component.get("name") or component.get("componentId") or ""
            for group in component:
                category = _CATEGORY_OF_GROUP.get(group.tag)
                if category is None:
                    continue
                for obs in group:
                    found.append(_observation(obs, category, device_name, where))
    found.sort(key=lambda o: o.sequence)
    return Streams(_header(root), tuple(found))


def _observation(obs: ET.Element, category: str, device: str, where: str) -> Observation:
    ident = obs.get("dataItemId")
    stamp = obs.get("timestamp")
    if not ident or not stamp:
        raise DataError(f"MTConnect <{obs.tag}> lacks dataItemId or timestamp")
    sequence = _int(obs, "sequence") or 0
    text = " ".join("".join(obs.itertext()).split())
    if category == "CONDITION" and obs.tag in _CONDITION_LEVELS:
        return Observation(
            data_item_id=ident,
            element=obs.tag,
            category=category,
            sequence=sequence,
            timestamp_s=parse_timestamp(stamp),
            value=obs.tag.upper(),
            device=device,
            component_name=where,
            name=obs.get("name"),
            sub_type=obs.get("subType"),
            condition_type=obs.get("type"),
            native_code=obs.get("nativeCode"),
            message=text or None,
        )
    return Observation(
        data_item_id=ident,
        element=obs.tag,
        category=category,
        sequence=sequence,
        timestamp_s=parse_timestamp(stamp),
        value=text,
        device=device,
        component_name=where,
        name=obs.get("name"),
        sub_type=obs.get("subType"),
    )


def parse_document(data: bytes) -> Devices | Streams:
    """A Devices or Streams document, whichever ``data`` is.

    Raises
    ------
    AgentError
        ``data`` is an ``MTConnectError`` document.
    DataError
        ``data`` is neither, or malformed.
    """
    root = parse_xml(data)
    if root.tag == "MTConnectDevices":
        return parse_devices(root)
    return parse_streams(root)


# SHDR ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class ShdrRecord:
    """One key of an SHDR line with its fields.

    Attributes
    ----------
    line
        1-based line number of the line that carried it.
    timestamp_s
        The line's timestamp, POSIX s.
    key
        The data item id or name, or an asset command (``@ASSET@``, ``@REMOVE_ASSET@``,
        ``@REMOVE_ALL_ASSETS@``, ``@UPDATE_ASSET@``).
    fields
        One value for a sample or event; ``(LEVEL, NATIVE_CODE, NATIVE_SEVERITY, QUALIFIER,
        MESSAGE)`` for a condition; ``(NATIVE_CODE, TEXT)`` for a message; for ``@ASSET@``
        ``(ASSET_ID, TYPE, DOCUMENT)``, the document joined from its multiline block.
    """

    line: int
    timestamp_s: float
    key: str
    fields: tuple[str, ...]


@dataclass
class ShdrFeed:
    """What :func:`parse_shdr` read.

    Attributes
    ----------
    records
        Every key of every usable line, in file order (SHDR timestamps need not increase).
    rejected
        One line per unusable line or key: line number and reason.
    """

    records: list[ShdrRecord] = field(default_factory=list)
    rejected: list[str] = field(default_factory=list)

    def values(self, key: str) -> list[tuple[float, tuple[str, ...]]]:
        """``(timestamp_s, fields)`` of every record of ``key``, in file order."""
        return [(r.timestamp_s, r.fields) for r in self.records if r.key == key]


def _shdr_width(key: str, devices: Devices | None) -> int:
    """Fields that follow ``key`` on a line (1 when the key is unknown)."""
    if devices is None:
        return 1
    item = devices.item(key)
    if item is None:
        return 1
    if item.category == "CONDITION":
        return 5
    if item.type == "MESSAGE":
        return 2
    return 1


def parse_shdr(lines: Iterable[str], devices: Devices | None = None) -> ShdrFeed:
    """Parse an adapter's SHDR lines.

    Parameters
    ----------
    lines
        The text, one SHDR line per item (line ends are stripped).
    devices
        The agent's probe: it says which keys are conditions (five fields) or messages (two);
        without it every key takes one field.

    Returns
    -------
    ShdrFeed
        The records and the rejected lines (bad timestamp, a line cut short, an unterminated
        multiline block), each with its reason.
    """
    feed = ShdrFeed()
    pending = iter(enumerate(lines, start=1))
    for number, raw in pending:
        line = raw.rstrip("\r\n")
        if not line.strip() or line.startswith("*"):  # blank, or a "* PING"-style command
            continue
        parts = line.split("|")
        try:
            stamp = parse_timestamp(parts[0])
        except DataError as err:
            feed.rejected.append(f"line {number}: {err}")
            continue
        index = 1
        while index < len(parts):
            key = parts[index]
            index += 1
            if key == "@ASSET@" or key == "@UPDATE_ASSET@":
                body = parts[index:]
                index = len(parts)
                if len(body) < 3:
                    feed.rejected.append(f"line {number}: {key} needs ASSET_ID|TYPE|DOCUMENT")
                    break
                document = "|".join(body[2:])
                if document.startswith("--multiline--"):
                    tag, block = document, []
                    for _, more in pending:
                        if more.rstrip("\r\n") == tag:
                            break
                        block.append(more.rstrip("\r\n"))
                    else:
                        feed.rejected.append(f"line {number}: multiline block {tag} not closed")
                        break
                    document = "\n".join(block)
                feed.records.append(ShdrRecord(number, stamp, key, (body[0], body[1], document)))
                break
            width = len(parts) - index if key.startswith("@") else _shdr_width(key, devices)
            if index + width > len(parts):
                feed.rejected.append(
                    f"line {number}: key {key!r} needs {width} field(s), the line has "
                    f"{len(parts) - index}"
                )
                break
            feed.records.append(ShdrRecord(number, stamp, key, tuple(parts[index : index + width])))
            index += width
    return feed


def number(text: str) -> float:
    """A finite number of an observation's text.

    Raises
    ------
    DataError
        Not a number (``"UNAVAILABLE"``, garbage), or not finite (``NaN``, ``INF``).
    """
    try:
        value = float(text)
    except ValueError:
        raise DataError(f"{text[:40]!r} is not a number") from None
    if not math.isfinite(value):
        raise DataError(f"{text!r} is not a finite number")
    return value


def latest(observations: Iterable[Observation]) -> Mapping[str, Observation]:
    """The newest observation (highest sequence) of each data item."""
    newest: dict[str, Observation] = {}
    for obs in observations:
        held = newest.get(obs.data_item_id)
        if held is None or obs.sequence >= held.sequence:
            newest[obs.data_item_id] = obs
    return newest
