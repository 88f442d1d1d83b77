"""LinuxCNC interpreter oracles: our canonical moves must match LinuxCNC's traces.

Each oracle folder in ``gcode_golden/linuxcnc`` holds an ``.ngc`` program and
``expected``, the canonical calls LinuxCNC's interpreter made for it. We compare every
STRAIGHT_TRAVERSE, STRAIGHT_FEED and ARC_FEED in order. The traces print 4 decimals,
so values agree within 1.5e-4 program units (half a printed digit plus float noise).
Oracles for constructs cnctwin rejects on purpose must be rejected with an error that
names the construct and a line.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import pytest

from cnctwin.errors import NCError
from cnctwin.nc.interpreter import Interpreter
from cnctwin.nc.setup import NCSetup
from cnctwin.nc.tool_table import read_tool_table
from cnctwin.nc.trace import canonical_moves

pytestmark = pytest.mark.validation

TOLERANCE = 1.5e-4
_MOVES = ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "ARC_FEED")
_CALL = re.compile(r"^\s*(?:\d+\s+)?N\.+\s+([A-Z_]+)\((.*)\)\s*$")

#: Oracles of constructs rejected on purpose, with a phrase the error must contain.
REJECTED = {
    "interp/g71-with-g70": "G71",
    "interp/g72-facing": "G72",
    "interp/g76": "G76",
}

#: Oracles whose expected trace depends on an INI setting, not on the program alone.
NOT_COMPARABLE = {
    "interp/g52/g92-offset-persistence": "result depends on the persistent-G92 INI setting",
    "interp/rotation/abs-pts": "the oracle records #<_abs_x> messages only, no moves",
}

#: Oracles recorded from a LinuxCNC whose G84 in G18/G19 feeds to the hole bottom with
#: its coordinates permuted (the tap would leave the hole axis). cnctwin taps along the
#: plane normal; for these feed moves we check the same numbers appear, permuted.
PERMUTED_G84_FEEDS = {
    "interp/g84/g18/g98",
    "interp/g84/g18/g99",
    "interp/g84/g19/g98",
    "interp/g84/g19/g99",
}


def _oracles(root: Path) -> list[Path]:
    return sorted(p.parent for p in root.rglob("expected"))


def _expected_moves(path: Path) -> list[tuple[str, list[float]]]:
    moves = []
    for raw in path.read_text().splitlines():
        found = _CALL.match(raw)
        if found and found.group(1) in _MOVES:
            moves.append((found.group(1), [float(v) for v in found.group(2).split(",")]))
    return moves


def _program(folder: Path) -> Path:
    programs = sorted(folder.glob("*.ngc"))
    assert len(programs) == 1, f"expected one .ngc in {folder}, found {programs}"
    return programs[0]


def _setup(folder: Path, program: Path) -> NCSetup:
    table = folder / "test.tbl"
    if not table.exists():
        return NCSetup()
    # The oracles' tool tables are in inches: cam-nisley, a G21 program, compensates
    # T1 "D0.0625" by 0.79375 mm.
    return NCSetup(tools=read_tool_table(table, units="inch"))


@pytest.fixture(scope="module")
def golden_root(shared_data: Path) -> Path:
    return shared_data / "gcode_golden" / "linuxcnc"


def _ids(root: Path) -> list[str]:
    return [str(p.relative_to(root)) for p in _oracles(root)]


ORACLES = [
    "ccomp/lathe-comp",
    "ccomp/mill-g90g91g92",
    "ccomp/mill-line-arc-entry",
    "ccomp/mill-zchanges",
    "interp/cam-nisley",
    "interp/crazy-paths",
    "interp/g10/g10-l1-l10",
    "interp/g10/g10-l11",
    "interp/g10/g10-l2-while-active",
    "interp/g10/g10-l20-while-active",
    "interp/g10/g10-with-g92",
    "interp/g52/g52-g92-interaction",
    "interp/g52/g92-offset-persistence",
    "interp/g71-with-g70",
    "interp/g72-facing",
    "interp/g76",
    "interp/g81/g17/g98",
    "interp/g81/g17/g99",
    "interp/g81/g18/g98",
    "interp/g81/g18/g99",
    "interp/g81/g19/g98",
    "interp/g81/g19/g99",
    "interp/g84/g17/g98",
    "interp/g84/g17/g99",
    "interp/g84/g18/g98",
    "interp/g84/g18/g99",
    "interp/g84/g19/g98",
    "interp/g84/g19/g99",
    "interp/inside-corners",
    "interp/rotation/abs-pts",
    "interp/rotation/g28",
    "interp/rotation/g53",
    "interp/unit-conversion",
]


def test_every_oracle_is_listed(golden_root: Path) -> None:
    assert _ids(golden_root) == ORACLES


@pytest.mark.parametrize("name", ORACLES)
def test_oracle(golden_root: Path, name: str) -> None:
    folder = golden_root / name
    if name in NOT_COMPARABLE:
        pytest.skip(NOT_COMPARABLE[name])
    program = _program(folder)
    interp = Interpreter(_setup(folder, program))
    if name in REJECTED:
        with pytest.raises(NCError) as info:
            list(interp.run_file(program))
        assert info.value.line > 0
        assert REJECTED[name].lower() in str(info.value).lower()
        return
    ours = [m for m in canonical_moves(interp.run_file(program)) if m.name in _MOVES]
    expected = _expected_moves(folder / "expected")
    for index, (move, (name_exp, values_exp)) in enumerate(zip(ours, expected, strict=False)):
        where = f"move {index + 1} (our line {move.line}): ours {move.format()}"
        assert move.name == name_exp, f"{where}; LinuxCNC {name_exp}{tuple(values_exp)}"
        assert len(move.values) == len(values_exp), where
        if name in PERMUTED_G84_FEEDS and name_exp == "STRAIGHT_FEED":
            values_exp = sorted(values_exp)
            move = replace(move, values=tuple(sorted(move.values)))
        for ours_v, exp_v in zip(move.values, values_exp, strict=True):
            assert abs(ours_v - exp_v) <= TOLERANCE, (
                f"{where}; LinuxCNC {name_exp}({', '.join(f'{v:.4f}' for v in values_exp)})"
            )
    assert len(ours) == len(expected), f"{len(ours)} moves, LinuxCNC made {len(expected)}"
