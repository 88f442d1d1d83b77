"""Fitting the logistic wear law: exact recovery, and prediction of real wear progressions."""

from __future__ import annotations

import csv
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

from cnctwin.errors import DataError
from cnctwin.wear.fitting import fit_logistic_wear, logistic_wear_curve

#: PHM 2010 cutting conditions as commonly quoted (data README): radial depth 0.125 mm,
#: axial depth 0.2 mm, each cut 108 mm long. Only the scale of q depends on it.
PHM_MR_PER_CUT_MM3 = 0.125 * 0.2 * 108.0


def test_exact_recovery_of_a_noise_free_logistic() -> None:
    mr = np.linspace(0.0, 6.0, 40)
    vb = logistic_wear_curve(mr, 1.43, 0.663, 0.02)
    fit = fit_logistic_wear([(mr[:20], vb[:20]), (mr[20:], vb[20:])])
    assert fit.law.q_per_mm3 == pytest.approx(1.43, rel=1e-4)
    assert fit.law.vb_max_mm == pytest.approx(0.663, rel=1e-4)
    assert fit.vb0_mm == pytest.approx(0.02, rel=1e-4)
    assert fit.rmse_mm < 1e-6 and fit.points == 40


def test_bad_series_are_refused() -> None:
    with pytest.raises(DataError, match="at least 3"):
        fit_logistic_wear([([0.0, 1.0], [0.1, 0.2])])
    with pytest.raises(DataError, match=">= 0"):
        fit_logistic_wear([([0.0, 1.0, 2.0], [0.1, -0.2, 0.3])])


def _phm(shared_data: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    out = {}
    for cutter in ("c1", "c4", "c6"):
        table = np.loadtxt(
            shared_data / "phm2010_wear" / f"{cutter}_wear.csv", delimiter=",", skiprows=1
        )
        # The worst flute decides a tool's life; wear is given in 10^-3 mm.
        out[cutter] = (table[:, 0] * PHM_MR_PER_CUT_MM3, table[:, 1:].max(axis=1) / 1000.0)
    return out


@pytest.mark.validation
@pytest.mark.parametrize("held_out", ["c1", "c4", "c6"])
def test_phm2010_fit_two_cutters_predict_the_third(shared_data: Path, held_out: str) -> None:
    data = _phm(shared_data)
    fit = fit_logistic_wear([series for name, series in data.items() if name != held_out])
    mr, vb = data[held_out]
    error = fit.predict(mr) - vb
    rmse = float(np.sqrt(np.mean(error**2)))
    # Measured (docs/validation.md): 0.018, 0.024 and 0.035 mm RMSE over wear of
    # 0.03-0.23 mm. The bound is the largest with a margin for solver differences.
    assert rmse < 0.04
    assert fit.rmse_mm < 0.025


def _nasa(shared_data: Path) -> dict[int, tuple[tuple[str, str, str], np.ndarray, np.ndarray]]:
    rows = defaultdict(list)
    with (shared_data / "nasa_milling" / "labels_with_tool_class.csv").open() as handle:
        for row in csv.DictReader(handle):
            if row["VB"]:
                rows[int(row["case"])].append(row)
    out = {}
    for case, items in rows.items():
        condition = (items[0]["DOC"], items[0]["feed"], items[0]["material"])
        time = np.array([float(r["time"]) for r in items])
        vb = np.array([float(r["VB"]) for r in items])
        out[case] = (condition, time, vb)
    return out


@pytest.mark.validation
def test_nasa_cases_follow_the_logistic_law_and_predict_their_twin_case(
    shared_data: Path,
) -> None:
    cases = _nasa(shared_data)
    usable = {k: v for k, v in cases.items() if v[1].size >= 5}
    assert len(usable) == 14
    # Per case (time in minutes drives the law): measured RMSE 0.012-0.042 mm.
    for _case, (_condition, time, vb) in usable.items():
        assert fit_logistic_wear([(time, vb)]).rmse_mm < 0.045
    # Cases run under the same depth, feed and material: fit one, predict the other.
    by_condition = defaultdict(list)
    for case, (condition, time, vb) in usable.items():
        by_condition[condition].append((case, time, vb))
    errors = []
    for group in by_condition.values():
        for (_a, ta, va), (_b, tb, vb) in ((g, h) for g in group for h in group if g is not h):
            fit = fit_logistic_wear([(ta, va)])
            errors.append(float(np.sqrt(np.mean((fit.predict(tb) - vb) ** 2))))
    assert errors, "no two cases share a condition"
    # Tools differ: the twin case is predicted to within about 0.1-0.2 mm (median below).
    assert float(np.median(errors)) < 0.2


def test_wear_torque_fit_recovers_the_papers_model() -> None:
    # Christiand 2024, Eq. 8 with the preset's parameters: p1 and p3 only shift the offset,
    # so the fit (p1 = p3 = 1 /mm) must give p0, the domain end p2/p3 and the same torques.
    from cnctwin.wear import CHRISTIAND2024, fit_wear_torque

    model = CHRISTIAND2024.wear_torque
    vb = np.linspace(0.02, 0.6, 25)
    torque = np.array([model.torque_nm(v) for v in vb])
    fit = fit_wear_torque(vb, torque)
    assert fit.p0_nm == pytest.approx(model.p0_nm, rel=1e-4)
    assert fit.vb_limit_mm == pytest.approx(model.vb_limit_mm, rel=1e-4)
    expected_offset = model.p4_nm + model.p0_nm * np.log(model.p1_per_mm / model.p3_per_mm)
    assert fit.p4_nm == pytest.approx(expected_offset, rel=1e-4)
    assert [fit.torque_nm(v) for v in vb] == pytest.approx(torque.tolist(), rel=1e-5)


@pytest.mark.parametrize(
    ("vb", "torque", "message"),
    [
        ([0.1, 0.2], [1.0, 2.0], "at least 3 finite points"),
        ([0.1, 0.0, 0.3], [1.0, 2.0, 3.0], "every VB must be > 0"),
        ([0.1, 0.2, 0.3], [3.0, 2.0, 1.0], "does not rise with wear"),
        ([0.1, 0.2, 0.3], [1.0, 2.0], "3 wear values but 2 torques"),
    ],
)
def test_wear_torque_fit_refuses_bad_pairs(vb: list, torque: list, message: str) -> None:
    from cnctwin.wear import fit_wear_torque

    with pytest.raises(DataError, match=message):
        fit_wear_torque(vb, torque)
