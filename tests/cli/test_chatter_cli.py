"""``cnctwin chatter simulate`` and ``calibrate-damping``: output, agreement with the library,
plots and errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from cnctwin.cli import chatter
from cnctwin.dynamics.config import load_stability_config
from cnctwin.dynamics.process_damping import CalibrationSetup, calibrate_cpd
from cnctwin.dynamics.stability import sdm_lobes
from cnctwin.dynamics.time_domain import simulate_milling
from cnctwin.errors import CnctwinError, ConfigError, DataError, InputError
from cnctwin.geometry import Cutter

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "stability"
RPM = math.pi / 30.0
G = 9.80665

# Royandi 2026: Table 2 means (918.58 Hz, zeta 0.04242, k 8028 N/mm) in x and y, a slot with
# a 4-flute 12 mm cutter in AA6060-T6 (the materials library's entry of their Sec. 4.2).
ROYANDI = """
[[modes]]
direction = "x"
fn_hz = 918.5764
damping_ratio = 0.042417
stiffness_n_m = 8028000.0

[[modes]]
direction = "y"
fn_hz = 918.5764
damping_ratio = 0.042417
stiffness_n_m = 8028000.0

[cut]
teeth = 4
radial_immersion = 1.0
material = "AA6060-T6"

[process_damping]
cpd_n_m2 = 2e10
chip_thickness_mm = 0.1
diameter_mm = 12.0
"""
# Table 3, 7500 rpm and 0.1 mm/tooth, plus one cut at 0.05 mm/tooth.
CUTS = """ap_mm,spindle_rpm,fz_mm,vibration_g
1.5,7500,0.100,2.573
2.5,7500,0.100,3.487
3.5,7500,0.100,3.312
1.5,7500,0.050,2.786
"""
SIMULATE_KEYS = [
    "spindle_rpm", "depth_mm", "feed_per_tooth_mm", "simulated_s", "transient_s",
    "steps_per_tooth", "slices", "tooth_passing_hz", "cpd_n_m2", "process_damping_n_s_m",
    "rms", "mean_force_n", "peak_to_peak_um", "chatter", "decision", "growth_rate_per_s",
    "growth_rate_sigma_per_s", "nonsynchronous_ratio", "growth",
    "chatter_frequency_hz", "sdm_spectral_radius", "sdm_stable", "wall_s",
]  # fmt: skip


def invoke(args: list[str]) -> tuple[int, str, BaseException | None]:
    app = typer.Typer()
    app.add_typer(chatter.app, name="chatter")
    result = CliRunner().invoke(app, ["chatter", *args])
    return result.exit_code, result.stdout, result.exception


def run_json(args: list[str]) -> dict:
    code, out, error = invoke([*args, "--json"])
    assert (code, error) == (0, None), out
    assert out.count("\n") == 1
    return json.loads(out)


@pytest.fixture()
def royandi(tmp_path: Path) -> Path:
    path = tmp_path / "royandi.toml"
    path.write_text(ROYANDI, encoding="utf-8")
    return path


def test_simulate_stable_cut_is_the_library_result(royandi: Path) -> None:
    args = ["simulate", "--config", str(royandi), "--rpm", "7500", "--depth-mm", "1.5",
            "--helix-deg", "30", "--helical-edge", "--seconds", "0.2",
            "--max-seconds", "0.2"]  # fmt: skip
    report = run_json(args)
    assert list(report) == SIMULATE_KEYS
    assert report["feed_per_tooth_mm"] == pytest.approx(0.1)  # from [process_damping]
    assert report["cpd_n_m2"] == 2e10
    # Eq. 3: C_eff = C_pd a_p f_z / V_c, V_c = pi D n / 60.
    speed = 7500 * RPM
    assert report["process_damping_n_s_m"] == pytest.approx(2e10 * 1.5e-3 * 1e-4 / (speed * 0.006))
    assert report["chatter"] is False and report["sdm_stable"] is True
    assert report["chatter_frequency_hz"] is None
    config = load_stability_config(royandi)
    process = config.process()
    direct = simulate_milling(
        config.tool_dynamics(), process, spindle_rad_s=speed, depth_m=1.5e-3,  # type: ignore[arg-type]
        feed_per_tooth_m=1e-4, duration_s=0.2,
        cutter=Cutter.flat(12.0, 20.0, flutes=4, helix_rad=math.radians(30)),
        edge_tangential_n_m=31.49e3, edge_radial_n_m=21.85e3, helical_edge=True,
        damping=config.process_damping_model(),
    )  # fmt: skip
    rms = direct.rms()
    assert report["rms"]["acceleration_g"] == pytest.approx(list(rms.acceleration_g), rel=1e-12)
    assert report["rms"]["displacement_um"] == pytest.approx(list(rms.displacement_m * 1e6))
    assert report["tooth_passing_hz"] == pytest.approx(500.0)
    assert report["steps_per_tooth"] == direct.steps_per_tooth


def test_simulate_unstable_cut_reports_chatter_with_the_sdm(tmp_path: Path) -> None:
    # Insperger's 1-DOF slot at 10000 rpm: SDM critical depth 0.326 mm, chatter near 930 Hz.
    config = str(EXAMPLES / "insperger_slot.toml")
    report = run_json(["simulate", "--config", config, "--rpm", "10000", "--depth-mm", "0.4",
                       "--feed-mm", "0.1"])  # fmt: skip
    assert report["chatter"] is True and report["sdm_stable"] is False
    settings = load_stability_config(config)
    lobes = sdm_lobes(settings.tool_dynamics(), settings.process(), [10000 * RPM], max_depth_m=0.01)
    assert report["chatter_frequency_hz"] == pytest.approx(lobes.chatter_frequency_hz[0], rel=0.02)
    assert report["cpd_n_m2"] is None and report["process_damping_n_s_m"] == 0.0
    png = tmp_path / "chatter.png"
    code, out, error = invoke(["simulate", "--config", config, "--rpm", "10000", "--depth-mm",
                               "0.4", "--feed-mm", "0.1", "--plot", str(png)])  # fmt: skip
    assert (code, error) == (0, None)
    assert "CHATTER" in out and "semi-discretization" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_calibrate_damping_matches_the_library_and_feeds_simulate(
    royandi: Path, tmp_path: Path
) -> None:
    cuts = tmp_path / "cuts.csv"
    cuts.write_text(CUTS, encoding="utf-8")
    args = ["calibrate-damping", str(cuts), "--config", str(royandi), "--helix-deg", "30",
            "--helical-edge", "--seconds", "0.15"]  # fmt: skip
    report = run_json(args)
    assert [row["status"] for row in report["cuts"]] == ["matched"] * 4
    config = load_stability_config(royandi)
    setup = CalibrationSetup(
        config.tool_dynamics(), config.process(),
        Cutter.flat(12.0, 20.0, flutes=4, helix_rad=math.radians(30)),
        31.49e3, 21.85e3, True, 0.15,
    )  # fmt: skip
    first = calibrate_cpd(setup, spindle_rad_s=7500 * RPM, depth_m=1.5e-3, feed_per_tooth_m=1e-4,
                          measured_rms_m_s2=2.573 * G)  # fmt: skip
    row = report["cuts"][0]
    assert row["cpd_n_m2"] == pytest.approx(first.cpd_pa, rel=1e-12)
    assert row["simulated_g"] == pytest.approx(2.573, rel=0.01)
    assert row["gamma_n"] == pytest.approx(first.cpd_pa * 1.5e-3 * 1e-4)
    assert row["effective_damping_n_s_m"] == pytest.approx(row["gamma_n"] / (7500 * RPM * 0.006))
    assert [fit["spindle_rpm"] for fit in report["fits"]] == [7500]
    assert report["unfitted_rpm"] == []
    # The JSON is a damping model for simulate: C_pd by Eq. 20 from the fitted Gamma.
    model_file = tmp_path / "model.json"
    model_file.write_text(json.dumps(report), encoding="utf-8")
    fit = report["fits"][0]
    simulated = run_json(["simulate", "--config", str(royandi), "--rpm", "7500", "--depth-mm",
                          "2.5", "--feed-mm", "0.1", "--damping-model", str(model_file),
                          "--seconds", "0.1"])  # fmt: skip
    gamma = fit["a_n"] + fit["b_n"] * math.exp(-2.5 / fit["a0_mm"])
    assert simulated["cpd_n_m2"] == pytest.approx(gamma / (2.5e-3 * 1e-4))
    code, out, error = invoke([*args[:-2], "--seconds", "0.1", "--plot", str(tmp_path / "g.png")])
    assert (code, error) == (0, None)
    assert "Gamma = A + B exp(-a_p / a0)" in out
    assert (tmp_path / "g.png").stat().st_size > 0


@pytest.mark.parametrize(
    ("args", "error", "message"),
    [
        (["simulate", "--config", "{slot}", "--rpm", "9000", "--depth-mm", "1"], InputError,
         "give --feed-mm"),
        (["simulate", "--config", "{orthogonal}", "--rpm", "9000", "--depth-mm", "1",
          "--feed-mm", "0.1"], ConfigError, "orthogonal"),
        (["simulate", "--config", "{slot}", "--rpm", "9000", "--depth-mm", "1", "--feed-mm",
          "0.1", "--helix-deg", "30"], InputError, "--diameter-mm"),
        (["simulate", "--config", "{slot}", "--rpm", "9000", "--depth-mm", "1", "--feed-mm",
          "0.1", "--cpd-n-m2", "1e10"], InputError, "diameter"),
        (["simulate", "--config", "{slot}", "--rpm", "-5", "--depth-mm", "1", "--feed-mm",
          "0.1"], InputError, "--rpm"),
        (["simulate", "--config", "{royandi}", "--rpm", "9000", "--depth-mm", "1",
          "--damping-model", "{bad}"], DataError, "not a damping model"),
        (["simulate", "--config", "{royandi}", "--rpm", "9000", "--depth-mm", "1",
          "--cpd-n-m2", "1e10", "--damping-model", "{model}"], InputError, "exclude"),
        (["calibrate-damping", "{bad}", "--config", "{royandi}"], DataError, "no column"),
        (["calibrate-damping", "{cuts}", "--config", "{slot}"], InputError, "--diameter-mm"),
        (["calibrate-damping", "{cuts}", "--config", "{royandi}", "--axis", "z"], InputError,
         "--axis"),
    ],
)  # fmt: skip
def test_errors_name_the_bad_value(
    args: list[str], error: type[CnctwinError], message: str, royandi: Path, tmp_path: Path
) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text("x,y\n1,2\n", encoding="utf-8")
    cuts = tmp_path / "cuts.csv"
    cuts.write_text(CUTS, encoding="utf-8")
    model = tmp_path / "model.json"
    model.write_text('{"fits": [{"spindle_rpm": 7500, "a_n": 3e4, "b_n": 0, "a0_mm": 0.5}]}')
    paths = {
        "slot": str(EXAMPLES / "insperger_slot.toml"),
        "orthogonal": str(EXAMPLES / "orthogonal_2dof.toml"),
        "royandi": str(royandi),
        "bad": str(bad),
        "cuts": str(cuts),
        "model": str(model),
    }
    code, _, raised = invoke([arg.format(**paths) for arg in args])
    assert code != 0
    assert isinstance(raised, error), raised
    assert message in str(raised)
    assert "\n" not in str(raised)


# ---------------------------------------------------------------------------------------------
# chatter detect


def test_detect_reads_the_simulated_signals_and_agrees_with_the_library(tmp_path: Path) -> None:
    """simulate --signals writes a CSV; detect finds what the library finds on the arrays."""
    from cnctwin.dynamics.chatter_detection import DetectorSettings, detect_chatter

    config = str(EXAMPLES / "insperger_slot.toml")
    signals = tmp_path / "cut.csv"
    # 10000 rpm: the SDM's critical depth is 0.329 mm; 0.41 mm chatters, 0.25 mm does not.
    for depth, expected in (("0.41", True), ("0.25", False)):
        code, out, error = invoke(["simulate", "--config", config, "--rpm", "10000",
                                   "--depth-mm", depth, "--feed-mm", "0.1", "--seconds", "0.6",
                                   "--signals", str(signals)])  # fmt: skip
        assert (code, error) == (0, None), out
        header = signals.read_text().splitlines()[0]
        assert header == ",".join(chatter.SIGNAL_COLUMNS)
        detect = ["detect", str(signals), "--rpm", "10000", "--teeth", "2", "--column"]
        report = run_json([*detect, "ax_m_s2", "--window-s", "0.1", "--hop-s", "0.05"])
        lists = ("start_s", "end_s", "energy_ratio", "chatter_frequency_hz", "chatter_flags")
        assert len({len(report[key]) for key in lists}) == 1 and report["windows"] == 11
        assert report["tooth_passing_hz"] == pytest.approx(10000 * 2 / 60)
        settled = [flag for flag, t in zip(report["chatter_flags"], report["start_s"],
                                           strict=True) if t >= 0.3]  # fmt: skip
        assert all(flag == expected for flag in settled)
        data = np.loadtxt(signals, delimiter=",", skiprows=1)
        library = detect_chatter(
            data[:, 3], DetectorSettings(1.0 / np.mean(np.diff(data[:, 0])), 10000.0, 2, 0.1, 0.05)
        )
        assert report["energy_ratio"] == pytest.approx(library.energy_ratio.tolist(), rel=1e-12)
        if expected:
            assert report["dominant_chatter_frequency_hz"] == pytest.approx(932.5, abs=10.0)
    code, out, error = invoke(["detect", str(signals), "--rpm", "10000", "--teeth", "2"])
    assert (code, error) == (0, None) and "chatter detection" in out and "x_m" in out


@pytest.mark.parametrize(
    ("content", "args", "message"),
    [
        ("t_s,a\n" + "".join(f"{i * 1e-3},{i % 3}\n" for i in range(200)), ["--column", "b"],
         "no column 'b' (--column)"),
        ("x,a\n" + "".join(f"{i * 1e-3},{i % 3}\n" for i in range(200)), [], "no time column"),
        ("t_s,a\n" + "".join(f"{i * 1e-3},{i % 3}\n" for i in range(200)) + "0.2,oops\n", [],
         ":202: column 'a' is 'oops'"),
        ("t_s,a\n" + "".join(f"{(i * i) * 1e-6},{i % 3}\n" for i in range(200)), [],
         "not evenly increasing"),
        ("t_s,a\n" + "".join(f"{i * 1e-3},{i % 3}\n" for i in range(50)), [],
         "shorter than one window"),
        ("t_s,a\n" + "".join(f"{i * 1e-3},{i % 3}\n" for i in range(200)), ["--window-s", "0"],
         "--window-s 0.0"),
        ("t_s,a\n" + "".join(f"{i * 1e-3},{i % 3}\n" for i in range(200)),
         ["--threshold", "2"], "--threshold"),
    ],
)  # fmt: skip
def test_detect_errors_are_one_line(
    content: str, args: list[str], message: str, tmp_path: Path
) -> None:
    path = tmp_path / "signal.csv"
    path.write_text(content, encoding="utf-8")
    code, out, error = invoke(["detect", str(path), "--rpm", "6000", "--teeth", "2", *args])
    assert isinstance(error, CnctwinError) and message in str(error)
    assert "\n" not in str(error)


def test_vibration_simulate_is_chatter_simulate(capsys: pytest.CaptureFixture[str]) -> None:
    from cnctwin.cli.app import run

    args = ["simulate", "--config", str(EXAMPLES / "insperger_slot.toml"), "--rpm", "10000",
            "--depth-mm", "0.25", "--feed-mm", "0.1", "--seconds", "0.1", "--json"]  # fmt: skip
    reports = []
    for group in ("vibration", "chatter"):
        assert run([group, *args]) == 0
        report = json.loads(capsys.readouterr().out)
        report.pop("wall_s")
        reports.append(report)
    assert reports[0] == reports[1]
    assert run(["vibration", "simulate", "--config", "nowhere.toml", "--rpm", "1",
                "--depth-mm", "1"]) == 2  # fmt: skip
    assert capsys.readouterr().err.count("\n") == 1
