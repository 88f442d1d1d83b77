"""``cnctwin mirs predict`` and ``search``: JSON, the physics it reports, one-line errors."""

from __future__ import annotations

import json

import pytest

from cnctwin.cli import run

CUT = "--diameter-mm 16 --teeth 3 --ae-mm 8".split()
SLOW = [*CUT, "--feed-mm-min", "100", "--rpm", "1e4"]


def _json(capsys: pytest.CaptureFixture[str], *argv: str) -> dict:  # type: ignore[type-arg]
    assert run(["mirs", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)  # type: ignore[no-any-return]


def test_predict_reports_ward_eq1_loads_and_a_profile(capsys: pytest.CaptureFixture[str]) -> None:
    out = _json(capsys, "predict", *CUT, "--feed-mm-min", "14400", "--rpm", "30000")
    assert out["fz_mm"] == pytest.approx(0.16)
    # AA7075-T6: Ktc 767.01 N/mm^2, Kte 27.7 N/mm; Krc 168.8, Kre 26.6 (h = fz, slot centre)
    assert out["tangential_load_n_mm"] == pytest.approx(767.01 * 0.16 + 27.7)
    assert out["normal_load_n_mm"] == pytest.approx(168.8 * 0.16 + 26.6)
    assert len(out["depth_um"]) == len(out["sigma_xx_mpa"]) == 41
    assert out["max_abs_sigma_xx_mpa"] == pytest.approx(max(map(abs, out["sigma_xx_mpa"])))


def test_search_meets_the_reduction(capsys: pytest.CaptureFixture[str]) -> None:
    out = _json(
        capsys, "search", *CUT, "--feed-mm-min", "14400", "--rpm", "30000", "--min-rpm", "18750"
    )
    assert out["feasible"]
    assert out["limit_mpa"] == pytest.approx(0.7 * out["start_mirs_mpa"])
    assert out["mirs_mpa"] <= out["limit_mpa"]
    assert out["reduction"] == pytest.approx(0.3, abs=0.002)
    assert out["rpm"] == 30000.0 and 1440.0 <= out["feed_mm_min"] <= 14400.0


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["predict", *CUT, "--feed-mm-min", "-5", "--rpm", "30000"], "--feed-mm-min -5.0"),
        (["predict", *SLOW, "--contact-mm", "0"], "--contact-mm"),
        (["predict", *SLOW, "--forces", "x"], "no milling material 'x'"),
        (["predict", *SLOW, "--points", "1"], "--points 1"),
        (["search", *SLOW, "--reduction", "1"], "reduction < 1"),
        (["search", *SLOW, "--min-rpm", "2e4"], "--min-rpm 20000 > --max-rpm 10000"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    capsys: pytest.CaptureFixture[str], argv: list[str], words: str
) -> None:
    assert run(["mirs", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and "\n" not in err
