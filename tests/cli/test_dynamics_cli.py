"""``cnctwin dynamics fit-frf`` end to end: the readers, JSON, plot, errors and the real files."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import typer
from scipy.io import savemat

from cnctwin.cli import app as root_app
from cnctwin.cli import dynamics, run
from cnctwin.dynamics import Mode, modal_frf
from cnctwin.errors import DataError
from cnctwin.measurements.tap_test import load_tap_test, read_frf_mat, read_table

TWO_PI = 2.0 * math.pi
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
TRUTH = [Mode.from_mck(0.3, 150.0, 2.0e7), Mode.from_mck(0.2, 160.0, 4.0e7)]
TAP = "frf_modal/tool_tap_test"


@pytest.fixture(scope="module", autouse=True)
def _wired() -> None:
    """Register the command group on the root app unless the lead already wired it in."""
    if "dynamics" not in typer.main.get_command(root_app).commands:  # type: ignore[attr-defined]
        root_app.add_typer(dynamics.app, name="dynamics")


def _run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = run(["dynamics", "fit-frf", *args])
    out, err = capsys.readouterr()
    return code, out, err


def _frf_table(path: Path, f_hz: np.ndarray, modes: list[Mode], header: str = "") -> Path:
    h = modal_frf(TWO_PI * f_hz, modes)
    lines = [header] if header else []
    lines += [f"{f:.6e}, {v.real:.9e}, {v.imag:.9e}" for f, v in zip(f_hz, h, strict=True)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_fit_frf_json_recovers_an_frf_table(tmp_path: Path, capsys) -> None:
    path = _frf_table(tmp_path / "tool.csv", np.arange(0.0, 3000.0, 1.0), TRUTH,
                      header="# f [Hz], Re [m/N], Im [m/N]\nfrequency,real,imag")  # fmt: skip
    code, out, _ = _run(capsys, str(path), "--modes", "2", "--json", "--plot",
                        str(tmp_path / "fit.png"))  # fmt: skip
    assert code == 0
    report = json.loads(out)
    assert report["kind"] == "frf" and report["quantity"] == "receptance"
    assert report["band_hz"] == pytest.approx([100.0, 2999.0])
    for mode, true in zip(report["modes"], TRUTH, strict=True):
        # The table carries 10 significant digits.
        assert mode["natural_frequency_hz"] == pytest.approx(true.omega_n / TWO_PI, rel=1e-7)
        assert mode["damping_ratio"] == pytest.approx(true.zeta, rel=1e-6)
        assert mode["stiffness_n_m"] == pytest.approx(true.stiffness, rel=1e-6)
        assert mode["mass_kg"] == pytest.approx(true.mass, rel=1e-6)
        assert mode["damping_n_s_m"] == pytest.approx(true.damping, rel=1e-6)
    assert report["residual_norm"] < 1e-6
    assert (tmp_path / "fit.png").read_bytes()[:8] == PNG_MAGIC


def test_fit_frf_table_output_and_band(tmp_path: Path, capsys) -> None:
    path = _frf_table(tmp_path / "tool.txt", np.arange(0.0, 3000.0, 1.0), TRUTH[:1])
    code, out, _ = _run(capsys, str(path), "--band", "500", "2500")
    assert code == 0
    # The mode: 1299.5 Hz, zeta 3.06 %, k 20 N/um, m 0.3 kg, c 150 N s/m.
    assert "500-2500 Hz" in out and "k (N/um)" in out and "m (kg)" in out
    row = next(line for line in out.splitlines() if "1299.5" in line)
    assert all(value in row for value in ("3.06", "20", "0.3", "150"))
    code, out, _ = _run(capsys, str(path), "--band", "500", "2500", "--json")
    assert json.loads(out)["band_hz"] == pytest.approx([500.0, 2500.0])


def test_impact_record_is_detected_and_windowed(tmp_path: Path, capsys) -> None:
    from scipy import signal

    fs, n = 20_000.0, 10_000
    t = np.arange(n) / fs
    m, c, k = 0.4, 200.0, 0.4 * (TWO_PI * 800.0) ** 2
    force = np.where(t < 3e-4, 200.0 * np.sin(np.pi * t / 3e-4), 0.0)
    system = signal.StateSpace([[0, 1], [-k / m, -c / m]], [[0], [1 / m]],
                               [[-k / m, -c / m]], [[1 / m]])  # fmt: skip
    _, acceleration, _ = signal.lsim(system, force, t)
    path = tmp_path / "hit.txt"
    np.savetxt(path, np.column_stack([t, force, acceleration]), fmt="%.9e")
    test = load_tap_test(path)
    assert test.kind == "impact" and test.frf.quantity == "accelerance"
    assert test.excited_omega is not None and test.excited_omega > TWO_PI * 2000.0
    code, out, _ = _run(capsys, str(path), "--json", "--tau-ms", "50")
    assert code == 0
    report = json.loads(out)
    assert report["kind"] == "impact" and report["window_tau_ms"] == 50.0
    mode = report["modes"][0]
    # lsim's linear interpolation of the 0.3 ms pulse at 20 kHz costs about 0.5 %.
    assert mode["natural_frequency_hz"] == pytest.approx(800.0, rel=1e-3)
    assert mode["stiffness_n_m"] == pytest.approx(k, rel=0.01)
    assert mode["damping_ratio"] == pytest.approx(c / (2 * math.sqrt(k * m)), rel=0.02)


def test_mat_files_with_one_or_several_frfs(tmp_path: Path) -> None:
    f_hz = np.arange(0.0, 2000.0, 0.5)
    h = modal_frf(TWO_PI * f_hz, TRUTH)
    savemat(tmp_path / "complex.mat", {"H": h, "f": f_hz, "note": "x"})
    frf, name = read_frf_mat(tmp_path / "complex.mat")
    assert name == "H" and np.allclose(frf.h, h) and np.allclose(frf.omega, TWO_PI * f_hz)
    pair = np.column_stack([h.real, h.imag])
    savemat(tmp_path / "two.mat", {"Hx": pair, "Hy": pair, "df": 0.5, "f_start": 0})
    with pytest.raises(DataError, match=r"2 FRF variables \(Hx, Hy\); name one with --variable"):
        read_frf_mat(tmp_path / "two.mat")
    frf, name = read_frf_mat(tmp_path / "two.mat", "Hy")
    assert name == "Hy" and np.allclose(frf.omega, TWO_PI * f_hz)
    with pytest.raises(DataError, match="no FRF variable 'Hz'"):
        read_frf_mat(tmp_path / "two.mat", "Hz")
    savemat(tmp_path / "nofreq.mat", {"H": h})
    with pytest.raises(DataError, match="no frequencies"):
        read_frf_mat(tmp_path / "nofreq.mat")


def test_table_reader_errors(tmp_path: Path) -> None:
    bad = tmp_path / "bad.txt"
    bad.write_text("0 1 2\n1 1 2\n2 1\n3 1 2\n")
    with pytest.raises(DataError, match=r"bad.txt:3: 2 columns; give 3"):
        read_table(bad)
    bad.write_text("0 1 2\n1 x 2\n")
    with pytest.raises(DataError, match=r"bad.txt:2: '1 x 2' is not 3 numbers"):
        read_table(bad)
    bad.write_text("# nothing\n")
    with pytest.raises(DataError, match="0 numeric rows"):
        read_table(bad)


def test_bad_input_exits_2_with_one_line(tmp_path: Path, capsys) -> None:
    path = _frf_table(tmp_path / "tool.txt", np.arange(0.0, 3000.0, 1.0), TRUTH)
    cases = [
        ((str(tmp_path / "missing.txt"),), "missing.txt: no such file"),
        ((str(path), "--kind", "wav"), "--kind 'wav'; valid: auto, frf, impact"),
        ((str(path), "--band", "900", "100"), "--band 900 100: give 0 <= LO < HI, in Hz"),
        ((str(path), "--quantity", "force"), "--quantity 'force'; valid:"),
        ((str(path), "--modes", "4", "--band", "1000", "1100"), "peak(s) in the band"),
        ((str(path), "--tau-ms", "0"), "--tau-ms 0.0: give a value > 0 and <= 60000 ms"),
    ]
    for args, message in cases:
        code, out, err = _run(capsys, *args)
        assert code == 2 and out == ""
        assert err.count("\n") == 1 and message in err, err


@pytest.mark.validation
def test_real_files(shared_data: Path, capsys) -> None:
    folder = shared_data / TAP
    # H00.mat: generated by its authors from fn = 1198, 1389, 1586 Hz, zeta = 0.041, 0.048,
    # 0.027, k = 1.2e7, 1.3e7, 3.7e6 N/m (FRFGeneration.m, leekunhwee/Vibration-Signal-Processing).
    h00 = folder / "Modal-Parameter-Identification/Frequency-Domain/H00.mat"
    code, out, _ = _run(capsys, str(h00), "--modes", "3", "--json")
    assert code == 0
    modes = json.loads(out)["modes"]
    assert [m["natural_frequency_hz"] for m in modes] == pytest.approx([1198, 1389, 1586])
    assert [m["damping_ratio"] for m in modes] == pytest.approx([0.041, 0.048, 0.027])
    assert [m["stiffness_n_m"] for m in modes] == pytest.approx([1.2e7, 1.3e7, 3.7e6])
    # The measured tool-point FRF and the raw hit behind it: the hand-identified modes near
    # 1074 and 1961 Hz (stability/NOTES.md, section 5), within 1.5 %.
    for name in ("ExperimentalModalAnalysis/Point_1_Channel_1_CH1.txt",
                 "ImpactTesting/Point1_Channel1_CH1.txt"):  # fmt: skip
        code, out, _ = _run(capsys, str(folder / name), "--modes", "3", "--band", "500", "3200",
                            "--json")  # fmt: skip
        assert code == 0
        report = json.loads(out)
        assert report["kind"] == ("impact" if "Impact" in name else "frf")
        found = [m["natural_frequency_hz"] for m in report["modes"]]
        for f_n in (1074.0, 1961.0):
            assert min(abs(f / f_n - 1.0) for f in found) < 0.015


def test_modal_fit_is_dynamics_fit_frf(tmp_path: Path, capsys) -> None:
    path = _frf_table(tmp_path / "tool.csv", np.arange(0.0, 3000.0, 1.0), TRUTH)
    outputs = []
    for command in (["modal", "fit"], ["dynamics", "fit-frf"]):
        assert run([*command, str(path), "--modes", "2", "--json"]) == 0
        outputs.append(json.loads(capsys.readouterr().out))
    assert outputs[0] == outputs[1]
    assert run(["modal", "fit", str(tmp_path / "missing.csv")]) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_modes_out_feeds_stability_lobes(tmp_path: Path, capsys) -> None:
    """Tap test -> modes file -> lobes, on the command line alone (issue 5, 'done when')."""
    from cnctwin.dynamics.config import load_modes_file

    path = _frf_table(tmp_path / "tool.csv", np.arange(0.0, 3000.0, 1.0), TRUTH)
    for axis in ("x", "y"):
        code = run(["modal", "fit", str(path), "--modes", "2", "--modes-out",
                    str(tmp_path / f"{axis}.toml"), "--direction", axis])  # fmt: skip
        assert code == 0
    capsys.readouterr()
    both = tmp_path / "modes.toml"
    both.write_text((tmp_path / "x.toml").read_text() + (tmp_path / "y.toml").read_text())
    modes = load_modes_file(both)
    assert [m.direction for m in modes] == ["x", "x", "y", "y"]
    for mode, true in zip(modes, TRUTH + TRUTH, strict=True):
        assert mode.fn_hz == pytest.approx(true.omega_n / TWO_PI, rel=1e-7)
        assert mode.damping_ratio == pytest.approx(true.zeta, rel=1e-6)
        assert mode.stiffness_n_m == pytest.approx(true.stiffness, rel=1e-6)
    code = run(["stability", "lobes", "--modes-file", str(both), "--teeth", "2", "--ktc", "600",
                "--krc", "200", "--rpm", "3000,6000", "--json"])  # fmt: skip
    assert code == 0
    assert len(json.loads(capsys.readouterr().out)["critical_depth_mm"]) == 2
    assert run(["modal", "fit", str(path), "--direction", "z"]) == 2
    assert "--direction 'z'" in capsys.readouterr().err
