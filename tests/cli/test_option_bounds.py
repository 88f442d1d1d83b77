"""Every numeric option of the whole CLI, walked from the command tree, with extreme values.

For each command an explicit, valid base invocation is kept in :data:`BASES`; a command
without one fails :func:`test_every_command_has_a_base_invocation`, so no command joins the CLI
unchecked. Each numeric option (an int or float option or argument, a tuple of them, or a
string option that carries numbers, listed in the base's ``numbers``) is then replaced in turn
by nan, inf, -inf, -1, 0, 1e308, -1e308, 1e-300 (and 10**12 for integers). The property: exit
0 or 2, never 1 (an internal error) or an exception; on exit 2, stderr is one line that names
the option (or the quantity, e.g. ``vb0_mm`` for ``--vb0-mm``). Non-finite values are always
refused.

Commands that would run long (demo, run, bench, virtual serve, study) get a base invocation that
ends with exit 2 at once *after* option validation (an unknown transport, a missing file):
their options are validated before any work, so a bad value is still named; there, +-1e308 and
10**12 must be refused too (no option of those commands takes them).
"""

from __future__ import annotations

import json
import re
import signal
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import Any, get_args

import numpy as np
import pytest
import typer
from typer.core import TyperArgument, TyperGroup

from cnctwin.cli.app import app, run

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "examples"
PACKAGED = REPO / "src" / "cnctwin" / "examples"
STABILITY = EXAMPLES / "stability" / "insperger_slot.toml"
#: Values each numeric option is replaced by.
EXTREMES = ("nan", "inf", "-inf", "-1", "0", "1e308", "-1e308", "1e-300")
NON_FINITE = ("nan", "inf", "-inf")
#: Values out of every option's range: refused by name even where the base ends with exit 2
#: (10**12 is a valid run id, an argument of ``runs``: it is only refused for options).
REFUSED = (*NON_FINITE, "1e308", "-1e308", "1000000000000")
#: One invocation must not run longer than this (s): far above the slowest valid case
#: (a fraction of a second), low enough that an unbounded loop is reported, not waited for.
CASE_LIMIT_S = 60


def _cut_csv(path: Path) -> Path:
    """Turning cuts of a power law Ra = 0.5 ap^0.4 S^0.05 fz^0.55 V^0.17 (roughness fit)."""
    rng = np.random.default_rng(3)
    rows = ["ap_mm,spindle_rpm,fz_mm,vibration_g,ra_um"]
    for _ in range(12):
        ap, s, fz, v = (rng.uniform(lo, hi) for lo, hi in ((1, 4), (3e3, 9e3), (0.05, 0.1), (1, 5)))
        rows.append(f"{ap},{s},{fz},{v},{0.5 * ap**0.4 * s**0.05 * fz**0.55 * v**0.17}")
    path.write_text("\n".join(rows) + "\n")
    return path


def _model(path: Path) -> Path:
    exponents = {"ap_mm": 0.4, "spindle_rpm": 0.05, "fz_mm": 0.55, "vibration_g": 0.17}
    path.write_text(json.dumps({"target": "ra_um", "b0": 0.5, "exponents": exponents}))
    return path


def _frf_csv(path: Path) -> Path:
    """A one-mode FRF table (f in Hz, Re and Im in m/N): 150 Hz, zeta 0.03, k 2e7 N/m."""
    f = np.arange(1.0, 600.0, 1.0)
    r = f / 150.0
    h = 1.0 / (2.0e7 * (1.0 - r**2 + 2j * 0.03 * r))
    rows = (f"{a:.6e},{b.real:.9e},{b.imag:.9e}\n" for a, b in zip(f, h, strict=True))
    path.write_text("".join(rows))
    return path


def _signal_csv(path: Path) -> Path:
    t = np.arange(0.0, 0.5, 1e-4)
    y = np.sin(2 * np.pi * 100.0 * t)
    path.write_text("t_s,a\n" + "".join(f"{a:.6f},{b:.6f}\n" for a, b in zip(t, y, strict=True)))
    return path


def _ekf_csv(path: Path) -> Path:
    rows = ["time_s,torque_nm,material_removed_mm3"]
    rows += [f"{k * 0.01:.2f},0.0035,0.0004" for k in range(1, 51)]
    path.write_text("\n".join(rows) + "\n")
    return path


def _program(path: Path) -> Path:
    path.write_text("G21 G90 G17\nT1 M6\nS6000 M3\nG0 X-10 Y5 Z5\nG1 Z-1 F600\nG1 X10\nM30\n")
    return path


@dataclass(frozen=True)
class Base:
    """A valid invocation of one command (after the command path)."""

    argv: Callable[[Path], list[str]]
    #: String options that carry numbers: option -> template with {v} for the value.
    numbers: dict[str, str] = field(default_factory=dict)
    #: Substring of the one-line error the base ends with on purpose (exit 2), if any.
    ends_with: str | None = None
    #: Each case in a fresh folder (the command changes its files, e.g. a registry).
    fresh: bool = False
    #: Another valid base for options that exclude one of the base's (option -> argv).
    instead: dict[str, Callable[[Path], list[str]]] = field(default_factory=dict)


def _registry(tmp: Path) -> Path:
    db = tmp / "wear.db"
    if not db.exists():
        code = run(
            ["wear", "mount", "--db", str(db), "--tool", "T1", "--target-mm", "20", "--json"]
        )
        assert code == 0
    return db


def _historian(tmp: Path) -> str:
    """An empty historian database (SQLite), created once."""
    from cnctwin.store.historian import Historian

    db = tmp / "h.db"
    if not db.exists():
        with Historian.open(db):
            pass
    return str(db)


BASES: dict[tuple[str, ...], Base] = {
    ("demo",): Base(lambda t: ["--transport", "none", "--json"], ends_with="--transport"),
    ("run",): Base(
        lambda t: ["--config", str(t / "missing.toml"), "--duration", "1"],
        ends_with="missing.toml",
    ),
    ("forces",): Base(
        lambda t: (
            "--diameter-mm 10 --teeth 4 --helix-deg 30 --ae-mm 5 --ap-mm 2 --fz-mm 0.1 "
            "--rpm 6000 --material AA6060-T6 --json"
        ).split(),
        instead=dict.fromkeys(
            ("--ktc", "--krc", "--kac", "--kte", "--kre", "--kae"),
            lambda t: (
                "--diameter-mm 10 --teeth 4 --helix-deg 30 --ae-mm 5 --ap-mm 2 "
                "--fz-mm 0.1 --rpm 6000 --ktc 800 --krc 300 --kac 200 --kte 20 --kre 25 "
                "--kae 2 --json"
            ).split(),
        ),
    ),
    ("materials", "list"): Base(lambda t: ["--json"]),
    ("materials", "identify"): Base(
        lambda t: [
            str(EXAMPLES / "materials" / "kistler_slot_means.csv"),
            *"--teeth 2 --ap-mm 3 --name x --diameter-mm 25 --ae-mm 25".split(),
        ]
    ),
    ("simulate",): Base(
        lambda t: (
            f"{PACKAGED / 'demo.ngc'} -c {PACKAGED / 'demo.toml'} --density 2 "
            "--cycle-ms 100 --json".split()
        )
    ),
    ("optimize",): Base(
        lambda t: (
            f"{_program(t / 'p.ngc')} -c {PACKAGED / 'demo.toml'} --max-force-n 200 "
            f"--density 2 --cycle-ms 100 --out {t / 'opt.ngc'} --json".split()
        )
    ),
    ("signals",): Base(
        lambda t: (
            f"{PACKAGED / 'demo.ngc'} -c {PACKAGED / 'demo.toml'} --density 2 "
            "--cycle-ms 100 --json".split()
        )
    ),
    ("nc", "inspect"): Base(lambda t: [str(PACKAGED / "demo.ngc"), "--json"]),
    ("nc", "trace"): Base(lambda t: [str(PACKAGED / "demo.ngc")]),
    ("bench", "latency"): Base(lambda t: ["--transport", "none"], ends_with="--transport"),
    ("wear", "simulate-lathe"): Base(lambda t: ["--test", "1", "--parts", "3", "--json"]),
    ("learn", "train"): Base(
        lambda t: [
            "--data",
            str(t / "none.csv"),
            "--features",
            str(EXAMPLES / "twin_model" / "features.toml"),
            "--target",
            "y",
            "--group-by",
            "run",
        ],  # fmt: skip
        ends_with="none.csv",
    ),
    ("learn", "evaluate"): Base(
        lambda t: [str(t / "none.onnx"), "--data", str(t / "none.csv")], ends_with="none.onnx"
    ),
    ("learn", "inspect"): Base(lambda t: [str(t / "none.onnx")], ends_with="none.onnx"),
    ("learn", "lead-time"): Base(
        lambda t: [
            "--data",
            str(t / "none.csv"),
            "--labels",
            str(t / "labels.csv"),
            "--label-key",
            "No",
            "--features",
            str(EXAMPLES / "learn" / "umich_clamping.toml"),
            "--target",
            "machining_finalized",
            "--alarm",
            "no",
            "--phase-column",
            "Machining_Process",
            "--active-prefix",
            "Layer",
        ],  # fmt: skip
        ends_with="labels.csv",
    ),
    ("wear", "ekf"): Base(lambda t: ["--data", str(_ekf_csv(t / "ekf.csv")), "--json"]),
    ("wear", "mount"): Base(
        lambda t: ["--db", str(t / "mount.db"), "--tool", "T2", "--target-mm", "20", "--json"],
        fresh=True,
    ),
    ("wear", "compensate"): Base(
        lambda t: ["--db", str(_registry(t)), "--tool", "T1", "--measurement", "20.01", "--json"],
        numbers={"--measurement": "{v}"},
    ),
    ("wear", "retire"): Base(lambda t: ["--db", str(_registry(t)), "--tool", "T1"]),
    ("wear", "history"): Base(lambda t: ["--db", str(_registry(t)), "--json"]),
    ("study", "dexel"): Base(
        lambda t: ["--out", str(_program(t / "a_file")), "--quick"], ends_with="--out"
    ),
    ("mirs", "predict"): Base(
        lambda t: (
            "--diameter-mm 16 --teeth 3 --ae-mm 8 --feed-mm-min 14400 --rpm 30000 "
            "--contact-mm 1 --depth-um 50 --points 2 --json".split()
        )
    ),
    ("mirs", "search"): Base(
        lambda t: (
            "--diameter-mm 16 --teeth 3 --ae-mm 8 --feed-mm-min 14400 --rpm 30000 "
            "--contact-mm 1 --depth-um 50 --points 2 --speeds 2 --min-feed 1000 "
            "--max-feed 14400 --min-rpm 20000 --max-rpm 30000 --json".split()
        )
    ),
    ("roughness", "fit"): Base(lambda t: [str(_cut_csv(t / "cuts.csv")), "--json"]),
    ("roughness", "predict"): Base(
        lambda t: (
            f"--model {_model(t / 'm.json')} --ap-mm 2 --rpm 6000 --fz-mm 0.08 "
            "--vib-g 2 --json".split()
        ),
        numbers={"--value": "vibration_g={v}"},
    ),
    ("dynamics", "fit-frf"): Base(
        lambda t: [str(_frf_csv(t / "frf.csv")), "--band", "50", "500", "--json"]
    ),
    ("modal", "fit"): Base(
        lambda t: [str(_frf_csv(t / "frf.csv")), "--band", "50", "500", "--json"]
    ),
    ("stability", "lobes"): Base(
        lambda t: ["--config", str(STABILITY), "--rpm-range", "5000:6000:5", "--json"],
        numbers={"--rpm": "{v}", "--rpm-range": "5000:{v}:5", "--steps": "{v}"},
    ),
    ("stability", "roadmap"): Base(
        lambda t: (
            f"{PACKAGED / 'demo.ngc'} -c {PACKAGED / 'demo.toml'} --stability {STABILITY} "
            "--rpm-range 5000:6000:3 --density 1 --json".split()
        ),
        numbers={"--rpm-range": "5000:{v}:3"},
    ),
    ("chatter", "simulate"): Base(
        lambda t: (
            f"--config {STABILITY} --rpm 6000 --depth-mm 0.5 --feed-mm 0.05 "
            "--seconds 0.02 --diameter-mm 10 --json".split()
        )
    ),
    ("chatter", "calibrate-damping"): Base(
        lambda t: [str(t / "missing.csv"), "--config", str(STABILITY)], ends_with="missing.csv"
    ),
    ("chatter", "detect"): Base(
        lambda t: [str(_signal_csv(t / "sig.csv")), "--rpm", "6000", "--teeth", "2", "--json"]
    ),
    ("vibration", "simulate"): Base(
        lambda t: (
            f"--config {STABILITY} --rpm 6000 --depth-mm 0.5 --feed-mm 0.05 "
            "--seconds 0.02 --diameter-mm 10 --json".split()
        )
    ),
    ("runs", "list"): Base(lambda t: ["--db", _historian(t), "--json"]),
    ("web",): Base(lambda t: ["--db", str(t / "missing.sqlite")], ends_with="missing.sqlite"),
    ("runs", "show"): Base(lambda t: ["1", "--db", _historian(t)], ends_with="run 1"),
    ("runs", "export"): Base(
        lambda t: ["1", str(t / "out.csv"), "--db", _historian(t)], ends_with="run 1"
    ),
    ("virtual", "serve"): Base(
        lambda t: ["--config", str(t / "missing.toml"), "--port", "0"], ends_with="missing.toml"
    ),
    # no numeric option; the base stops before the password prompt
    ("virtual", "hash-password"): Base(lambda t: ["--role", "admin"], ends_with="--role"),
}


def _commands(
    command: Any = None, path: tuple[str, ...] = ()
) -> Iterator[tuple[tuple[str, ...], Any]]:
    command = command or typer.main.get_command(app)
    if isinstance(command, TyperGroup):
        for name, sub in command.commands.items():
            yield from _commands(sub, (*path, name))
    else:
        yield path, command


COMMANDS = dict(_commands())


def _numeric(annotation: Any) -> str | None:
    """'int' or 'float' for a numeric annotation (also inside Optional, tuple, list)."""
    if annotation in (int, float):
        return annotation.__name__
    inner = {a for a in get_args(annotation) if a is not type(None)}
    kinds = {_numeric(a) for a in inner} - {None}
    return "float" if "float" in kinds else ("int" if kinds else None)


@dataclass(frozen=True)
class Case:
    option: str
    names: tuple[str, ...]
    value: str
    argv: tuple[str, ...]
    argument: bool = False


def _names(opts: list[str]) -> tuple[str, ...]:
    """Ways an error line may name an option: ``--vb0-mm``, ``vb0-mm``, ``vb0_mm``."""
    bare = [o.lstrip("-") for o in opts if o.startswith("--") and len(o) > 4]
    return (*opts, *bare, *(b.replace("-", "_") for b in bare))


def _names_in(names: tuple[str, ...], line: str) -> bool:
    """Whether the line holds one of the names as a whole word (``n`` is not in ``none``)."""
    return any(
        re.search(rf"(?<![\w-]){re.escape(name)}(?![\w-])", line, re.IGNORECASE) for name in names
    )


def _cases(path: tuple[str, ...], base: Base, tmp: Path) -> Iterator[Case]:
    for param in COMMANDS[path].params:
        if param.name in ("help",):
            continue
        annotation = param.type_descriptor.annotation
        kind = _numeric(annotation)
        opt = param.opts[0]
        argv = base.instead.get(opt, base.argv)(tmp)
        template = base.numbers.get(opt)
        if kind is None and template is None:
            continue
        values = EXTREMES + (("1000000000000",) if kind == "int" else ())
        for value in values:
            if isinstance(param, TyperArgument):
                # the base gives a numeric argument as the only all-digit word
                digits = [i for i, a in enumerate(argv) if a.isdigit()]
                assert param.nargs == 1 and len(digits) == 1, f"{path}: base lacks {param.name}"
                new = [*argv[: digits[0]], value, *argv[digits[0] + 1 :]]
                name = param.name or opt
                yield Case(name, (name,), value, tuple(new), argument=True)
                continue
            text = template.format(v=value) if template else value
            arity = max(param.nargs, 1)
            for slot in range(arity):
                new = list(argv)
                if opt in new:
                    at = new.index(opt)
                    olds = new[at + 1 : at + 1 + arity]
                else:
                    default = param.default if arity > 1 else ("1",)
                    at, olds = len(new), [str(v) for v in default]
                    new += [opt, *olds]
                olds = list(olds)
                olds[slot] = text
                new[at + 1 : at + 1 + arity] = olds
                yield Case(opt, _names(param.opts), value, tuple(new))


class _Hang(Exception):
    pass


def _alarm(_signum: int, _frame: FrameType | None) -> None:
    raise _Hang


def test_the_walk_finds_the_numeric_options(tmp_path: Path) -> None:
    """Guards the walk itself: a change of typer's parameter objects must not make every
    option look non-numeric (and the property hold vacuously)."""
    found = {case.option for case in _cases(("forces",), BASES[("forces",)], tmp_path)}
    assert {"--rpm", "--teeth", "--diameter-mm", "--ktc"} <= found
    found = {case.option for case in _cases(("runs", "show"), BASES[("runs", "show")], tmp_path)}
    assert found == {"run_id"}
    found = {case.option for case in _cases(("wear", "ekf"), BASES[("wear", "ekf")], tmp_path)}
    assert {"--stages-mm", "--seed", "--vb0-mm"} <= found


def test_every_command_has_a_base_invocation() -> None:
    missing = sorted(" ".join(p) for p in COMMANDS if p not in BASES)
    stale = sorted(" ".join(p) for p in BASES if p not in COMMANDS)
    assert not missing, f"commands without a base invocation in BASES: {missing}"
    assert not stale, f"BASES names commands the CLI no longer has: {stale}"


@pytest.mark.parametrize("path", sorted(BASES), ids=" ".join)
def test_numeric_options_take_extremes_without_an_internal_error(
    path: tuple[str, ...], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = BASES[path]
    code = run([*path, *base.argv(tmp_path)])
    _, err = capsys.readouterr()
    assert code == (2 if base.ends_with else 0), err
    if base.ends_with:
        assert base.ends_with in err, err
    failures: list[str] = []
    previous = signal.signal(signal.SIGALRM, _alarm)
    try:
        for n, case in enumerate(_cases(path, base, tmp_path)):
            argv = list(case.argv)
            if base.fresh:  # the same argv in a folder of its own
                folder = tmp_path / f"case{n}"
                folder.mkdir()
                argv = [a.replace(str(tmp_path), str(folder)) for a in argv]
            signal.alarm(CASE_LIMIT_S)
            try:
                code = run([*path, *argv])
            except _Hang:
                code = -1
            finally:
                signal.alarm(0)
            _, err = capsys.readouterr()
            lines = err.strip().splitlines()
            named = bool(lines) and _names_in(case.names, lines[-1])
            if case.value.startswith("-") and case.argument:
                # a negative positional argument reads as an unknown option: refused, exit 2
                named = named or bool(lines) and "No such option" in lines[-1]
            where = f"{case.option} {case.value}: exit {code}: {err.strip()[:300]!r}"
            refused = REFUSED[:-1] if case.argument else REFUSED
            if code not in (0, 2):
                failures.append(where)
            elif code == 2 and (
                len(lines) != 1 or not (named or base.ends_with and base.ends_with in lines[0])
            ):
                failures.append(where)
            elif case.value in (refused if base.ends_with else NON_FINITE) and not (
                code == 2 and named
            ):
                failures.append(where)
    finally:
        signal.signal(signal.SIGALRM, previous)
    assert not failures, "\n".join(failures)
