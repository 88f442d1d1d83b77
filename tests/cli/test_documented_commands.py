"""Every ``cnctwin`` command shown in the README and docs/ parses, and the files it reads exist.

The commands are those of the fenced shell blocks (``sh``, ``bash``, ``console``): lines joined
at a trailing backslash, split at ``&&``, ``;``, ``|`` and ``&``, comments dropped, ``$NAME``
expanded from a ``NAME=value`` line before it, ``NAME=value`` before a command dropped. Each
is handed to the real command tree without running it: the subcommands must exist, and the
leaf command must accept the options and arguments (names, counts, types and ranges, required
options) as the CLI checks them before any work. Every file it reads (a word with an input
file's suffix that is not the value of an option that writes) must exist relative to the
repository root, where the commands are written to run, unless a command before it on the
page writes it (an output option, ``> FILE``). Files under ``../shared/`` count only where the
shared data is present (their own tests skip without it, or fail in CI).
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass
from pathlib import Path

import pytest
import typer
from typer.core import TyperGroup

from cnctwin.cli.app import app

REPO = Path(__file__).resolve().parents[2]
PAGES = sorted([REPO / "README.md", *(REPO / "docs").glob("*.md"), REPO / "examples/README.md"])
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)
SHELLS = {"sh", "bash", "console", "shell"}
PROGRAM = re.compile(r"^(?:\S*/)?cnctwin$")
ASSIGNMENT = re.compile(r"^([A-Z_][A-Z0-9_]*)=(\S+)$")
#: Suffixes of the files commands read.
READS = re.compile(r"\.(toml|ngc|nc|mpf|tap|csv|json|txt|camotics|pem|der)$")
#: Options whose value is a file or folder the command writes.
WRITES = {"--out", "--plot", "--report", "--db", "--modes-out", "--signals", "--export"}
#: Commands with an argument that is a file they write: its index in the words.
WRITES_AT = {("runs", "export"): 4}
#: Files a page's commands read that another page's commands make: the page that says how.
MADE_ELSEWHERE = {
    "docs/security.md": {"pki/server-cert.pem", "pki/server-key.pem"},  # docs/opcua.md, OpenSSL
}


@dataclass(frozen=True)
class Command:
    page: str
    argv: tuple[str, ...]
    #: Files written by the commands before this one on its page.
    written: frozenset[str]

    def __str__(self) -> str:
        return f"{self.page}: cnctwin {shlex.join(self.argv)}"


def _outputs(words: list[str]) -> set[str]:
    out = {words[i + 1] for i, w in enumerate(words[:-1]) if w in WRITES or w == ">"}
    at = WRITES_AT.get((words[1], words[2]) if len(words) > 2 else ("", ""))
    if at is not None and len(words) > at:
        out.add(words[at])
    return out


def commands(text: str, page: str) -> list[Command]:
    """The ``cnctwin`` commands of the shell blocks of a page, in order."""
    found: list[Command] = []
    written: set[str] = set()
    variables: dict[str, str] = {}
    for lang, body in FENCE.findall(text):
        if lang not in SHELLS:
            continue
        for line in body.replace("\\\n", " ").splitlines():
            line = line.strip().removeprefix("$ ")
            for part in re.split(r"&&|;|\||&", line):
                words = shlex.split(part, comments=True)
                if len(words) == 1 and (assigned := ASSIGNMENT.match(words[0])):
                    variables[assigned[1]] = assigned[2]
                    continue
                words = [re.sub(r"\$(\w+)", lambda m: variables.get(m[1], m[0]), w) for w in words]
                while len(words) > 1 and ASSIGNMENT.match(words[0]):
                    words.pop(0)  # an environment variable for this command only
                if words and PROGRAM.match(words[0]):
                    argv = words[1 : words.index(">")] if ">" in words else words[1:]
                    found.append(Command(page, tuple(argv), frozenset(written)))
                written |= _outputs(words)
    return found


ALL = [c for page in PAGES for c in commands(page.read_text("utf-8"), str(page.relative_to(REPO)))]


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
    outputs = _outputs(list(argv))
    missing = []
    for word in argv[1:]:
        value = word.split("=", 1)[1] if word.startswith("--") and "=" in word else word
        if not READS.search(value) or value in outputs or value in command.written:
            continue
        if value in MADE_ELSEWHERE.get(command.page, ()):
            continue
        path = REPO / value
        if value.startswith("../shared/") and not (REPO / "../shared/data").exists():
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
    assert lobes.written == {"m.toml", "fit.json"} and missing_inputs(lobes) == []
