"""LinuxCNC tool tables: hand-written ones and the real ones of LinuxCNC's interpreter tests."""

from __future__ import annotations

import re

import pytest

from cnctwin.errors import DataError
from cnctwin.nc.setup import ToolEntry
from cnctwin.nc.tool_table import parse_tool_table, read_tool_table


def test_words_comments_and_blank_lines() -> None:
    text = (
        "\n; a comment line\nT1 P1 Z0.5 D0.0625;first tool\n   \nt4 p4 z-2 x1.5 d6 ; lower case\n"
    )
    tools = parse_tool_table(text)
    assert tools == {
        1: ToolEntry(number=1, length_mm=0.5, x_offset_mm=0.0, diameter_mm=0.0625),
        4: ToolEntry(number=4, length_mm=-2.0, x_offset_mm=1.5, diameter_mm=6.0),
    }


def test_inch_lengths_are_converted_to_mm_and_angles_are_not() -> None:
    tools = parse_tool_table("T2 P2 Z1 X-0.5 D0.25 I95 J155 Q3 A10", units="inch")
    assert tools[2] == ToolEntry(
        number=2, length_mm=25.4, x_offset_mm=-12.7, diameter_mm=6.35, orientation=3
    )


def test_only_the_tool_word_is_required() -> None:
    assert parse_tool_table("T7") == {7: ToolEntry(number=7)}


@pytest.mark.parametrize(
    ("line", "expected"),
    [
        ("T1 P1 K3", r"tbl:2: unknown word 'K3'; valid letters: T P X Y Z"),
        ("T1 Zabc", r"tbl:2: Z needs a number; got 'Zabc'"),
        ("T1 Z", r"tbl:2: Z needs a number; got 'Z'"),
        ("P3 Z1", r"tbl:2: no T word"),
        ("T1.5 Z1", r"tbl:2: T needs a whole number; got 'T1.5'"),
        ("T-1", r"tbl:2: T must be >= 0; got 'T-1'"),
        ("T1 Q12", r"tbl:2: Q must be 0 to 9; got 'Q12'"),
        ("T1 Z1 Z2", r"tbl:2: word Z appears twice"),
        ("T1 D-3", r"tbl:2: diameter D must be >= 0; got 'D-3'"),
        ("T1 Dnan", r"tbl:2: D must be finite; got 'Dnan'"),
        ("T9 Z1", r"tbl:2: tool T9 is already defined on line 1"),
    ],
)
def test_bad_lines_name_file_line_and_word(line: str, expected: str) -> None:
    with pytest.raises(DataError, match="^" + re.escape(expected)):
        parse_tool_table(f"T9 P9\n{line}\n", source="tbl")


def test_units_must_be_mm_or_inch() -> None:
    with pytest.raises(DataError, match=r"units must be 'mm' or 'inch'; got 'cm'"):
        parse_tool_table("T1", units="cm")  # type: ignore[arg-type]


def test_unreadable_file_is_a_data_error(tmp_path) -> None:
    missing = tmp_path / "none.tbl"
    with pytest.raises(DataError, match=f"^{re.escape(str(missing))}: cannot read tool table"):
        read_tool_table(missing)
    binary = tmp_path / "binary.tbl"
    binary.write_bytes(b"T1 \xff\xfe")
    with pytest.raises(DataError, match="not UTF-8 text"):
        read_tool_table(binary)


@pytest.mark.validation
def test_every_linuxcnc_golden_tool_table_reads(shared_data) -> None:
    tables = sorted((shared_data / "gcode_golden" / "linuxcnc").glob("**/test.tbl"))
    assert len(tables) >= 10, "expected the 10 tool tables of LinuxCNC's interpreter tests"
    for table in tables:
        tools = read_tool_table(table, units="inch")
        text = table.read_text()
        numbers = [int(m) for m in re.findall(r"^\s*T(\d+)", text, re.MULTILINE | re.IGNORECASE)]
        assert sorted(tools) == sorted(numbers), table


@pytest.mark.validation
def test_golden_tables_values_in_mm(shared_data) -> None:
    root = shared_data / "gcode_golden" / "linuxcnc"
    mill = read_tool_table(root / "ccomp" / "mill-g90g91g92" / "test.tbl", units="inch")
    # "T4 P4 Z0.7 D1.0;" in inch
    assert mill[4] == ToolEntry(number=4, length_mm=0.7 * 25.4, diameter_mm=25.4)
    assert sorted(mill) == [1, 2, 3, 4, 32]
    lathe = read_tool_table(root / "ccomp" / "lathe-comp" / "test.tbl", units="mm")
    # "T6 P6 Z0.5 X0.5 D0.1 I120.0 J60.0 Q6;"
    assert lathe[6] == ToolEntry(
        number=6, length_mm=0.5, x_offset_mm=0.5, diameter_mm=0.1, orientation=6
    )
    assert len(lathe) == 19
