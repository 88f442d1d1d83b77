"""Users file, roles and password hashes of the virtual machine's OPC UA server."""

from __future__ import annotations

import base64
import hashlib
from pathlib import Path

import pytest

from cnctwin.errors import ConfigError
from cnctwin.virtual.exposure import check_exposure, is_loopback
from cnctwin.virtual.users import UserTable, hash_password, load_users, verify_password


def test_hash_is_scrypt_of_rfc7914_salted_and_verified() -> None:
    stored = hash_password("s3cret", salt=b"0123456789abcdef")
    scheme, n, r, p, salt, key = stored.split("$")
    assert (scheme, n, r, p) == ("scrypt", "16384", "8", "1")
    # the key is hashlib's scrypt (OpenSSL's RFC 7914 implementation) of the password
    expected = hashlib.scrypt(b"s3cret", salt=b"0123456789abcdef", n=16384, r=8, p=1, dklen=32)
    assert base64.b64decode(key) == expected
    assert verify_password("s3cret", stored)
    assert not verify_password("s3cret ", stored)
    assert hash_password("s3cret") != hash_password("s3cret")  # random salt
    with pytest.raises(ConfigError, match="empty password"):
        hash_password("")


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "users.toml"
    path.write_text(text)
    return path


def test_users_file_roles_and_anonymous(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        f'anonymous = "none"\n[users.twin]\nrole = "operator"\n'
        f'password_hash = "{hash_password("op")}"\n'
        f'[users.viewer]\nrole = "read-only"\npassword_hash = "{hash_password("view")}"\n',
    )
    table = load_users(path)
    assert table.role_of("twin", "op") == "operator"
    assert table.role_of("viewer", "view") == "read-only"
    assert table.role_of("twin", "view") is None
    assert table.role_of("admin", "anything") is None
    assert table.role_of(None, None) is None
    assert UserTable().role_of(None, None) == "read-only"  # the default: anonymous reads


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('anonymous = "admin"\n', "anonymous = 'admin'; valid: read-only, operator, none"),
        ('[users.x]\nrole = "admin"\npassword_hash = "h"\n', "[users.x] role = 'admin'"),
        ('[users.x]\nrole = "operator"\npassword = "plain"\n', "needs exactly role and"),
        ('[users.x]\nrole = "operator"\npassword_hash = "plain"\n', "is not a password hash"),
        (
            '[users.x]\nrole = "operator"\npassword_hash = "scrypt$1048576$8$1$AAAAAAAAAAA=$'
            + "A" * 43
            + '="\n',
            "scrypt cost n=1048576",
        ),
        ("admins = 1\n", "unknown key(s) admins"),
        ("[users\n", "not a TOML users file"),
    ],
)
def test_bad_users_files_name_the_entry(tmp_path: Path, text: str, message: str) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(ConfigError) as err:
        load_users(path)
    assert message in str(err.value)
    assert str(path) in str(err.value)
    assert "\n" not in str(err.value)


def test_exposure_only_loopback_without_security() -> None:
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.0.20")
    assert not is_loopback("cnc-17.plant.local")
    check_exposure("127.0.0.2", "modbus", secured=False, insecure=False)
    check_exposure("0.0.0.0", "opcua", secured=True, insecure=False)
    check_exposure("0.0.0.0", "modbus", secured=False, insecure=True)
    for transport in ("opcua", "modbus"):
        with pytest.raises(ConfigError, match="--insecure"):
            check_exposure("0.0.0.0", transport, secured=False, insecure=False)


def test_a_server_nobody_could_log_in_to_is_a_config_error() -> None:
    from opcua_fixtures import FakeMachine

    from cnctwin.virtual.opcua_server import OpcUaMachineServer

    with pytest.raises(ConfigError, match="nobody could connect"):
        OpcUaMachineServer(FakeMachine(), users=UserTable(anonymous=None))
