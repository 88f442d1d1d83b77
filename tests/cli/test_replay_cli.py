"""``cnctwin virtual serve --replay``: bad logs and option conflicts, one line and exit 2."""

from __future__ import annotations

from pathlib import Path

import pytest

from cnctwin.cli.app import run


def _csv(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--replay", "BAD"], "bad.csv: column 'x_mm' is not numeric (line 3: 'oops')"),
        (["--replay", "BAD", "--map", "no.toml"], "no.toml: cannot read mapping"),
        (["--map", "m.toml"], "--map needs --replay LOG"),
        (["--replay", "BAD", "--loop", "--once"], "--loop and --once: give one"),
        (["--replay", "BAD", "--config", "x.toml"], "--config and --replay: give one"),
    ],
)
def test_cli_refuses_bad_replays_in_one_line_exit_2(
    tmp_path: Path, argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = str(_csv(tmp_path / "bad.csv", "time_s,x_mm\n0,1\n0.1,oops\n"))
    assert run(["virtual", "serve", "--port", "0", *(bad if a == "BAD" else a for a in argv)]) == 2
    err = capsys.readouterr().err
    assert message in err
    assert err.count("\n") == 1
