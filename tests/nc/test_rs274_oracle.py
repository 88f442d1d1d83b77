"""cnctwin against LinuxCNC's own interpreter (``rs274``) on every real program.

Each program in ``../shared/data/gcode`` runs through both interpreters with the same tool
table; traverses, feeds and arcs (end points, arc centres, turns), the feed rate of every
feed move and the number of moves must agree. Programs rs274 cannot read (other controls'
dialects) or that cnctwin refuses on purpose are listed with the reason; the full list of
departures is in docs/nc.md. Without rs274 the tests skip, and fail in CI
(``CNCTWIN_REQUIRE_SERVICES=1``); ``.ci/run`` installs it.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from rs274_oracle import first_difference, rs274_fixture, run_cnctwin, run_rs274

__all__ = ["rs274_fixture"]  # the fixture, used by name

pytestmark = pytest.mark.validation

_NURBS = "rs274 prints G5.1 splines as NURBS_FEED calls without coordinates; cnctwin cuts lines"

#: Programs not compared move for move, with the reason.
NOT_COMPARED = {
    "haas_style_enier/1006.nc": "Haas dialect: rs274 refuses M31 (Haas parts counter)",
    "haas_style_enier/lathe_hp_2.nc": "Haas lathe dialect (G50 spindle clamp, G71), lathe set-up",
    "haas_style_enier/o20013.nc": "Haas lathe dialect (G50 spindle clamp), lathe set-up",
    "haas_style_enier/weld_pin.nc": "Haas lathe dialect (G50 spindle clamp, G71), lathe set-up",
    "linuxcnc/lathe-g76.ngc": "cnctwin refuses the G76 threading cycle on purpose",
    "linuxcnc/lathe_g70_71_demo.ngc": "cnctwin refuses the G70/G71 lathe cycles on purpose",
    "linuxcnc/lathe_g7x_quadrants.ngc": "cnctwin refuses the G70/G71 lathe cycles on purpose",
    "linuxcnc/systems.ngc": _NURBS,
    "siemens_kit_dmc60h/AL_2007_T4_Notch_Normal.mpf": "Sinumerik dialect (G710, ';' comments)",
    "siemens_kit_dmc60h/AL_2007_T4_Plate_Normal.mpf": "Sinumerik dialect (G710, ';' comments)",
}

#: Programs that agree up to a known departure (docs/nc.md), with the move it is at:
#: the moves before are compared, and the first difference must be that move.
DEPARTS_AT = {
    # "G91 G81 @1 R.1 Z-0.5 L5": polar coordinates in an incremental canned cycle.
    "linuxcnc/polar.ngc": 15,
}

#: Programs whose last line rs274 (run without a GUI) stops on, with its message: a '%'
#: that closes no opening '%', or the end of a file without M2/M30/'%' (cnctwin warns for
#: those). Every move before is compared.
STOPS_AT_END = {
    "camotics/compass/compass.ngc": "Bad character '%' used",
    "camotics/heart/cutout.ngc": "File ended with no percent sign or program end",
    "camotics/heart/heart.ngc": "File ended with no percent sign or program end",
    "camotics/slant_test/slant_test.nc": "File ended with no percent sign or program end",
}

_SUFFIXES = {".nc", ".ngc", ".gcode", ".mpf"}


def _programs(root: Path) -> list[str]:
    return sorted(
        str(p.relative_to(root)) for p in root.rglob("*") if p.suffix.lower() in _SUFFIXES
    )


def test_every_program_is_compared_or_listed(shared_data: Path) -> None:
    programs = _programs(shared_data / "gcode")
    assert len(programs) >= 30, programs
    assert set(NOT_COMPARED) <= set(programs)


def test_programs_agree_with_linuxcnc(shared_data: Path, rs274: str) -> None:
    root = shared_data / "gcode"
    compared, differences = 0, []
    for name in _programs(root):
        if name in NOT_COMPARED:
            continue
        theirs = run_rs274(rs274, root / name)
        ours = run_cnctwin(root / name)
        if name in STOPS_AT_END and STOPS_AT_END[name] in theirs.error:
            theirs.error = ""
            ours.moves = ours.moves[: len(theirs.moves)]
        if ours.error or theirs.error or not theirs.moves:
            differences.append(f"{name}: cnctwin: {ours.error!r}, rs274: {theirs.error!r}")
        elif name in DEPARTS_AT:
            found = first_difference(ours, theirs)
            if not found.startswith(f"move {DEPARTS_AT[name]}:"):
                differences.append(
                    f"{name}: expected to depart at move {DEPARTS_AT[name]}: {found}"
                )
        elif found := first_difference(ours, theirs):
            differences.append(f"{name}: {found}")
        compared += 1
    assert differences == [], "\n".join(differences)
    assert compared >= 20
