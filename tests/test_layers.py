"""The layers of docs/architecture.md hold: every import in src/cnctwin points downward.

The contracts live in pyproject.toml (``[tool.importlinter]``, also run by ``lint-imports``);
these tests run them, show that they catch an upward import and an I/O import in a physics
package, and check that the design guide draws the same layers as the contract.
"""

from __future__ import annotations

import re
from pathlib import Path

import grimp
import pytest
from importlinter import api
from importlinter.application import use_cases
from importlinter.contracts.forbidden import ForbiddenContract
from importlinter.contracts.layers import LayersContract

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = ROOT / "pyproject.toml"
GUIDE = ROOT / "docs" / "architecture.md"


def _config() -> dict:
    return api.read_configuration(str(PYPROJECT))


def _contract_options(contract_id: str) -> dict:
    for options in _config()["contracts_options"]:
        if options["id"] == contract_id:
            return options
    raise AssertionError(f"pyproject.toml has no import-linter contract {contract_id!r}")


@pytest.fixture
def graph() -> grimp.ImportGraph:
    """The package's import graph, built afresh for each test (the tests add imports to it)."""
    return grimp.build_graph("cnctwin", include_external_packages=True, cache_dir=None)


def _check(contract_class, contract_id: str, graph: grimp.ImportGraph) -> bool:
    options = _contract_options(contract_id)
    contract = contract_class(
        name=options["name"],
        session_options=_config()["session_options"],
        contract_options=options,
    )
    return contract.check(graph, verbose=False).kept


def test_every_contract_is_kept(capsys: pytest.CaptureFixture[str]) -> None:
    passed = use_cases.lint_imports(str(PYPROJECT), cache_dir=None, no_logo=True)
    assert passed == use_cases.SUCCESS, capsys.readouterr().out


def test_layers_contract_breaks_on_an_upward_import(graph: grimp.ImportGraph) -> None:
    assert _check(LayersContract, "layers", graph)
    graph.add_import(importer="cnctwin.nc.lexer", imported="cnctwin.twin.runtime")
    assert not _check(LayersContract, "layers", graph)


def test_layers_contract_breaks_on_an_import_between_siblings(graph: grimp.ImportGraph) -> None:
    # wear and nc share a layer and are independent: neither may import the other.
    graph.add_import(importer="cnctwin.wear.ekf", imported="cnctwin.nc.segments")
    assert not _check(LayersContract, "layers", graph)


def test_layers_contract_names_every_package(graph: grimp.ImportGraph) -> None:
    graph.add_module("cnctwin.newpackage")
    assert not _check(LayersContract, "layers", graph)


def test_physics_contract_breaks_on_network_io(graph: grimp.ImportGraph) -> None:
    assert _check(ForbiddenContract, "pure-physics", graph)
    graph.add_import(importer="cnctwin.geometry.dexel", imported="asyncua")
    assert not _check(ForbiddenContract, "pure-physics", graph)


def _guide_layers() -> list[str]:
    text = GUIDE.read_text(encoding="utf-8")
    block = re.search(r"<!-- layers -->\s*```text\n(.*?)```", text, re.DOTALL)
    assert block, f"{GUIDE} has no ```text block after <!-- layers -->"
    return [re.sub(r"\s+", " ", line.split("#")[0]).strip() for line in block[1].splitlines()]


def test_the_guide_draws_the_contract_layers() -> None:
    contract = [
        " | ".join(p.strip() for p in layer.split("|"))
        for layer in _contract_options("layers")["layers"]
    ]
    assert [line for line in _guide_layers() if line] == contract
