"""``cnctwin stability lobes``: the example configurations, modes files, options and errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from cnctwin.cli import stability
from cnctwin.dynamics.config import load_stability_config
from cnctwin.errors import InputError

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "stability"
LISTS = ["spindle_rpm", "critical_depth_mm", "chatter_frequency_hz", "bifurcation"]

SLOT_MODES = """
[[modes]]
direction = "x"
fn_hz = 922.0
damping_ratio = 0.011
stiffness_n_m = 1340049.648
"""


def invoke(args: list[str]) -> tuple[int, str, BaseException | None]:
    app = typer.Typer()
    app.add_typer(stability.app, name="stability")
    result = CliRunner().invoke(app, ["stability", "lobes", *args])
    return result.exit_code, result.stdout, result.exception


def run_json(args: list[str]) -> dict:
    code, out, error = invoke([*args, "--json"])
    assert (code, error) == (0, None), out
    return json.loads(out)


TOOL_MAPS = {"demo_tools.toml"}  # stability files by tool number, for the roadmap
STABILITY_FILES = sorted(p.name for p in EXAMPLES.glob("*.toml") if p.name not in TOOL_MAPS)


@pytest.mark.parametrize("name", STABILITY_FILES)
def test_examples_are_valid(name: str) -> None:
    config = load_stability_config(EXAMPLES / name)
    assert config.tool_dynamics().modes
    config.process()


def test_the_tool_map_example_names_stability_files() -> None:
    from cnctwin.dynamics import load_tool_stability

    loaded = load_tool_stability(EXAMPLES / "demo_tools.toml")
    assert isinstance(loaded, dict) and list(loaded) == [1]
    assert loaded[1] == load_stability_config(EXAMPLES / "ubc_two_mode.toml")
    assert load_tool_stability(EXAMPLES / "insperger_slot.toml") == load_stability_config(
        EXAMPLES / "insperger_slot.toml"
    )


def test_orthogonal_example_reproduces_the_textbook_limit() -> None:
    # NOTES.md section 4: absolute critical depth 7.185 mm at 253 Hz.
    report = run_json(["--config", str(EXAMPLES / "orthogonal_2dof.toml"), "--points", "120"])
    assert len({len(report[key]) for key in LISTS}) == 1
    assert len(report["spindle_rpm"]) == 120
    assert report["spindle_rpm"][0] == 2000.0 and report["spindle_rpm"][-1] == 14000.0
    assert report["absolute_depth_mm"] == pytest.approx(7.185, abs=5e-4)
    assert report["absolute_chatter_frequency_hz"] == pytest.approx(252.98, abs=0.01)
    assert 7.185 <= report["min_critical_depth_mm"] < 7.185 * 1.01
    assert report["method"] == "zoa" and report["operation"] == "orthogonal"


def test_modes_file_with_options_gives_the_slot_closed_form(tmp_path: Path) -> None:
    # NOTES.md section 1: 1-DOF slot, ZOA a = 2 k zeta (1 + zeta) / (N Kn / 4) = 0.298 mm.
    modes = tmp_path / "tool.toml"
    modes.write_text(SLOT_MODES)
    args = ["--modes-file", str(modes), "--teeth", "2", "--ktc", "600", "--krc", "200"]
    report = run_json([*args, "--immersion", "1", "--method", "zoa", "--rpm", "5000", "25000"])
    expected = 2 * 1340049.648 * 0.011 * 1.011 / (2 * 2e8 / 4) * 1e3
    assert report["absolute_depth_mm"] == pytest.approx(expected, rel=1e-5)
    assert report["min_critical_depth_mm"] == pytest.approx(expected, rel=0.01)


def test_sdm_on_the_low_immersion_example_finds_flip_lobes() -> None:
    config = str(EXAMPLES / "insperger_ad005.toml")
    report = run_json(["--config", config, "--rpm", "18500", "20500", "--points", "5"])
    assert report["method"] == "sdm" and report["steps"] == 40
    assert "flip" in report["bifurcation"]
    assert report["min_critical_depth_mm"] < report["absolute_depth_mm"]


def test_options_override_the_file_and_plot(tmp_path: Path) -> None:
    config = str(EXAMPLES / "insperger_slot.toml")
    plot = tmp_path / "lobes.png"
    args = ["--config", config, "--method", "zoa", "--teeth", "4", "--up", "--points", "50"]
    report = run_json([*args, "--plot", str(plot)])
    assert report["method"] == "zoa"
    # Four teeth halve the averaged limit of two.
    assert report["absolute_depth_mm"] == pytest.approx(0.2980538 / 2, rel=1e-6)
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_human_output_names_the_lowest_depth() -> None:
    code, out, error = invoke(["--config", str(EXAMPLES / "ubc_two_mode.toml")])
    assert (code, error) == (0, None)
    assert "lowest critical depth" in out and "stable pocket" in out


def test_materials_library_coefficients(tmp_path: Path) -> None:
    modes = tmp_path / "tool.toml"
    modes.write_text(SLOT_MODES)
    report = run_json(["--modes-file", str(modes), "--teeth", "3", "--material", "AA6060-T6"])
    # 1-DOF in x, slot: a = 8 k zeta (1 + zeta) / (N Krc), Krc = 360.98 N/mm^2.
    expected = 8 * 1340049.648 * 0.011 * 1.011 / (3 * 360.98e6) * 1e3
    assert report["absolute_depth_mm"] == pytest.approx(expected, rel=1e-5)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ([], "either --config FILE or --modes-file FILE"),
        (["--config", "{cfg}", "--modes-file", "{cfg}"], "either --config"),
        (["--config", "{cfg}", "--method", "fdm"], "--method 'fdm'"),
        (["--config", "{cfg}", "--immersion", "1.5"], "--immersion 1.5"),
        (["--config", "{cfg}", "--rpm", "9000", "5000"], "--rpm 9000.0 5000.0"),
        (["--config", "{cfg}", "--steps", "1"], "--steps '1'"),
        (["--config", "{cfg}", "--material", "AA6060-T6", "--ktc", "700"], "exclude"),
        (["--config", "{cfg}", "--material", "unobtainium"], "no milling material"),
        (["--config", "{bad}"], "modes[0].damping_ratio: must be >= 0 and < 1"),
        (["--config", "{damped}", "--method", "zoa"], "process damping needs --method sdm"),
        (["--modes-file", "{cfg}"], "cut: unknown key"),
        (["--modes-file", "{modes}"], "cut.teeth: milling needs the number of teeth"),
    ],
)
def test_errors_are_config_errors(tmp_path: Path, args: list[str], message: str) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(SLOT_MODES.replace("0.011", "1.5"))
    damped = tmp_path / "damped.toml"
    damped.write_text(
        (EXAMPLES / "insperger_slot.toml").read_text()
        + "\n[process_damping]\ncpd_n_m2 = 3e9\nchip_thickness_mm = 0.05\ndiameter_mm = 10\n"
    )
    modes = tmp_path / "modes.toml"
    modes.write_text(SLOT_MODES)
    paths = {
        "cfg": str(EXAMPLES / "insperger_slot.toml"),
        "bad": str(bad),
        "damped": str(damped),
        "modes": str(modes),
    }
    code, _, error = invoke([arg.format(**paths) for arg in args])
    assert code != 0
    assert isinstance(error, InputError)
    assert message in str(error)
    assert "\n" not in str(error)


def test_process_damping_raises_the_sdm_limit(tmp_path: Path) -> None:
    base = (EXAMPLES / "insperger_slot.toml").read_text()
    damped = tmp_path / "damped.toml"
    damped.write_text(
        base + "\n[process_damping]\ncpd_n_m2 = 1e11\nchip_thickness_mm = 0.05\ndiameter_mm = 10\n"
    )
    args = ["--rpm", "6000", "7000", "--points", "2", "--max-depth-mm", "3"]
    plain = run_json(["--config", str(EXAMPLES / "insperger_slot.toml"), *args])
    with_pd = run_json(["--config", str(damped), *args])
    assert with_pd["process_damping"] is True
    for low, high in zip(plain["critical_depth_mm"], with_pd["critical_depth_mm"], strict=True):
        assert high is None or high > low * 1.05
    assert math.isfinite(plain["min_critical_depth_mm"])


# ---------------------------------------------------------------------------------------------
# --rpm LIST and --rpm-range (issue 5, item 8)


def test_rpm_list_gives_those_speeds_and_the_library_values() -> None:
    from cnctwin.dynamics.stability import zoa_lobes

    config = EXAMPLES / "insperger_slot.toml"
    report = run_json(["--config", str(config), "--method", "zoa", "--rpm", "8000,9000,10500"])
    assert report["spindle_rpm"] == [8000.0, 9000.0, 10500.0]
    assert all(len(report[key]) == 3 for key in LISTS)
    settings = load_stability_config(config)
    direct = zoa_lobes(settings.tool_dynamics(), settings.process(),
                       [v * math.pi / 30 for v in (8000, 9000, 10500)])  # fmt: skip
    assert report["critical_depth_mm"] == pytest.approx(
        (direct.critical_depth_m * 1e3).tolist(), rel=1e-12
    )
    assert report["chatter_frequency_hz"] == pytest.approx(direct.chatter_frequency_hz.tolist())
    best = int(np.argmin(report["critical_depth_mm"]))
    assert report["min_critical_depth_mm"] == report["critical_depth_mm"][best]
    assert report["min_critical_rpm"] == report["spindle_rpm"][best]


def test_rpm_range_spans_min_max_with_n_speeds() -> None:
    report = run_json(["--config", str(EXAMPLES / "ubc_two_mode.toml"), "--rpm-range",
                       "2000:16000:400"])  # fmt: skip
    assert len(report["spindle_rpm"]) == 400
    assert report["spindle_rpm"][0] == 2000.0 and report["spindle_rpm"][-1] == 16000.0
    assert len({len(report[key]) for key in LISTS}) == 1
    finite = [v for v in report["critical_depth_mm"] if v is not None]
    assert report["min_critical_depth_mm"] == min(finite)
    # The same as the older form --rpm LOW HIGH --points N.
    legacy = run_json(["--config", str(EXAMPLES / "ubc_two_mode.toml"), "--rpm", "2000",
                       "16000", "--points", "400"])  # fmt: skip
    assert legacy["critical_depth_mm"] == report["critical_depth_mm"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--rpm-range", "9000:5000:10"], "--rpm-range '9000:5000:10'"),
        (["--rpm-range", "5000:9000"], "MIN:MAX:N"),
        (["--rpm-range", "5000:9000:1"], "2 <= N <= 100000"),
        (["--rpm", "8000,x"], "--rpm '8000,x'"),
        (["--rpm", "8000,-1"], "each > 0"),
        (["--rpm", "8000", "--rpm-range", "1:2:3"], "exclude each other"),
        (["--rpm-range", "1000:2000:5", "--points", "5"], "--points"),
    ],
)
def test_speed_option_errors_exit_2_in_one_line(
    args: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from cnctwin.cli.app import run

    code = run(["stability", "lobes", "--config", str(EXAMPLES / "insperger_slot.toml"), *args])
    _, err = capsys.readouterr()
    assert code == 2
    assert message in err and err.count("\n") == 1


@pytest.mark.parametrize("name", STABILITY_FILES)
def test_the_example_configs_run_through_the_cli(name: str) -> None:
    report = run_json(["--config", str(EXAMPLES / name), "--rpm-range", "6000:12000:5"])
    assert len({len(report[key]) for key in LISTS}) == 1 and len(report["spindle_rpm"]) == 5
    assert report["min_critical_depth_mm"] is not None


# ---------------------------------------------------------------------------------------------
# stability roadmap (issue 5, item 7)

CELL = """
[machine]
name = "test mill"
max_spindle_rpm = 24000.0

[[tools]]
number = 1
kind = "flat"
diameter_mm = 10.0
flutes = 2
helix_deg = 0.0
flute_length_mm = 20.0

[stock]
kind = "box"
min_mm = [0.0, 0.0, -10.0]
max_mm = [60.0, 40.0, 0.0]

[simulation]
density_per_mm = 5.0
"""
PASSES = """G21 G90 G17 G94
T1 M6
S10000 M3
G0 X-10 Y10 Z5
G0 Z-0.5
G1 X70 F1000
G0 Z5
G0 X-10 Y30
G0 Z-2.0
G1 X70 F1000
G0 Z5
M30
"""


def roadmap_json(args: list[str], capsys: pytest.CaptureFixture[str]) -> dict:
    from cnctwin.cli.app import run

    code = run(["stability", "roadmap", *args, "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert out.count("\n") == 1
    return json.loads(out)


def test_roadmap_of_two_slots_schedules_stable_speeds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from cnctwin.dynamics.stability import MillingProcess, zoa_lobes

    (tmp_path / "cell.toml").write_text(CELL)
    (tmp_path / "passes.ngc").write_text(PASSES)
    stability_file = EXAMPLES / "insperger_slot.toml"
    plot = tmp_path / "roadmap.png"
    report = roadmap_json([str(tmp_path / "passes.ngc"), "--config", str(tmp_path / "cell.toml"),
                           "--stability", str(stability_file), "--method", "zoa",
                           "--plot", str(plot)], capsys)  # fmt: skip
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert report["method"] == "zoa" and report["margin"] == 1.2
    # [lobes] rpm 5000-25000 capped by machine.max_spindle_rpm, every 10 rpm.
    assert report["spindle_rpm_min"] == 5000.0 and report["spindle_rpm_max"] == 24000.0
    assert report["spindle_rpm_points"] == 1901
    segments = report["segments"]
    assert [s["line"] for s in segments] == [6, 10]
    assert [s["ap_mm"] for s in segments] == pytest.approx([0.5, 2.0], abs=0.21)
    assert report["changed_lines"] == [6, 10] and report["lines_without_stable_speed"] == []
    settings = load_stability_config(stability_file)
    for seg in segments:
        assert seg["radial_immersion"] == pytest.approx(1.0, abs=0.01)
        process = MillingProcess(2, 6e8, 2e8, math.radians(seg["entry_deg"]),
                                 math.radians(seg["exit_deg"]))  # fmt: skip
        speed = [seg["scheduled_rpm"] * math.pi / 30.0]
        at = zoa_lobes(settings.tool_dynamics(), process, speed).critical_depth_m[0] * 1e3
        assert at >= 1.2 * seg["ap_mm"]
        assert seg["scheduled_critical_depth_mm"] == pytest.approx(at, rel=1e-9)
        assert seg["programmed_critical_depth_mm"] < 1.2 * seg["ap_mm"]
    code, out, err = invoke_roadmap([str(tmp_path / "passes.ngc"), "--config",
                                     str(tmp_path / "cell.toml"), "--stability",
                                     str(stability_file), "--margin", "0.5"], capsys)  # fmt: skip
    assert code == 2 and "--margin 0.5" in err and err.count("\n") == 1


def invoke_roadmap(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    from cnctwin.cli.app import run

    code = run(["stability", "roadmap", *args])
    out, err = capsys.readouterr()
    return code, out, err


def test_roadmap_of_a_real_program(shared_data: Path, tmp_path: Path, capsys) -> None:
    """The KIT DMC 60H notch program (three 6 mm passes of a 10 mm four-flute end mill at
    S3800) with the UBC two-mode tool: full slots, and no stable speed for 6 mm."""
    from cnctwin.dynamics.stability import MillingProcess, zoa_lobes

    program = shared_data / "gcode" / "siemens_kit_dmc60h" / "AL_2007_T4_Notch_Normal.mpf"
    config = Path(__file__).resolve().parents[2] / "examples" / "kit_dmc60h_al2007.toml"
    plot = tmp_path / "kit.png"
    report = roadmap_json([str(program), "--config", str(config), "--stability",
                           str(EXAMPLES / "ubc_two_mode.toml"), "--density", "5",
                           "--plot", str(plot)], capsys)  # fmt: skip
    assert plot.stat().st_size > 0
    segments = report["segments"]
    assert len(segments) == 15
    assert {s["programmed_rpm"] for s in segments} == {3800.0}
    assert all(s["ap_mm"] == pytest.approx(6.0, abs=0.2) for s in segments)
    assert all(s["radial_immersion"] == pytest.approx(1.0, abs=0.01) for s in segments)
    settings = load_stability_config(EXAMPLES / "ubc_two_mode.toml")
    slot = MillingProcess.from_immersion(4, settings.coefficients(), 1.0)
    expected = zoa_lobes(settings.tool_dynamics(), slot, [3800 * math.pi / 30])
    for seg in segments:
        assert seg["programmed_critical_depth_mm"] == pytest.approx(
            expected.critical_depth_m[0] * 1e3, rel=0.01
        )
    # The slot lobes of this tool stay below 1.2 x 6 mm at every speed of 1000-16000 rpm.
    assert report["lines_without_stable_speed"] == sorted({s["line"] for s in segments})
    lobes = zoa_lobes(settings.tool_dynamics(), slot, np.linspace(1000, 16000, 1501) * math.pi / 30)
    assert np.max(lobes.critical_depth_m) * 1e3 < 1.2 * 6.0


# Per-tool modes, cost and progress (issue 16, item 4)

TWO_TOOLS = CELL.replace(
    """[stock]""",
    """[[tools]]
number = 2
kind = "flat"
diameter_mm = 6.0
flutes = 2
helix_deg = 0.0
flute_length_mm = 20.0

[stock]""",
)
TWO_TOOL_PASSES = """G21 G90 G17 G94
T1 M6
S10000 M3
G0 X-10 Y10 Z5
G0 Z-1.0
G1 X70 F1000
G0 Z5
T2 M6
S3000 M3
G0 X-10 Y30 Z5
G0 Z-1.0
G1 X70 F300
G0 Z5
M30
"""


@pytest.fixture
def two_tools(tmp_path: Path) -> Path:
    """A folder with the two-tool cell (cell.toml) and its program (p.ngc)."""
    (tmp_path / "cell.toml").write_text(TWO_TOOLS)
    (tmp_path / "p.ngc").write_text(TWO_TOOL_PASSES)
    return tmp_path


def test_roadmap_per_tool_leaves_a_tool_without_modes_at_its_speed(
    two_tools: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from cnctwin.dynamics.stability import MillingProcess, sdm_lobes

    tmp_path = two_tools
    # The benchmark's file asks for 40 equal steps; the roadmap's default is the auto grid.
    text = (EXAMPLES / "insperger_slot.toml").read_text()
    (tmp_path / "slot.toml").write_text(text.replace("steps = 40", 'steps = "auto"'))
    slot = str(tmp_path / "slot.toml")
    base = [str(tmp_path / "p.ngc"), "--config", str(tmp_path / "cell.toml")]
    report = roadmap_json([*base, "--stability", f"T1={slot}", "--method", "sdm"], capsys)
    t1 = [s for s in report["segments"] if s["tool"] == 1]
    t2 = [s for s in report["segments"] if s["tool"] == 2]
    assert [s["line"] for s in t1] == [6] and [s["line"] for s in t2] == [12]
    assert report["tools_without_modes"] == [2] and report["lines_without_modes"] == [12]
    # T2 (no modes) keeps S3000: not rescheduled to the floor of the speed range.
    assert t2[0]["scheduled_rpm"] == 3000.0 and t2[0]["programmed_critical_depth_mm"] is None
    assert 12 not in report["changed_lines"] and report["plunge_lines"] == []
    # T1's schedule, checked by a finer semi-discretization (200 equal steps) at that speed.
    seg = t1[0]
    process = MillingProcess(2, 6e8, 2e8, math.radians(seg["entry_deg"]),
                             math.radians(seg["exit_deg"]))  # fmt: skip
    tool = load_stability_config(EXAMPLES / "insperger_slot.toml").tool_dynamics()
    speed = [seg["scheduled_rpm"] * math.pi / 30.0]
    depth = sdm_lobes(tool, process, speed, max_depth_m=0.01, steps=200).critical_depth_m[0]
    assert depth * 1e3 >= 1.2 * seg["ap_mm"] * 0.99
    assert report["sdm_points"] == 20
    # Both tools with modes: T2's line gets lobes of its own.
    both = roadmap_json([*base, "--stability", f"T1={slot}", "--stability", f"t2={slot}",
                         "--method", "zoa"], capsys)  # fmt: skip
    assert both["tools_without_modes"] == []
    assert {e["tool"] for e in both["engagements"]} == {1, 2}
    # The same as a tool map (paths relative to the map).
    (tmp_path / "map.toml").write_text('[tools]\nT1 = "slot.toml"\n2 = "slot.toml"\n')
    mapped = roadmap_json([*base, "--stability", str(tmp_path / "map.toml"), "--method", "zoa"],
                          capsys)  # fmt: skip
    assert mapped["segments"] == both["segments"]


@pytest.mark.parametrize(
    ("stability", "message"),
    [
        (["map.toml"], "tools.X1"),
        (["T9=x.toml"], "tool T9"),
        (["T1="], "T1=FILE"),
        (["a.toml", "T1=b.toml"], "not both"),
        (["T1=a.toml", "T1=b.toml"], "given twice"),
    ],
)
def test_roadmap_stability_option_errors_are_one_line(
    two_tools: Path, capsys: pytest.CaptureFixture[str], stability: list[str], message: str
) -> None:
    tmp_path = two_tools
    (tmp_path / "map.toml").write_text('[tools]\nX1 = "a.toml"\n')
    slot = str(EXAMPLES / "insperger_slot.toml")
    options = []
    for value in stability:
        value = value.replace("x.toml", slot).replace("map.toml", str(tmp_path / "map.toml"))
        options += ["--stability", value]
    code, out, err = invoke_roadmap([str(tmp_path / "p.ngc"), "--config",
                                     str(tmp_path / "cell.toml"), *options], capsys)  # fmt: skip
    assert code == 2 and message in err and err.count("\n") == 1, err


def test_sdm_lobes_print_the_cost_on_stderr_and_keep_json_valid(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from cnctwin.cli.app import run

    code = run(["stability", "lobes", "--config", str(EXAMPLES / "insperger_slot.toml"),
                "--rpm-range", "9000:11000:6", "--json"])  # fmt: skip
    out, err = capsys.readouterr()
    assert code == 0
    report = json.loads(out)
    assert out.count("\n") == 1 and len(report["spindle_rpm"]) == 6
    line = next(x for x in err.splitlines() if "estimated cost" in x)
    # "6 speeds x ~E depth evaluations x T ms = ~S s": S is the product.
    words = line.split()
    speeds = int(words[words.index("speeds") - 1])
    evaluations = float(words[words.index("depth") - 1].lstrip("~"))
    milliseconds = float(words[words.index("ms") - 1])
    total = float(words[words.index("=") + 1].lstrip("~"))
    assert speeds == 6
    assert total == pytest.approx(speeds * evaluations * milliseconds / 1e3, rel=0.1, abs=0.05)


def test_progress_lines_are_throttled_by_the_clock() -> None:
    import io

    from cnctwin.cli.stability import ProgressLine
    from cnctwin.dynamics import SdmCost

    now = [0.0]
    stream = io.StringIO()
    progress = ProgressLine("lobes", interval_s=2.0, stream=stream, clock=lambda: now[0])
    progress.estimate(SdmCost(100, 20.0, 0.005))
    assert stream.getvalue() == (
        "lobes: estimated cost 100 speeds x ~20 depth evaluations x 5 ms = ~10.0 s\n"
    )
    for done in range(1, 101):
        now[0] = done * 0.1  # 0.1 s per speed
        progress(done, 100)
    lines = stream.getvalue().splitlines()[1:]
    assert lines[0] == "lobes: 20/100 done, 2.0 s, ~8.0 s left"
    assert len(lines) == 5 and lines[-1] == "lobes: 100/100 done, 10.0 s"
