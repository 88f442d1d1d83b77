"""Every ``cnctwin`` command shown in the README and docs/ parses, and runs as written.

The commands are those of the fenced shell blocks (``sh``, ``bash``, ``console``), found as
``tests/cli/_documented.py`` describes. Each is first handed to the real command tree without
running it: the subcommands must exist, and the leaf command must accept the options and
arguments (names, counts, types and ranges, required options) as the CLI checks them before
any work. Every file it reads (a word with an input file's suffix that is not the value of an
option that writes) must exist relative to the repository root, where the commands are written
to run, unless a command before it on the page writes it (an output option, ``> FILE``). Files
under ``../shared/`` count only where the shared data is present (their own tests skip without
it, or fail in CI).

Then every page's commands run, in page order, with the installed ``cnctwin``, in a temporary
working directory laid out like the repository (the shipped examples copied, ``../shared``
linked) and with a home of their own: each must exit 0 with no traceback on stderr, and a
``--json`` command must print valid JSON. The commands that cannot simply run to their end here
are in :data:`SPECIAL`, each with the reason and what is checked instead. One test per page,
in parallel under ``pytest -n``; each page in a network namespace of its own where the system
allows it (``unshare -rn``), so the servers' fixed ports (4840, 5020, 8765, 8766) meet nothing
else; elsewhere the pages with such servers run one after the other in one test.
"""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest
import typer
from _documented import (
    PAGES,
    READS,
    REPO,
    SHARED,
    SHIPPED,
    Command,
    Shell,
    Special,
    commands,
    isolation,
    outputs,
    run_page,
    run_page_isolated,
    steps,
)
from skips import missing
from typer.core import TyperGroup

from cnctwin.cli.app import app

#: Files a page's commands read that another page's commands make: the page that says how.
MADE_ELSEWHERE = {
    "docs/security.md": {"pki/server-cert.pem", "pki/server-key.pem"},  # docs/opcua.md, OpenSSL
}

DEMO_TWIN = "cnctwin run --config src/cnctwin/examples/demo_twin.toml"
SERVE = "cnctwin virtual serve"
OPCUA = "opc.tcp://127.0.0.1:4840/cnctwin"
#: A virtual machine for the page's next commands.
MACHINE = "a server: the virtual machine serves until Ctrl-C (the page's next commands use it)"
REMOTE = "the reader's own {}: a documented address that is not here"

#: The documented commands that do not simply run to their end here: (page, the command as
#: written, ``cnctwin`` first and ``$NAME`` expanded) -> how it is checked instead, and why.
#: Every other documented command runs and must succeed.
SPECIAL: dict[tuple[str, str], Special] = {
    ("docs/twin.md", f"{SERVE} --config src/cnctwin/examples/demo_twin.toml"): Special(
        "server", MACHINE, port=4840, ready=OPCUA
    ),
    ("docs/twin.md", f"{DEMO_TWIN} --endpoint opc.tcp://10.0.0.7:4840/cnc"): Special(
        "unreachable", REMOTE.format("machine"), expect="opc.tcp://10.0.0.7:4840/cnc"
    ),
    ("docs/virtual-machine.md", f"{SERVE} --delay 10 --anonymous operator"): Special(
        "server", MACHINE, port=4840, ready=OPCUA
    ),
    (
        "docs/virtual-machine.md",
        f"{SERVE} --config src/cnctwin/examples/demo_twin.toml --transport modbus --port 5020 "
        "--speed 1",
    ): Special("server", MACHINE, port=5020, ready="modbus://127.0.0.1:5020"),
    (
        "docs/replay.md",
        f"{SERVE} --replay ../shared/data/umich_cnc_mill_tool_wear/experiment_05.csv "
        "--map examples/replay/umich.toml --loop",
    ): Special("server", MACHINE, port=4840, ready=OPCUA),
    (
        "docs/roughness.md",
        f"{SERVE} --config examples/roughness/roughness_twin.toml --delay 20 --once",
    ): Special("server", MACHINE, port=4840, ready=OPCUA),
    ("docs/dashboard.md", "cnctwin demo --web"): Special(
        "server",
        "a server: it waits up to 60 s for a browser, runs, then serves the page until Ctrl-C",
        port=8765,
        ready="open http://127.0.0.1:8765/",
        keep=False,
    ),
    ("docs/dashboard.md", f"{DEMO_TWIN} --web"): Special(
        "unreachable",
        "the page's 'against a real machine': the configuration's machine does not run here",
        expect=OPCUA,
    ),
    (
        "docs/dashboard.md",
        f"{DEMO_TWIN} --web --port 9000 --endpoint opc.tcp://10.0.0.7:4840/cnc",
    ): (Special("unreachable", REMOTE.format("machine"), expect="opc.tcp://10.0.0.7:4840/cnc")),
    ("docs/run-browser.md", "cnctwin web --db demo.sqlite"): Special(
        "server",
        "a server: the run browser serves until Ctrl-C",
        port=8766,
        ready="http://127.0.0.1:8766/runs",
        keep=False,
    ),
    ("docs/historian.md", "cnctwin runs list --db postgresql://twin@db-host:5432/plant"): Special(
        "unreachable", REMOTE.format("PostgreSQL server"), expect="db-host"
    ),
    ("docs/latency.md", "cnctwin bench latency"): Special(
        "long",
        "Heide 2025's protocol: 500 round trips 500 ms apart, about 4 minutes (the page says so)",
        quick="cnctwin bench latency --n 50 --interval-ms 20 --json",
    ),
    ("docs/latency.md", "cnctwin bench latency --endpoint opc.tcp://192.168.0.20:4840/cnctwin"): (
        # the one line does not name the address yet ("cannot connect: connection lost")
        Special("unreachable", REMOTE.format("server"), expect="cannot connect")
    ),
    ("docs/study.md", "cnctwin study dexel --out study/"): Special(
        "long",
        "the paper's 240 runs: minutes (81 s on 2 loaded cores); the page shows --quick",
        quick="cnctwin study dexel --out study/ --quick",
    ),
    ("docs/study.md", "cnctwin study dexel --out study/ --workers 1 --json"): Special(
        "long",
        "the paper's 240 runs in one process: minutes; the page shows --quick",
        quick="cnctwin study dexel --out study/ --quick",
    ),
    ("docs/demo.md", "cnctwin demo --config examples/adaptive/adaptive.toml"): Special(
        "long",
        "a live run of 40 s to 3 minutes on 2 loaded cores; the page's wear example runs the "
        "same `demo --config`",
        quick="cnctwin demo --config examples/wear/wear_twin.toml",
    ),
    (
        "docs/demo.md",
        "cnctwin demo --config examples/chatter_live/chatter_live.toml --duration 120",
    ): Special(
        "long",
        "a live run integrating the cut's vibration in real time, 20 s to 2 minutes on 2 loaded "
        "cores; the page's wear example runs the same `demo --config`",
        quick="cnctwin demo --config examples/wear/wear_twin.toml",
    ),
    ("docs/security.md", ""): Special(
        "elsewhere",
        "tests/cli/test_security_docs.py runs every command of the page as written, with the "
        "certificates of docs/opcua.md's OpenSSL commands made by `cryptography`",
    ),
}

#: Pages whose servers listen on fixed ports (4840, 5020, 8765, 8766): each page runs in a
#: network namespace of its own where the system allows it, else these run one after the other.
FIXED_PORTS = (
    "README.md",
    "docs/dashboard.md",
    "docs/roughness.md",
    "docs/run-browser.md",
    "docs/twin.md",
    "docs/virtual-machine.md",
)
#: Longest a command may take before it counts as hung, s (a loaded 2-core machine).
TIMEOUT_S = 300.0

ALL = [c for page in PAGES for c in commands(page.read_text("utf-8"), str(page.relative_to(REPO)))]
ISOLATION = isolation()
#: The pages' commands run in these groups, one group per test (in parallel under -n).
GROUPS = [(page,) for page in sorted({c.page for c in ALL} - set(FIXED_PORTS))] + (
    [(page,) for page in FIXED_PORTS] if ISOLATION else [FIXED_PORTS]
)


def parse(argv: tuple[str, ...]) -> None:
    """Resolve the subcommands of ``argv`` and let the leaf command parse the rest."""
    command = typer.main.get_command(app)
    args = list(argv)
    context: typer.Context | None = None
    name = "cnctwin"
    while isinstance(command, TyperGroup) and args and not args[0].startswith("-"):
        context = typer.Context(command, info_name=name, parent=context)
        name = args.pop(0)
        sub = command.get_command(context, name)
        if sub is None:
            raise typer.TyperException(f"no command {name!r}")
        command = sub
    with command.make_context(name, args, parent=context) as leaf:
        assert leaf.command is command


def missing_inputs(command: Command) -> list[str]:
    """The files ``command`` reads that are neither in the repository nor written before it."""
    argv = ("cnctwin", *command.argv)
    written = outputs(list(argv))
    missing = []
    for word in argv[1:]:
        value = word.split("=", 1)[1] if word.startswith("--") and "=" in word else word
        if not READS.search(value) or value in written or value in command.written:
            continue
        if value in MADE_ELSEWHERE.get(command.page, ()):
            continue
        path = REPO / value
        if value.startswith("../shared/") and not (SHARED / "data").exists():
            continue  # the shared data is not here; its own tests say so
        if not path.exists():
            missing.append(value)
    return missing


def test_the_pages_show_commands() -> None:
    assert len(ALL) >= 60
    assert any(c.page == "README.md" for c in ALL)


@pytest.mark.parametrize("command", ALL, ids=str)
def test_a_documented_command_parses(command: Command) -> None:
    try:
        parse(command.argv)
    except typer.Exit:
        pass  # --help or --version: printed and done
    except typer.TyperException as err:
        pytest.fail(f"{command}\n  {err}")


@pytest.mark.parametrize("command", ALL, ids=str)
def test_the_files_a_documented_command_reads_exist(command: Command) -> None:
    missing = missing_inputs(command)
    assert not missing, f"{command}\n  reads files that are not there: {missing}"


@pytest.mark.parametrize("command", ALL, ids=str)
def test_a_documented_command_writes_inside_its_working_directory(command: Command) -> None:
    for written in outputs(["cnctwin", *command.argv]) | {command.stdout_to or "."}:
        assert not Path(written).is_absolute() and ".." not in Path(written).parts, (
            f"{command}\n  writes {written!r} outside the directory it runs in"
        )


def test_every_special_command_is_on_its_page() -> None:
    shown = {(c.page, c.line) for c in ALL}
    for (page, line), how in SPECIAL.items():
        assert how.kind in ("server", "unreachable", "long", "elsewhere"), how
        assert line == "" or (page, line) in shown, f"{page}: no `{line}` (SPECIAL is stale)"
        if how.kind == "long":
            assert (page, how.quick) in shown, f"{page}: its quick variant `{how.quick}` is gone"


@pytest.mark.parametrize("pages", GROUPS, ids=" ".join)
def test_the_commands_of_a_page_run_as_written(pages: tuple[str, ...], tmp_path: Path) -> None:
    reads_shared = any(c.page in pages and "../shared/" in shlex.join(c.argv) for c in ALL)
    if reads_shared and not (SHARED / "data").is_dir():
        missing("../shared/data is not here; the page's commands read it", "CNCTWIN_REQUIRE_DATA")
    problems = []
    for page in pages:
        root = tmp_path / Path(page).stem
        if ISOLATION:
            root.mkdir()
            results = run_page_isolated(page, SPECIAL, ISOLATION, root, TIMEOUT_S)
        else:
            results = run_page(page, SPECIAL, root, TIMEOUT_S)  # type: ignore[assignment]
        problems += [f"{r.command} ({r.seconds:.1f} s): {r.problem}" for r in results if r.problem]
    assert not problems, "\n\n".join(problems)


def test_the_checks_catch_a_wrong_option_an_unknown_command_and_a_missing_file() -> None:
    page = (
        "```sh\nD=examples/stability\ncnctwin nc inspect part.ngc --no-such-option\n"
        "cnctwin nope\ncnctwin modal fit $D/x.txt --modes-out m.toml > fit.json\n```\n"
        "```sh\ncnctwin stability lobes --modes-file m.toml \\\n"
        "    --config $D/insperger_slot.toml &\n```\n"
    )
    wrong, unknown, fit, lobes = commands(page, "page.md")
    with pytest.raises(typer.TyperException, match="no-such-option"):
        parse(wrong.argv)
    with pytest.raises(typer.TyperException, match="nope"):
        parse(unknown.argv)
    assert missing_inputs(wrong) == ["part.ngc"]
    assert fit.argv[-1] == "m.toml" and missing_inputs(fit) == ["examples/stability/x.txt"]
    assert fit.stdout_to == "fit.json" and lobes.background
    assert lobes.written == {"m.toml", "fit.json"} and missing_inputs(lobes) == []


def test_the_steps_of_a_page_keep_the_preparing_lines_and_the_input() -> None:
    page = (
        "```sh\nK=a.csv\n{ echo t,x; tail -n +2 $K; } > k.csv\n"
        "printf '%s\\n' 'pw' | cnctwin virtual hash-password --user u > users.toml\n```\n"
    )
    prepare, hash_password = steps(page, "page.md")
    assert isinstance(prepare, Shell) and isinstance(hash_password, Command)
    assert prepare.line.startswith("{ echo") and dict(prepare.variables) == {"K": "a.csv"}
    assert hash_password.stdin_from == ("printf", "%s\\n", "pw")
    assert hash_password.stdout_to == "users.toml"


def test_a_failing_command_is_reported(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "page.md").write_text(
        "```sh\ncnctwin nc inspect no-such.ngc\ncnctwin forces --help\n```\n"
    )
    for shipped in SHIPPED:
        (tmp_path / shipped).mkdir(parents=True)
    monkeypatch.setattr("_documented.REPO", tmp_path)
    failed, helped = run_page("page.md", {}, tmp_path / "run", TIMEOUT_S)
    assert "exit 2" in failed.problem and "no-such.ngc" in failed.problem
    assert helped.problem == ""
