"""``cnctwin run`` with a ``[[twin.models]]`` entry the twin cannot feed: one line, exit 2."""

from __future__ import annotations

from pathlib import Path

import pytest
from tiny_models import tiny_model

from cnctwin.cli import run
from cnctwin.examples import example_file


def test_cnctwin_run_refuses_the_model_in_one_line_before_connecting(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    spec = {"sample_period_s": 0.0125, "signals": {"X1_OutputPower": "kW"}}
    tiny_model(tmp_path, spec, "X1_OutputPower")
    text = example_file("demo_twin.toml").read_text()
    (tmp_path / "demo_twin.ngc").write_text(example_file("demo_twin.ngc").read_text())
    config = tmp_path / "twin.toml"
    config.write_text(text + '\n[[twin.models]]\nname = "load"\npath = "X1_OutputPower.onnx"\n')
    # nothing listens on this port: a refusal before connecting is the model's, at once
    db = tmp_path / "h.sqlite"
    argv = ["run", "--config", str(config), "--endpoint", "opc.tcp://127.0.0.1:9/x", "--db"]
    code = run([*argv, str(db)])
    _, err = capsys.readouterr()
    lines = [line for line in err.splitlines() if not line.startswith("history: ")]
    assert code == 2
    assert len(lines) == 1 and "'X1_OutputPower'" in lines[0] and "twin.models[0]" in lines[0]
