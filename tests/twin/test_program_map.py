"""The twin's tool offset by program line (:class:`cnctwin.twin.program.ProgramMap`).

Expected offsets are written out by hand from the program and demo.toml's tool lengths
(T1 75 mm, T2 110 mm): G43.1 sets the offset it names, G43 H2 tool 2's length, G49 none; a
line that does not move, or a tool other than the program's there, gets the tool's length.
"""

from __future__ import annotations

import tracemalloc
from importlib.resources import as_file, files
from pathlib import Path

import pytest

from cnctwin.config import MachiningConfig, load_config
from cnctwin.twin.program import ProgramMap

PROGRAM = """G21 G90 G17 G94
T1 M6 G43.1 Z5
G0 X10 Y10 Z5
G1 Z-1 F500
o100 repeat [2]
  G1 X20
  G43.1 Z6
o100 endrepeat
M5
T2 M6
G43 H2
G0 X30 Y30 Z5
G49
G0 Z10
M30
"""

#: Line -> offset of the tool the program has there (line 6: its last pass, after G43.1 Z6).
MOVES = {
    3: (1, (0.0, 0.0, 5.0)),
    4: (1, (0.0, 0.0, 5.0)),
    6: (1, (0.0, 0.0, 6.0)),
    12: (2, (0.0, 0.0, 110.0)),
    14: (2, (0.0, 0.0, 0.0)),
}
LENGTH = {1: (0.0, 0.0, 75.0), 2: (0.0, 0.0, 110.0)}


@pytest.fixture(scope="module")
def config() -> MachiningConfig:
    with as_file(files("cnctwin.examples")) as folder:
        return load_config(Path(folder) / "demo.toml")


def test_offsets_by_line_match_the_program(config: MachiningConfig) -> None:
    program = ProgramMap(config, text=PROGRAM)
    for line in range(-2, 20):
        for tool in (1, 2):
            known = MOVES.get(line)
            expected = known[1] if known and known[0] == tool else LENGTH[tool]
            assert program.offset_mm(line, tool) == expected, (line, tool)
    assert program.offset_mm(3, 9) == (0.0, 0.0, 0.0)  # a tool the configuration lacks


def test_without_a_program_the_tool_length_is_assumed(config: MachiningConfig) -> None:
    program = ProgramMap(config)
    assert program.offset_mm(3, 1) == LENGTH[1]
    assert program.offset_mm(3, 2) == LENGTH[2]


def test_memory_kept_is_a_few_bytes_a_line(config: MachiningConfig, tmp_path: Path) -> None:
    """20,000 moving lines keep under 16 bytes each (a dict entry per line: over 100)."""
    lines = 20_000
    path = tmp_path / "long.ngc"
    moves = "".join(f"G1 X{k % 50} Y{k % 7}\n" for k in range(lines))
    path.write_text(f"G21 G90\nT1 M6 G43 H1\nG0 X0 Y0 Z5\nG1 Z-1 F800\n{moves}M30\n")
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        program = ProgramMap(config, path)
        kept = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert program.offset_mm(lines, 1) == LENGTH[1]  # G43 H1: tool 1's own length
    assert kept < 16 * lines, kept
