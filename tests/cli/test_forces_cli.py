"""``cnctwin forces``: the calculator against the textbook slot formulas and its errors."""

from __future__ import annotations

import json
import math

import pytest
import typer
from typer.testing import CliRunner

from cnctwin.cli import run
from cnctwin.cli.forces import forces
from cnctwin.errors import InputError

KEYS = [
    "mean_fx_n",
    "mean_fy_n",
    "mean_fz_n",
    "mean_resultant_n",
    "max_resultant_n",
    "mean_torque_nm",
    "mean_power_w",
]
SLOT = "--diameter-mm 10 --teeth 3 --helix-deg 30 --ae-mm 10 --ap-mm 2 --fz-mm 0.05 --rpm 8000"
GIVEN = "--ktc 800 --krc 300 --kac 100 --kte 20 --kre 15 --kae 5"


def invoke(args: str) -> tuple[int, str, BaseException | None]:
    app = typer.Typer()
    app.command()(forces)
    result = CliRunner().invoke(app, args.split())
    return result.exit_code, result.stdout, result.exception


def test_json_slot_matches_the_textbook_formulas() -> None:
    code, out, error = invoke(f"{SLOT} {GIVEN} --json")
    assert (code, error) == (0, None)
    report = json.loads(out)
    assert list(report)[: len(KEYS)] == KEYS
    # Altintas 2012, ch. 2, slot with N = 3, a = 2 mm, c = 0.05 mm (forces in N, mm units):
    n, a, c = 3, 2.0, 0.05
    assert report["mean_fx_n"] == pytest.approx(-n * a * 300 * c / 4 - n * a * 15 / math.pi)
    assert report["mean_fy_n"] == pytest.approx(n * a * 800 * c / 4 + n * a * 20 / math.pi)
    assert report["mean_fz_n"] == pytest.approx(-n * a * 100 * c / math.pi - n * a * 5 / 2)
    torque = 5e-3 * n * a * (2 * 800 * c + math.pi * 20) / (2 * math.pi)  # R sum(Ft), N m
    assert report["mean_torque_nm"] == pytest.approx(torque)
    assert report["mean_power_w"] == pytest.approx(torque * 8000 * math.pi / 30)
    assert report["max_resultant_n"] >= report["mean_resultant_n"] > 0
    assert (report["entry_deg"], report["exit_deg"]) == pytest.approx((0.0, 180.0))


def test_up_and_down_milling_mirror_each_other() -> None:
    # Down-milling at ae sweeps pi - phi where up-milling sweeps phi: the tangential force
    # -Ft cos(phi) along the feed changes sign, its normal part Ft sin(phi) does not.
    common = "--diameter-mm 10 --teeth 2 --helix-deg 0 --ae-mm 3 --ap-mm 2 --fz-mm 0.05 --rpm 8000"
    common += " --ktc 800 --krc 0"
    up = json.loads(invoke(f"{common} --up --json")[1])
    down = json.loads(invoke(f"{common} --down --json")[1])
    assert up["mean_fx_n"] == pytest.approx(-down["mean_fx_n"])
    assert up["mean_fy_n"] == pytest.approx(down["mean_fy_n"])
    # Up-milling: the tooth moves with the feed, the work pushes the tool back (-x);
    # down-milling: it moves against the feed and pulls the tool forward (+x).
    assert up["mean_fx_n"] < 0 < down["mean_fx_n"]
    assert (up["milling"], down["milling"]) == ("up", "down")


def test_material_from_the_library_and_the_table() -> None:
    code, out, error = invoke(f"{SLOT} --material AA6060-T6")
    assert (code, error) == (0, None)
    assert (
        "mean Fy" in out and "AA6060-T6" in out and "toward the spindle" in out or "spindle" in out
    )


@pytest.mark.parametrize(
    "args",
    [
        f"{SLOT} --material AA6060-T6 --ktc 800 --krc 300",
        f"{SLOT}",
        f"{SLOT} --ktc 800",
        f"{SLOT} --material unobtainium",
        SLOT.replace("--ae-mm 10", "--ae-mm 12") + " --material AA6060-T6",
        SLOT.replace("--rpm 8000", "--rpm 0") + " --material AA6060-T6",
        SLOT.replace("--teeth 3", "--teeth 0") + " --material AA6060-T6",
    ],
)
def test_bad_input_is_an_input_error(args: str) -> None:
    code, _, error = invoke(args)
    assert code != 0 and isinstance(error, InputError), error


def test_wired_command_reports_errors_on_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    code = run(["forces", *SLOT.split(), "--material", "unobtainium"])
    _, err = capsys.readouterr()
    assert code == 2 and err.count("\n") == 1 and "unobtainium" in err
