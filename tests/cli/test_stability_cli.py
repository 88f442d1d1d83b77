"""``cnctwin stability lobes``: the example configurations, modes files, options and errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from cnctwin.cli import stability
from cnctwin.config.stability import load_stability_config
from cnctwin.errors import ConfigError

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


@pytest.mark.parametrize("name", sorted(p.name for p in EXAMPLES.glob("*.toml")))
def test_examples_are_valid(name: str) -> None:
    config = load_stability_config(EXAMPLES / name)
    assert config.tool_dynamics().modes
    config.process()


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
        (["--config", "{bad}"], "modes[0].damping_ratio: must be less than 1"),
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
    assert isinstance(error, ConfigError)
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
