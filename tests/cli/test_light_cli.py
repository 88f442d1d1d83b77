"""The command line imports only what a command needs.

``cnctwin --version`` and ``cnctwin --help`` must not pay for the numerical stack: each
command's modules are imported when that command runs (``cnctwin.cli.app.COMMANDS``).
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
import typer

from cnctwin.cli import run
from cnctwin.cli.app import COMMANDS, app, load_command

#: Packages that cost seconds or tens of MB to import; no light command may load them.
HEAVY = ("scipy", "numba", "matplotlib", "asyncua", "numpy", "pydantic")

_PROBE = """
import json, sys
from cnctwin.cli import run
code = run(sys.argv[1:])
print(json.dumps([code, sorted({m.split('.')[0] for m in sys.modules})]))
"""

#: As _PROBE, with the full names of the modules imported.
_PROBE_MODULES = _PROBE.replace("{m.split('.')[0] for m in sys.modules}", "set(sys.modules)")


@pytest.mark.parametrize("args", [["--version"], ["--help"]])
def test_light_commands_import_no_heavy_package(args: list[str]) -> None:
    # A fresh interpreter: this test process has imported everything already.
    done = subprocess.run(
        [sys.executable, "-c", _PROBE, *args], capture_output=True, text=True, timeout=120
    )
    code, modules = json.loads(done.stdout.splitlines()[-1])
    assert code == 0
    assert not set(HEAVY) & set(modules), sorted(set(HEAVY) & set(modules))


def test_help_lists_each_command_by_its_own_first_sentence() -> None:
    for name, entry in COMMANDS.items():
        command = load_command(name)
        assert command.get_short_help_str(10_000) == entry.summary, name


def test_groups_carry_their_commands_from_other_modules() -> None:
    for name, entry in COMMANDS.items():
        command = load_command(name)
        for extra, _, _ in entry.extra:
            assert extra in command.commands, f"{name} {extra}"


def test_an_unknown_command_is_bad_input(capsys: pytest.CaptureFixture[str]) -> None:
    assert run(["no-such-command"]) == 2
    assert "no-such-command" in capsys.readouterr().err


def test_root_group_knows_every_command_without_importing_it() -> None:
    group = typer.main.get_command(app)
    assert list(group.commands) == list(COMMANDS)  # type: ignore[attr-defined]


def test_loading_the_run_command_keeps_the_run_function() -> None:
    load_command("run")
    import cnctwin.cli

    assert callable(cnctwin.cli.run) and cnctwin.cli.run is run


def test_nc_inspect_without_config_imports_neither_configuration_nor_rich(tmp_path) -> None:
    # Nor does it import typer or pydantic (tests/cli/test_nc_plain_cli.py).
    program = tmp_path / "plain.ngc"
    program.write_text("G1 X1 Y2 F100\nM2\n")
    done = subprocess.run(
        [sys.executable, "-c", _PROBE_MODULES, "nc", "inspect", "--json", str(program)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    code, modules = json.loads(done.stdout.splitlines()[-1])
    assert code == 0, done.stderr
    assert json.loads(done.stdout.splitlines()[0])["feed_length_mm"] == pytest.approx(5**0.5)
    loaded = {name for name in modules if name.startswith(("cnctwin.config", "rich"))}
    assert not loaded, sorted(loaded)


def test_nc_defaults_equal_those_of_a_default_configuration() -> None:
    # `nc inspect` and `nc trace` without --config use these instead of building a config.
    from cnctwin.config import MachiningConfig
    from cnctwin.nc import NCSetup
    from cnctwin.nc.setup import DEFAULT_RAPID_MM_MIN

    config = MachiningConfig()
    assert config.nc_setup() == NCSetup()
    assert config.machine.rapid_mm_min == DEFAULT_RAPID_MM_MIN == 10_000.0
