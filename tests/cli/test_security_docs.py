"""Every command of docs/security.md runs as written, and the secured set-up it describes works.

The certificates the page takes from OpenSSL are made here with ``cryptography`` (same names,
same extensions). The ``serve`` command runs as written plus ``--port 0 --once --speed 20
--delay 0`` (a free port, and an end); the twin's TOML block connects to it as written, with
that port in its endpoint.
"""

from __future__ import annotations

import asyncio
import io
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from pki import certificate

from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.opcua import OpcUaConnection

DOC = Path(__file__).resolve().parents[2] / "docs" / "security.md"
#: Generous: the served machine compiles its kernels before it listens (seconds, more on a
#: loaded machine).
START_TIMEOUT_S = 180.0


def _blocks(kind: str) -> list[str]:
    return re.findall(rf"```{kind}\n(.*?)```", DOC.read_text(), flags=re.S)


def _commands() -> list[str]:
    return [line for block in _blocks("sh") for line in block.splitlines() if line.strip()]


def _shell(command: str, cwd: Path, **kwargs: object) -> subprocess.Popen[str]:
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    return subprocess.Popen(
        command, shell=True, cwd=cwd, env=env, text=True,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, **kwargs,  # type: ignore[arg-type]
    )  # fmt: skip


def test_documented_commands_run_and_secure_the_twin(tmp_path: Path) -> None:
    for name, role in (("server", "server"), ("twin", "client")):
        certificate(tmp_path / "pki", name, role)
    commands = _commands()
    serve = [c for c in commands if c.startswith("cnctwin virtual serve") and "--security" in c]
    assert len(serve) == 1 and "0.0.0.0" not in DOC.read_text()
    for command in commands:
        if command in serve:
            continue
        _, _, message = command.partition("# exit ")
        process = _shell(command, tmp_path)
        _, err = process.communicate(timeout=120)
        if message:  # documented as refused: that exit status and one line saying why
            status, _, text = message.partition(": ")
            assert process.returncode == int(status)
            assert text.rstrip(". ") in err and err.count("\n") == 1, err
        else:
            assert process.returncode == 0 and not err, (command, err)
    users = tomllib.loads((tmp_path / "users.toml").read_text())
    assert users["users"]["twin"]["role"] == "operator"

    server = _shell(serve[0] + " --port 0 --once --speed 20 --delay 0", tmp_path)
    try:
        assert server.stdout is not None
        endpoint = server.stdout.readline().strip()
        assert endpoint.startswith("opc.tcp://127.0.0.1:"), server.stderr
        (twin_toml,) = [b for b in _blocks("toml") if "[connection.security]" in b]
        table = tomllib.loads(twin_toml)["connection"]
        table["endpoint"] = endpoint
        connection = OpcUaConnection(ConnectionConfig(**table), base_dir=tmp_path)

        async def twin() -> float:
            async with connection:
                await connection.write("feed_override_pct", 80.0)
                return await connection.read_signal("feed_override_pct")

        assert asyncio.run(asyncio.wait_for(twin(), 60)) == 80.0
    finally:
        server.kill()
        server.wait()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--host", "0.0.0.0"], "refusing to serve opcua without security on '0.0.0.0'"),
        (["--transport", "modbus", "--host", "10.0.0.5"], "Modbus TCP has no security"),
        (["--security-mode", "Encrypt"], "--security-mode 'Encrypt'; valid: None, Sign,"),
        (["--security-mode", "Sign"], "needs a server certificate and private key"),
        (["--transport", "modbus", "--trust", "pki"], "--trust: OPC UA only"),
        (["--anonymous", "admin"], "--anonymous 'admin'; valid: none, read-only, operator"),
        (["--users", "no-such.toml"], "no-such.toml: cannot read users file"),
    ],
)
def test_refused_serve_options_exit_2_with_one_line(argv: list[str], message: str) -> None:
    refused = _shell(" ".join(["cnctwin", "virtual", "serve", *argv]), Path.cwd())
    _, err = refused.communicate(timeout=120)
    assert refused.returncode == 2
    assert message in err and err.count("\n") == 1, err


def test_hash_password_prints_a_users_table_that_loads(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from cnctwin.cli.app import run
    from cnctwin.virtual.users import load_users

    monkeypatch.setattr(sys, "stdin", io.StringIO("pass word\n"))
    assert run(["virtual", "hash-password", "--user", "Jane Doe", "--role", "read-only"]) == 0
    (tmp_path / "users.toml").write_text(capsys.readouterr().out)
    assert load_users(tmp_path / "users.toml").role_of("Jane Doe", "pass word") == "read-only"
    assert run(["virtual", "hash-password", "--role", "admin"]) == 2
    assert "--role 'admin'; valid: read-only, operator" in capsys.readouterr().err
