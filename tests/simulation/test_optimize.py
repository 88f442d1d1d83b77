"""The optimised program (issue 16, item 5): feeds from the limits, the path unchanged.

Independent references: the full-slot mean force of Altintas (2012, Eq. 2.39 integrated over
a slot by hand here), solved for the feed that meets a force limit; the path of the original
program as the interpreter reads it (every split point on it, every end point the same);
LinuxCNC's ``rs274`` reading the optimised program (same moves and feeds as cnctwin's
interpreter, where it is installed); ``cnctwin signals``' own prediction
(:func:`~cnctwin.simulation.predict_program_signals`, sampled its own way) of the optimised
program against the limit.
"""

from __future__ import annotations

import math
import re
import shutil
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from cnctwin.config import load_config
from cnctwin.errors import InputError
from cnctwin.mechanics import CuttingCoefficients
from cnctwin.mechanics.materials import milling_material
from cnctwin.nc import Interpreter, MotionKind, Segment
from cnctwin.optimize import FeedLimits, OptimizedProgram, force_feed_limit, optimize_program
from cnctwin.optimize.rewrite import read_block, set_words, split_block
from cnctwin.simulation import predict_program_signals

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "src" / "cnctwin" / "examples"
DEMO, DEMO_CONFIG = EXAMPLES / "demo.ngc", EXAMPLES / "demo.toml"
FORCE_N = 150.0

SLOT_CONFIG = """
[machine]
rapid_mm_min = 10000.0
[[tools]]
number = 1
kind = "flat"
diameter_mm = 10.0
flutes = 4
helix_deg = 0.0
flute_length_mm = 20.0
[stock]
kind = "box"
min_mm = [0.0, 0.0, -10.0]
max_mm = [60.0, 30.0, 0.0]
[material]
name = "AA6060-T6"
[simulation]
density_per_mm = 10.0
cycle_ms = 12.5
"""
SLOT_PROGRAM = """G21 G90 G94 G17
T1 M6
S6000 M3
G0 X-10 Y15 Z5
G0 Z-2
G1 X70 F600
G0 Z5
M30
"""


@pytest.fixture(scope="module")
def demo() -> OptimizedProgram:
    config = load_config(DEMO_CONFIG)
    return optimize_program(
        DEMO.read_text(), str(DEMO), config, FeedLimits(max_force_n=FORCE_N),
        coefficients=milling_material(config.material.name).coefficients,
        density_per_mm=config.simulation.density_per_mm, cycle_s=config.simulation.cycle_ms / 1e3,
    )  # fmt: skip


def test_slot_feed_is_the_closed_form_feed_of_the_mean_force_limit(tmp_path: Path) -> None:
    # Full slot, 4 teeth, a = 2 mm: per Altintas Eq. 2.39 over phi in [0, pi], the mean force
    # components are N a (Krc fz/4 + Kre/pi), N a (Ktc fz/4 + Kte/pi), N a (Kac fz/pi + Kae/2).
    n_teeth, depth_mm, rpm, limit_n = 4, 2.0, 6000.0, 120.0
    k = {"ktc": 800.0, "krc": 300.0, "kac": 100.0, "kte": 20.0, "kre": 15.0, "kae": 5.0}
    p = np.array([k["krc"] / 4, k["ktc"] / 4, k["kac"] / math.pi]) * n_teeth * depth_mm
    q = np.array([k["kre"] / math.pi, k["kte"] / math.pi, k["kae"] / 2]) * n_teeth * depth_mm
    a2, ab, c = p @ p, p @ q, q @ q - limit_n**2
    fz_mm = (-ab + math.sqrt(ab * ab - a2 * c)) / a2
    expected = fz_mm * n_teeth * rpm
    (tmp_path / "slot.toml").write_text(SLOT_CONFIG)
    config = load_config(tmp_path / "slot.toml")
    coefficients = CuttingCoefficients.from_n_mm(*k.values())
    result = optimize_program(
        SLOT_PROGRAM, "slot.ngc", config, FeedLimits(max_force_n=limit_n, force_metric="mean"),
        coefficients=coefficients, density_per_mm=10.0, cycle_s=0.0125,
    )  # fmt: skip
    plan = result.blocks[6]
    # The pieces in the cut (not in the air before and after it): the slowest is the slot's.
    slowest = min((p for p in plan.pieces if p[2] != "air"), key=lambda piece: piece[1])
    assert slowest[2] == "force"
    assert slowest[1] == pytest.approx(expected, rel=0.03)
    assert expected > 600.0  # the limit raises the programmed F600
    assert result.limits_hold
    assert result.maxima(result.after)["max_mean_force_n"] <= limit_n
    # The steady slot is written at that feed (3 significant digits, rounded down).
    written = [float(f) for f in re.findall(r"^G1 X[-.0-9]+ F([.0-9]+)$", result.text, re.M)]
    assert [f for f in written if f == pytest.approx(expected, rel=0.03)]


def test_force_feed_limit_solves_the_quadratic() -> None:
    # |f a + b| = L with a = (3, 4), b = (0, 5): (3f)^2 + (4f + 5)^2 = 25^2 -> f = 3.4.
    a = np.array([[3.0, 4.0, 0.0]])
    b = np.array([[0.0, 5.0, 0.0]])
    assert force_feed_limit(a, b, 25.0) == pytest.approx((-20 + math.sqrt(400 + 25 * 600)) / 25)
    assert force_feed_limit(a, b, 4.0) == 0.0  # the edge force alone exceeds the limit
    assert force_feed_limit(np.zeros((1, 3)), b, 25.0) == math.inf


def test_demo_limits_hold_and_signals_agree(demo: OptimizedProgram, tmp_path: Path) -> None:
    assert demo.limits_hold
    assert demo.maxima(demo.before)["max_force_n"] > FORCE_N  # the limit does bind
    assert demo.maxima(demo.after)["max_force_n"] <= FORCE_N
    path = tmp_path / "demo_opt.ngc"
    path.write_text(demo.text)
    config = load_config(DEMO_CONFIG)
    signals = predict_program_signals(path, config, density_per_mm=10.0, cycle_s=0.0125)
    # cnctwin signals samples block ends its own way (a step may span two feed blocks):
    # within 2 % of the limit.
    assert signals.summary()["max_force_n"] <= FORCE_N * 1.02


def _segments(text: str) -> list[Segment]:
    config = load_config(DEMO_CONFIG)
    return list(Interpreter(config.nc_setup()).run_text(text, "demo"))


def test_demo_path_is_the_original_path(demo: OptimizedProgram) -> None:
    original = _segments(DEMO.read_text())
    optimised = _segments(demo.text)
    rapids = [(s.start_mm, s.end_mm) for s in original if s.kind == MotionKind.RAPID]
    assert rapids == [(s.start_mm, s.end_mm) for s in optimised if s.kind == MotionKind.RAPID]
    feeds = (MotionKind.LINEAR, MotionKind.ARC)
    pieces: dict[int, list[Segment]] = {}
    for seg in optimised:
        if seg.kind in feeds:
            pieces.setdefault(demo.origin[seg.line], []).append(seg)
    split = 0
    for seg in (s for s in original if s.kind in feeds):
        mine = pieces[seg.line]
        if seg.line in {62, 63, 64, 65}:  # canned cycles: several feeds a line
            continue
        split += len(mine) > 1
        np.testing.assert_allclose(mine[0].start_mm, seg.start_mm, atol=1e-9)
        np.testing.assert_allclose(mine[-1].end_mm, seg.end_mm, atol=1e-9)
        for piece in mine[:-1]:
            end = np.asarray(piece.end_mm)
            start, stop = np.asarray(seg.start_mm), np.asarray(seg.end_mm)
            if seg.kind == MotionKind.ARC:
                assert seg.center_mm is not None and piece.center_mm is not None
                np.testing.assert_allclose(piece.center_mm, seg.center_mm, atol=1e-3)
                radius = math.dist(start[:2], seg.center_mm[:2])
                assert math.dist(end[:2], seg.center_mm[:2]) == pytest.approx(radius, abs=1e-3)
            else:
                d = stop - start
                t = float((end - start) @ d / (d @ d))
                assert -1e-9 <= t <= 1 + 1e-9
                assert np.linalg.norm(start + t * d - end) < 1e-3
    assert split >= 3  # the demo's long blocks are split


def _rs274() -> tuple[Any, str]:
    """The rs274 oracle module of tests/nc and LinuxCNC's ``rs274`` (skip without it)."""
    sys.path.insert(0, str(ROOT / "tests" / "nc"))
    try:
        import rs274_oracle
    finally:
        sys.path.remove(str(ROOT / "tests" / "nc"))
    executable = shutil.which("rs274")
    if executable is None:
        pytest.skip("LinuxCNC's rs274 is not installed (apt-get install linuxcnc-uspace)")
    return rs274_oracle, executable


def test_demo_program_is_read_alike_by_linuxcnc(demo: OptimizedProgram, tmp_path: Path) -> None:
    rs274_oracle, executable = _rs274()
    path = tmp_path / "demo_opt.ngc"
    path.write_text(demo.text)
    theirs = rs274_oracle.run_rs274(executable, path)
    ours = rs274_oracle.run_cnctwin(path)
    assert not theirs.error and not ours.error
    assert rs274_oracle.first_difference(ours, theirs) == ""
    # rs274 reads the optimised feeds, not only the programmed ones.
    feeds = {round(f) for _, _, f in theirs.moves if f is not None}
    assert feeds - {200, 300, 400, 600, 800}


def test_demo_keeps_comments_and_marks_split_blocks(demo: OptimizedProgram) -> None:
    lines = demo.text.splitlines()
    for raw in DEMO.read_text().splitlines():
        if raw.startswith("(") and raw.endswith(")"):
            assert raw in lines
    assert any(line.startswith("(cnctwin optimize: line ") for line in lines)


def test_drill_cycles_keep_their_feed(demo: OptimizedProgram) -> None:
    optimised = _segments(demo.text)
    cycles = [s for s in optimised if demo.origin[s.line] in {62, 63, 64, 65}]
    assert {s.feed_mm_min for s in cycles if s.kind == MotionKind.LINEAR} == {200.0}


def test_rewrite_keeps_dialect_and_block_numbers() -> None:
    block = read_block("N120 G1 X30 Y40 ; Siemens comment")
    assert block is not None
    assert set_words(block, {"F": "420"}) == "N120 G1 X30 Y40 F420 ; Siemens comment"
    lines = split_block(block, [({"X": "15", "Y": "20"}, {"F": "420"}), ({}, {"F": "300"})], ";",
                        "cnctwin optimize")  # fmt: skip
    assert lines == [
        "; cnctwin optimize: N120 G1 X30 Y40 ; Siemens comment",
        "N120 G1 X15 Y20 F420",
        "G1 X30 Y40 F300",
    ]
    assert read_block("G1 X[#1 + 2]") is None  # expressions are not rewritten
    assert read_block("IF R1 > 2 GOTOF END") is None
    compact = read_block("g1x1y2f300(comment)")
    assert compact is not None
    assert set_words(compact, {"F": "250"}) == "g1x1y2f250(comment)"


def test_bad_limits_are_refused() -> None:
    with pytest.raises(InputError, match="no limit"):
        FeedLimits()
    with pytest.raises(InputError, match="max_force_n"):
        FeedLimits(max_force_n=-1.0)
    with pytest.raises(InputError, match="force_metric"):
        FeedLimits(max_force_n=1.0, force_metric="rms")  # type: ignore[arg-type]


def test_a_program_that_loops_is_refused(tmp_path: Path) -> None:
    (tmp_path / "slot.toml").write_text(SLOT_CONFIG)
    config = load_config(tmp_path / "slot.toml")
    looping = (
        "G21 G90 T1 M6 S6000 M3\nG0 X-10 Y15 Z5\no100 repeat [2]\nG1 X70 F600\nG1 X-10\n"
        "o100 endrepeat\nM30\n"
    )
    with pytest.raises(InputError, match="runs again"):
        optimize_program(
            looping, "loop.ngc", config, FeedLimits(max_force_n=300.0),
            coefficients=CuttingCoefficients.from_n_mm(800, 300), density_per_mm=5.0,
            cycle_s=0.0125,
        )  # fmt: skip


def test_slot_feed_meets_the_closed_form_peak_force(tmp_path: Path) -> None:
    # Four straight teeth in a full slot without edge forces: two teeth 90 degrees apart cut at
    # any time and their sin(2 phi) terms cancel, so the force is constant at
    # a f_z (Krc, Ktc) in x and y (Altintas 2012, Eq. 2.10 summed): peak = a f_z |(Ktc, Krc)|.
    depth_mm, rpm, limit_n = 2.0, 6000.0, 60.0
    expected = limit_n / (depth_mm * math.hypot(800.0, 300.0)) * 4 * rpm
    (tmp_path / "slot.toml").write_text(SLOT_CONFIG)
    config = load_config(tmp_path / "slot.toml")
    result = optimize_program(
        SLOT_PROGRAM, "slot.ngc", config, FeedLimits(max_force_n=limit_n),
        coefficients=CuttingCoefficients.from_n_mm(800.0, 300.0), density_per_mm=10.0,
        cycle_s=0.0125,
    )  # fmt: skip
    slowest = min((p for p in result.blocks[6].pieces if p[2] != "air"), key=lambda p: p[1])
    assert slowest[2] == "force"
    assert slowest[1] == pytest.approx(expected, rel=0.03)
    assert result.limits_hold


def test_fusion_program_keeps_its_path_for_linuxcnc(shared_data: Path, tmp_path: Path) -> None:
    # A real Fusion 360 post (grbl style: modal axis words without G, F on its own blocks),
    # rewritten for a chip limit above its programmed chip (feeds rise where the cut allows).
    program = shared_data / "gcode" / "fusion360_grbl_shooshx" / "1024_block_14bit.nc"
    config = load_config(ROOT / "examples" / "fusion360" / "1024_block_14bit.toml")
    result = optimize_program(
        program.read_text(), str(program), config, FeedLimits(max_chip_mm=0.12),
        coefficients=milling_material("AA6060-T6").coefficients,
        density_per_mm=config.simulation.density_per_mm, cycle_s=config.simulation.cycle_ms / 1e3,
    )  # fmt: skip
    assert result.limits_hold
    assert result.summary()["cycle_time_after_s"] < result.summary()["cycle_time_before_s"]
    before = [s.end_mm for s in Interpreter(config.nc_setup()).run_text(program.read_text())]
    after = [s.end_mm for s in Interpreter(config.nc_setup()).run_text(result.text)]
    assert set(before) <= set(after)  # every original end point is still programmed
    rs274_oracle, executable = _rs274()
    path = tmp_path / "opt.nc"
    path.write_text(result.text)
    theirs = rs274_oracle.run_rs274(executable, path)
    ours = rs274_oracle.run_cnctwin(path)
    assert not theirs.error and not ours.error
    assert rs274_oracle.first_difference(ours, theirs) == ""
