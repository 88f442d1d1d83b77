"""Who may use the virtual machine's OPC UA server, and for what: users, roles, password hashes.

Two roles: ``"read-only"`` reads and subscribes; ``"operator"`` may also write the command
nodes (overrides, feed hold, stop). Nobody may change the address space. A users file is TOML:

.. code-block:: toml

    anonymous = "read-only"          # or "operator", or "none" (refuse anonymous sessions)

    [users.twin]
    role = "operator"
    password_hash = "scrypt$16384$8$1$..."   # from `cnctwin virtual hash-password`

Passwords are stored only as salted scrypt hashes (RFC 7914; n = 2**14, r = 8, p = 1,
16-byte random salt, 32-byte key), compared in constant time.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import hmac
import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, cast

from cnctwin.errors import ConfigError

__all__ = [
    "ROLES",
    "Account",
    "Role",
    "UserTable",
    "hash_password",
    "load_users",
    "verify_password",
]

Role = Literal["read-only", "operator"]

#: The roles a user or the anonymous session may have.
ROLES: tuple[Role, ...] = ("read-only", "operator")

_SCHEME = "scrypt"
_N, _R, _P = 2**14, 8, 1
_SALT_BYTES = 16
_KEY_BYTES = 32
#: Largest scrypt cost accepted from a file (128 * n * r bytes of memory: 64 MiB at most).
_MAX_MEMORY_BYTES = 64 * 2**20


def hash_password(password: str, salt: bytes | None = None) -> str:
    """A salted scrypt hash of ``password``: ``scrypt$N$R$P$SALT$KEY`` (base64 salt and key).

    Parameters
    ----------
    password
        The password (UTF-8); empty is refused.
    salt
        16 random bytes by default (pass one only to reproduce a hash).
    """
    if not password:
        raise ConfigError("empty password; give at least one character")
    salt = os.urandom(_SALT_BYTES) if salt is None else salt
    key = _scrypt(password, salt, _N, _R, _P)
    return "$".join((_SCHEME, str(_N), str(_R), str(_P), _b64(salt), _b64(key)))


def verify_password(password: str, stored: str) -> bool:
    """Whether ``password`` matches the hash ``stored`` (constant-time comparison)."""
    n, r, p, salt, key = _parse_hash(stored, "password hash")
    return hmac.compare_digest(_scrypt(password, salt, n, r, p), key)


@dataclass(frozen=True)
class Account:
    """A user of the server: its role and password hash (:func:`hash_password`)."""

    role: Role
    password_hash: str


@dataclass(frozen=True)
class UserTable:
    """The server's users, and what an anonymous session may do.

    Attributes
    ----------
    accounts
        User name -> :class:`Account`.
    anonymous
        Role of a session without user name (``None``: anonymous sessions are refused).
    """

    accounts: Mapping[str, Account] = field(default_factory=dict)
    anonymous: Role | None = "read-only"

    def role_of(self, username: str | None, password: str | None) -> Role | None:
        """The role of a login, or ``None`` if refused (unknown user or wrong password).

        ``username=None`` is an anonymous session. An unknown user costs the same hash as a
        known one, so the answer time does not tell which user names exist.
        """
        if username is None:
            return self.anonymous
        account = self.accounts.get(username)
        matches = verify_password(password or "", account.password_hash if account else _DECOY)
        return account.role if account is not None and matches else None


def load_users(path: Path) -> UserTable:
    """Read a users file (module docstring); ConfigError naming the file and the entry."""
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as err:
        raise ConfigError(f"cannot read users file: {err.strerror or err}", str(path)) from err
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise ConfigError(f"not a TOML users file: {err}", str(path)) from err
    unknown = sorted(set(data) - {"anonymous", "users"})
    if unknown:
        raise ConfigError(
            f"unknown key(s) {', '.join(unknown)}; valid: anonymous, users", str(path)
        )
    anonymous = data.get("anonymous", "read-only")
    if anonymous not in (*ROLES, "none"):
        raise ConfigError(f"anonymous = {anonymous!r}; valid: {', '.join(ROLES)}, none", str(path))
    users = data.get("users", {})
    if not isinstance(users, dict):
        raise ConfigError("users must be a table of [users.NAME] tables", str(path))
    accounts: dict[str, Account] = {}
    for name, entry in users.items():
        where = f"[users.{name}]"
        if not isinstance(entry, dict) or set(entry) != {"role", "password_hash"}:
            raise ConfigError(f"{where} needs exactly role and password_hash", str(path))
        if entry["role"] not in ROLES:
            raise ConfigError(
                f"{where} role = {entry['role']!r}; valid: {', '.join(ROLES)}", str(path)
            )
        if not isinstance(entry["password_hash"], str):
            raise ConfigError(f"{where} password_hash must be a string", str(path))
        _parse_hash(entry["password_hash"], f"{path}: {where} password_hash")
        accounts[name] = Account(cast(Role, entry["role"]), entry["password_hash"])
    return UserTable(accounts, None if anonymous == "none" else cast(Role, anonymous))


def _parse_hash(stored: str, where: str) -> tuple[int, int, int, bytes, bytes]:
    parts = stored.split("$")
    valid = "valid: scrypt$N$R$P$SALT$KEY from `cnctwin virtual hash-password`"
    if len(parts) != 6 or parts[0] != _SCHEME:
        raise ConfigError(f"{where} is not a password hash; {valid}")
    try:
        n, r, p = (int(x) for x in parts[1:4])
        salt, key = (
            base64.b64decode(parts[4], validate=True),
            base64.b64decode(parts[5], validate=True),
        )
    except (ValueError, binascii.Error) as err:
        raise ConfigError(f"{where} is malformed ({err}); {valid}") from err
    if not (n > 1 and n & (n - 1) == 0 and 1 <= r <= 32 and 1 <= p <= 16) or (
        128 * n * r > _MAX_MEMORY_BYTES
    ):
        raise ConfigError(
            f"{where} has scrypt cost n={n}, r={r}, p={p}; valid: n a power of 2, "
            f"128*n*r <= {_MAX_MEMORY_BYTES} bytes, 1 <= r <= 32, 1 <= p <= 16; {valid}"
        )
    if len(salt) < 8 or len(key) != _KEY_BYTES:
        raise ConfigError(
            f"{where} has a {len(salt)}-byte salt and a {len(key)}-byte key; valid: a salt of "
            f"8 bytes or more and a {_KEY_BYTES}-byte key; {valid}"
        )
    return n, r, p, salt, key


def _scrypt(password: str, salt: bytes, n: int, r: int, p: int) -> bytes:
    return hashlib.scrypt(
        password.encode("utf-8"),
        salt=salt,
        n=n,
        r=r,
        p=p,
        maxmem=_MAX_MEMORY_BYTES + 2**20,
        dklen=_KEY_BYTES,
    )


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


#: Compared against when the user name is unknown (same cost as a real account).
_DECOY = "$".join(
    (_SCHEME, str(_N), str(_R), str(_P), _b64(b"\0" * _SALT_BYTES), _b64(b"\0" * _KEY_BYTES))
)
