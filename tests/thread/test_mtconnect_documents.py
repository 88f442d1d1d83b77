"""MTConnect documents and SHDR lines: the real ones in ../shared/data/mtconnect, and hostile ones.

The references are the real files themselves (an Okuma/Mazak probe of the MTConnect
Institute's reference agent, a NIST test bed agent's /current, an Okuma adapter's SHDR log),
read here independently of the parser (regular expressions on the raw text, the counts the
data folder's README gives), and the MTConnect Standard's enumerations.
"""

from __future__ import annotations

import calendar
import re
from collections import Counter
from pathlib import Path

import pytest

from cnctwin.errors import ConfigError, DataError
from cnctwin.thread.mtconnect_documents import (
    AgentError,
    element_type,
    number,
    parse_devices,
    parse_document,
    parse_shdr,
    parse_streams,
    parse_timestamp,
    parse_xml,
)
from cnctwin.thread.mtconnect_map import MappedItem, convert, parse_selector, resolve_map
from cnctwin.thread.signals import RunState


@pytest.fixture(scope="module")
def samples(request: pytest.FixtureRequest) -> Path:
    shared = request.getfixturevalue("shared_data")
    folder = shared / "mtconnect" / "samples"
    if not folder.is_dir():
        pytest.skip(f"{folder} is absent (MTConnect samples of ../shared/data)")
    return folder


def _posix(text: str) -> float:
    """POSIX s of ``YYYY-MM-DDTHH:MM:SS[.f]`` (UTC) by calendar.timegm: an independent parse."""
    whole, _, frac = text.rstrip("Z").partition(".")
    stamp = calendar.timegm(tuple(int(p) for p in re.split(r"[-T:]", whole)) + (0, 0, 0))
    return stamp + (float("0." + frac) if frac else 0.0)


# Real documents ---------------------------------------------------------------------
def test_real_probe_has_its_devices_and_data_items(samples: Path) -> None:
    raw = (samples / "demo_Devices_2.7.xml").read_text()
    devices = parse_devices(raw.encode())
    assert devices.devices == ("OKUMA", "Mazak")
    # The README's count, and the raw text's: one <DataItem per data item.
    assert len(devices.data_items) == 216 == len(re.findall(r"<DataItem\b", raw))
    assert len({i.id for i in devices.data_items}) == 216
    fact = devices.item("p1Fact")  # by name; the SHDR key
    assert fact is not None and fact.id == "Lp1Fact"
    assert (fact.type, fact.sub_type, fact.category) == ("PATH_FEEDRATE", "ACTUAL", "SAMPLE")
    assert (fact.units, fact.native_units) == ("MILLIMETER/SECOND", "MILLIMETER/MINUTE")
    assert fact.device == "OKUMA" and fact.component == "Path"
    system = devices.item("Lsystem")
    assert system is not None and system.category == "CONDITION"
    assert devices.header.instance_id == 1 and devices.header.buffer_size == 131072


def test_real_current_gives_every_observation(samples: Path) -> None:
    raw = (samples / "nist_testbed_current_1.3.xml").read_text()
    streams = parse_streams(raw.encode())  # its undeclared x: prefix is read leniently
    obs = streams.observations
    assert len(obs) == 242 == len(re.findall(r"\bdataItemId=", raw))
    counts = Counter(o.value for o in obs if o.category == "CONDITION")
    assert counts == {"NORMAL": 46, "UNAVAILABLE": 6, "FAULT": 2}
    assert sum(o.value == "UNAVAILABLE" and o.category != "CONDITION" for o in obs) == 92
    header = streams.header
    assert (header.instance_id, header.first_sequence, header.next_sequence) == (
        1596156369,
        366898420,
        367946996,
    )
    # Every observation as the raw text has it: dataItemId, sequence, timestamp.
    pattern = re.compile(r'dataItemId="([^"]+)" timestamp="([^"]+)"[^>]*?sequence="(\d+)"')
    raw_obs = {m[0]: (int(m[2]), _posix(m[1])) for m in pattern.findall(raw)}
    assert len(raw_obs) == 242
    for o in obs:
        assert (o.sequence, o.timestamp_s) == pytest.approx(raw_obs[o.data_item_id], abs=1e-6)
    x = next(o for o in obs if o.data_item_id == "GFAgie01-X_2")
    assert (x.element, x.value, x.sub_type, x.category) == (
        "Position",
        "6.39211",
        "ACTUAL",
        "SAMPLE",
    )
    fault = next(o for o in obs if o.data_item_id == "GFAgie01-dtop_3")
    assert (fault.value, fault.native_code, fault.message) == ("FAULT", "3AA", "Key non-functional")
    assert [o.sequence for o in obs] == sorted(o.sequence for o in obs)


def test_real_shdr_log_parses_with_the_probe(samples: Path) -> None:
    devices = parse_devices((samples / "demo_Devices_2.7.xml").read_bytes())
    text = (samples / "okuma_shdr_first298lines.txt").read_text()
    feed = parse_shdr(text.splitlines(), devices)
    assert feed.rejected == []
    # Spot checks against the raw text, split here by a regular expression.
    raw_x = [
        (_posix(m[0]), m[1])
        for m in re.findall(r"^(\S+?Z)\|.*?\bX1actw\|([^|\n]*)", text, flags=re.M)
    ]
    assert len(raw_x) == 7
    assert [(t, f[0]) for t, f in feed.values("X1actw")] == [
        (pytest.approx(t, abs=1e-6), v) for t, v in raw_x
    ]
    assert feed.values("X1actw")[-1][1] == ("-119.9999",)
    assert feed.values("p1LPathPos")[0][1] == ("1039.897 0 269.0133",)
    # Conditions take five fields; the first line's snapshot is 79 key|value pairs.
    assert feed.values("system")[0][1] == ("NORMAL", "", "", "", "")
    assert sum(r.line == 1 for r in feed.records) == 79
    assert feed.values("OperatingSystemAll")[0][1][0].startswith("Name = Windows 10;Edition")
    # Assets: 20 @ASSET@ with their multiline documents, two removals, one remove-all.
    commands = Counter(r.key for r in feed.records if r.key.startswith("@"))
    assert commands == {"@ASSET@": 20, "@REMOVE_ASSET@": 2, "@REMOVE_ALL_ASSETS@": 1}
    asset = next(r for r in feed.records if r.key == "@ASSET@")
    assert asset.fields[:2] == ("123456.2201", "CuttingTool")
    assert asset.fields[2].startswith('<CuttingTool toolId="123456" serialNumber="2201"')
    assert "--multiline--" not in asset.fields[2]
    # Out-of-order time stamps are kept as sent: 25 lines are earlier than the line before.
    first_per_line = {}
    for r in feed.records:
        first_per_line.setdefault(r.line, r.timestamp_s)
    stamps = list(first_per_line.values())
    assert sum(b < a for a, b in zip(stamps, stamps[1:], strict=False)) == 25
    # The one key without a data item still reads, as one value.
    assert feed.values("ApplicationInstallDate") == [
        (pytest.approx(_posix(text[:28])), ("2/23/2022",))
    ]


def test_default_map_finds_the_okuma_signals(samples: Path) -> None:
    devices = parse_devices((samples / "demo_Devices_2.7.xml").read_bytes())
    mapped = resolve_map(devices, {"z_mm": "POSITION:ACTUAL@Z1"})
    assert mapped["x_mm"].item.id == "LX1actm"
    assert mapped["z_mm"].item.id == "LZ1actm"
    assert mapped["feed_mm_min"].item.id == "Lp1Fact" and mapped["feed_mm_min"].factor == 60.0
    assert convert(mapped["feed_mm_min"], "2.5") == 150.0  # 2.5 mm/s is 150 mm/min
    assert convert(mapped["run_state"], "ACTIVE") == RunState.RUNNING
    assert convert(mapped["run_state"], "PROGRAM_COMPLETED") == RunState.FINISHED
    assert convert(mapped["emergency_stop"], "TRIGGERED") == 1.0
    assert resolve_map(devices, {"x_mm": "id=X1actw"})["x_mm"].item.id == "LX1actw"
    assert "x_mm" not in resolve_map(devices, {"x_mm": "none"})
    with pytest.raises(ConfigError, match="matches no data item"):
        resolve_map(devices, {"z_mm": "POSITION:ACTUAL@W"})
    with pytest.raises(ConfigError, match="cannot feed 'x_mm'"):
        resolve_map(devices, {"x_mm": "id=Lp1Fact"})  # a feed rate is not a position
    with pytest.raises(ConfigError, match="unknown signal"):
        resolve_map(devices, {"x_position": "POSITION@X"})


# Garbage and hostile input ----------------------------------------------------------
@pytest.mark.parametrize("text", ["NaN", "nan", "INF", "-inf", "1e999", "abc", "", "0x10", "1,5"])
def test_garbage_numbers_are_rejected(text: str) -> None:
    with pytest.raises(DataError):
        number(text)


def test_garbage_values_of_mapped_items_are_rejected(samples: Path) -> None:
    devices = parse_devices((samples / "demo_Devices_2.7.xml").read_bytes())
    mapped = resolve_map(devices, {})
    line: MappedItem = mapped["program_line"]
    for bad, why in [
        ("UNAVAILABLE", "not a number"),
        ("12.5", "whole number"),
        ("-3", "plausible range"),
        ("NaN", "not a finite number"),
    ]:
        with pytest.raises(DataError, match=why):
            convert(line, bad)
    with pytest.raises(DataError, match="EXECUTION value 'RUNNING'"):
        convert(mapped["run_state"], "RUNNING")
    assert convert(line, "120") == 120.0


def test_a_document_type_declaration_is_refused() -> None:
    laughs = (
        b'<?xml version="1.0"?><!DOCTYPE lolz [<!ENTITY lol "lol">'
        b'<!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">]>'
        b"<MTConnectStreams>&lol2;</MTConnectStreams>"
    )
    with pytest.raises(DataError, match="document type"):
        parse_xml(laughs)
    external = b'<!DOCTYPE x [<!ENTITY e SYSTEM "file:///etc/passwd">]><x>&e;</x>'
    with pytest.raises(DataError, match="document type"):
        parse_xml(external)


def test_oversized_deep_and_malformed_documents_are_refused() -> None:
    with pytest.raises(DataError, match="limit"):
        parse_xml(b"<a>" + b" " * 2000 + b"</a>", max_bytes=1000)
    with pytest.raises(DataError, match="deeper"):
        parse_xml(b"<a>" * 100 + b"</a>" * 100)
    with pytest.raises(DataError, match="not well-formed"):
        parse_xml(b"<MTConnectStreams><Header></MTConnectStreams>")
    with pytest.raises(DataError, match="expected an MTConnectStreams"):
        parse_streams(b"<html><body>proxy error</body></html>")


def test_errors_of_both_generations_are_read() -> None:
    header = '<Header creationTime="2024-01-01T00:00:00Z" sender="a" instanceId="7" version="2.7"/>'
    new = (
        f"<MTConnectError xmlns='urn:mtconnect.org:MTConnectError:2.7'>{header}<Errors>"
        "<OutOfRange><QueryParameter name='from'><Value>5</Value></QueryParameter>"
        "<URI>/sample?from=5</URI><ErrorMessage>'from' must be 10..20</ErrorMessage>"
        "</OutOfRange></Errors></MTConnectError>"
    )
    with pytest.raises(AgentError) as caught:
        parse_document(new.encode())
    assert (caught.value.code, caught.value.text) == ("OUT_OF_RANGE", "'from' must be 10..20")
    assert caught.value.header is not None and caught.value.header.instance_id == 7
    old = (
        f"<MTConnectError>{header}<Errors><Error errorCode='NO_DEVICE'>Could not find the "
        "device 'x'</Error></Errors></MTConnectError>"
    )
    with pytest.raises(AgentError, match="NO_DEVICE: Could not find the device 'x'"):
        parse_devices(old.encode())


def test_shdr_lines_cut_short_or_with_bad_time_are_rejected_with_their_line() -> None:
    devices_xml = (
        "<MTConnectDevices><Header instanceId='1' version='2.7' sender='a' "
        "creationTime='2024-01-01T00:00:00Z'/><Devices><Device name='d' id='d'><DataItems>"
        "<DataItem id='c' type='SYSTEM' category='CONDITION'/>"
        "<DataItem id='m' type='MESSAGE' category='EVENT'/>"
        "</DataItems></Device></Devices></MTConnectDevices>"
    )
    devices = parse_devices(devices_xml.encode())
    feed = parse_shdr(
        [
            "2024-01-01T00:00:00Z|x|1|c|FAULT|E1|2|HIGH|overheat|y|2",
            "yesterday|x|1",
            "2024-01-01T00:00:01Z|c|FAULT|E1",
            "2024-01-01T00:00:02Z|m|17|door open|x|3",
            "2024-01-01T00:00:03Z|@ASSET@|a1|CuttingTool|--multiline--Q",
            "<CuttingTool/>",
        ],
        devices,
    )
    assert [(r.key, r.fields) for r in feed.records] == [
        ("x", ("1",)),
        ("c", ("FAULT", "E1", "2", "HIGH", "overheat")),
        ("y", ("2",)),
        ("m", ("17", "door open")),
        ("x", ("3",)),
    ]
    assert [why.split(":")[0] for why in feed.rejected] == ["line 2", "line 3", "line 5"]
    assert "not closed" in feed.rejected[2]


def test_timestamps_and_element_names() -> None:
    assert parse_timestamp("2022-08-08T13:51:34.7167146Z") == pytest.approx(
        _posix("2022-08-08T13:51:34.7167146Z"), abs=1e-6
    )
    assert parse_timestamp("2021-02-11T20:45:18") == _posix("2021-02-11T20:45:18")
    assert parse_timestamp("2024-01-01T01:00:00+01:00") == _posix("2024-01-01T00:00:00")
    for bad in ("2024-13-01T00:00:00Z", "now", "2024-01-01 00:00:00"):
        with pytest.raises(DataError, match="timestamp"):
            parse_timestamp(bad)
    assert element_type("PathFeedrateOverride") == "PATH_FEEDRATE_OVERRIDE"
    assert element_type("x:ToolGroup") == "TOOL_GROUP"
    assert element_type("PH") == "PH"


def test_selectors() -> None:
    sel = parse_selector("POSITION:ACTUAL@X", "x_mm")
    assert (sel.type, sel.sub_type, sel.component, sel.key) == ("POSITION", "ACTUAL", "X", None)
    assert parse_selector("id=Xabs", "x_mm").key == "Xabs"
    for bad in ("position", "", "id=", "POS ITION"):
        with pytest.raises(ConfigError, match="x_mm"):
            parse_selector(bad, "x_mm")
