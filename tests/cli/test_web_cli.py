"""``cnctwin web``: bad options end in one line and exit 2 before anything is served."""

from cnctwin.cli import run as cli_run


def test_cli_refuses_bad_input_in_one_line(tmp_path, capsys) -> None:
    assert cli_run(["web", "--db", str(tmp_path / "none.sqlite")]) == 2
    assert "no historian database at" in capsys.readouterr().err
    assert cli_run(["web", "--host", "0.0.0.0"]) == 2
    err = capsys.readouterr().err
    assert "--insecure" in err and err.count("\n") == 1
    assert cli_run(["web", "--port", "70000"]) == 2
    assert "--port 70000" in capsys.readouterr().err
