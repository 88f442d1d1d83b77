"""``cnctwin materials list|identify`` and ``cnctwin forces --materials``: the documented round
trip from measured mean forces to a calculator result (docs/materials.md)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from cnctwin.cli import run
from cnctwin.mechanics.materials import packaged_materials

REPO = Path(__file__).resolve().parents[2]
MEANS = REPO / "examples" / "materials" / "kistler_slot_means.csv"
SLOT = "--diameter-mm 25 --teeth 2 --helix-deg 30 --ae-mm 25 --ap-mm 3 --fz-mm 0.075 --rpm 6000"


def test_list_json_has_every_entry_with_its_source(capsys: pytest.CaptureFixture[str]) -> None:
    assert run(["materials", "list", "--json"]) == 0
    listing = json.loads(capsys.readouterr().out)
    library = packaged_materials()
    assert [m["name"] for m in listing["milling"]] == list(library.milling)
    assert [k["name"] for k in listing["kienzle"]] == list(library.kienzle)
    for entry in [*listing["milling"], *listing["kienzle"]]:
        assert entry["source"] and entry["conditions"] and isinstance(entry["checked"], bool)


def test_every_milling_entry_works_in_the_calculator(capsys: pytest.CaptureFixture[str]) -> None:
    for name, entry in packaged_materials().milling.items():
        assert run(["forces", *SLOT.split(), "--material", name, "--json"]) == 0, name
        report = json.loads(capsys.readouterr().out)
        assert report["mean_power_w"] > 0 and report["material"] == name
        assert report["derived"] == entry.derived


def test_identify_then_forces_with_the_users_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["materials", "identify", str(MEANS), "--teeth", "2", "--ap-mm", "3", "--name", "ours"]
    assert run(argv) == 0
    mine = tmp_path / "mine.toml"
    mine.write_text(capsys.readouterr().out)
    assert (
        run(["forces", *SLOT.split(), "--materials", str(mine), "--material", "ours", "--json"])
        == 0
    )
    ours = json.loads(capsys.readouterr().out)
    assert run(["forces", *SLOT.split(), "--material", "kistler-slot-6000rpm", "--json"]) == 0
    library = json.loads(capsys.readouterr().out)
    for key in ("mean_fx_n", "mean_fy_n", "mean_fz_n", "mean_torque_nm"):
        assert ours[key] == pytest.approx(library[key], rel=2e-3), key
    # The measured mean Fy at 0.075 mm/tooth (examples/materials/kistler_slot_means.csv).
    assert ours["mean_fy_n"] == pytest.approx(137.653, rel=0.05)
    assert math.isfinite(ours["max_resultant_n"])
    assert run(["materials", "list", "--materials", str(mine), "--json"]) == 0
    assert "ours" in [m["name"] for m in json.loads(capsys.readouterr().out)["milling"]]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--teeth", "0"], "--teeth"),
        (["--ap-mm", "0"], "--ap-mm"),
        (["--ae-mm", "5"], "give --ae-mm and --diameter-mm together"),
        (["--ae-mm", "30", "--diameter-mm", "25"], "--ae-mm 30.0; give 0.001 <= ae"),
    ],
)
def test_identify_refusals_are_one_line(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    base = {"--teeth": "2", "--ap-mm": "3"}
    for option, value in zip(argv[::2], argv[1::2], strict=True):
        base[option] = value
    words = [word for pair in base.items() for word in pair]
    assert run(["materials", "identify", str(MEANS), *words, "--name", "x"]) == 2
    error = capsys.readouterr().err.strip()
    assert message in error and "\n" not in error


def test_a_bad_means_file_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "means.csv"
    bad.write_text("fz_mm,fx_n,fy_n,fz_n\n0.05,1,2,3\n0.05,1,2,x\n")
    assert (
        run(["materials", "identify", str(bad), "--teeth", "2", "--ap-mm", "3", "--name", "x"]) == 2
    )
    assert "means.csv line 3" in capsys.readouterr().err
