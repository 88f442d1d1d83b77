"""Certificate trust lists for OPC UA: which peer certificates a server or the twin accepts.

A trust folder holds the certificates (``.der`` or ``.pem``, nothing else) of the peers to
accept, or of the certificate authorities that signed them. A peer whose certificate is not in
it, not signed by one in it, expired, or not made out to the application URI it claims is
refused with ``BadCertificateUntrusted`` (or the matching ``BadCertificate...`` status) before
its session exists. The checks are asyncua's
(:class:`asyncua.crypto.validator.CertificateValidator` with
``TRUSTED_VALIDATION``: time range, application URI, key usage, extended key usage, trust).

Trust on first use is an opt-in for the client: with an empty folder, the first server
certificate seen is written into the folder (and logged), and from then on only that one is
accepted.
"""

from __future__ import annotations

import hashlib
import logging
from pathlib import Path
from typing import Literal

from asyncua import ua
from asyncua.common.utils import ServiceError
from asyncua.crypto.truststore import TrustStore
from asyncua.crypto.validator import CertificateValidator, CertificateValidatorOptions
from cryptography import x509
from cryptography.hazmat.primitives.serialization import Encoding

from cnctwin.errors import ConfigError

__all__ = ["TrustList"]

logger = logging.getLogger(__name__)

_SUFFIXES = (".der", ".pem")


class TrustList:
    """The certificates a server accepts from clients, or the twin from servers.

    Use as the ``certificate_validator`` of an asyncua ``Server`` or ``Client`` after
    :meth:`load`.

    Parameters
    ----------
    folder
        Folder of trusted certificates (``.der``/``.pem``).
    peer
        Who presents the certificates checked: ``"client"`` (a server's list) or
        ``"server"`` (the twin's list); the extended key usage checked follows.
    first_use
        Trust on first use: if ``folder`` holds no certificate, write the first one presented
        into it and trust only that one from then on.
    """

    def __init__(
        self, folder: Path, peer: Literal["client", "server"], first_use: bool = False
    ) -> None:
        self.folder = folder
        self.peer = peer
        self.first_use = first_use
        role = (
            CertificateValidatorOptions.PEER_CLIENT
            if peer == "client"
            else CertificateValidatorOptions.PEER_SERVER
        )
        self._store = TrustStore([folder], [])
        self._validator = CertificateValidator(
            CertificateValidatorOptions.TRUSTED_VALIDATION | role, self._store
        )

    def certificates(self) -> list[Path]:
        """The certificate files in the folder."""
        return sorted(p for p in self.folder.iterdir() if p.suffix.lower() in _SUFFIXES)

    async def load(self) -> None:
        """Read the folder; ConfigError if it is missing, unreadable, or empty (without
        trust on first use)."""
        if not self.folder.is_dir():
            raise ConfigError(
                f"trust folder {str(self.folder)!r} not found; create it and copy the "
                f"certificates of the {self.peer}s to accept into it (.der or .pem)"
            )
        if not self.certificates():
            if self.first_use:
                return
            raise ConfigError(
                f"trust folder {str(self.folder)!r} holds no certificate; copy the "
                f"certificates of the {self.peer}s to accept into it (.der or .pem)"
            )
        try:
            await self._store.load_trust()
        except (ValueError, OSError) as err:
            raise ConfigError(
                f"trust folder {str(self.folder)!r}: a file is not a certificate ({err}); "
                "keep only certificates (.der or .pem) there, no keys"
            ) from err

    async def __call__(
        self, certificate: x509.Certificate, application: ua.ApplicationDescription
    ) -> None:
        """Accept ``certificate`` or raise asyncua's ServiceError (a ``BadCertificate...``
        status) that refuses the session."""
        if self.first_use and not self.certificates():
            await self._remember(certificate)
        try:
            await self._validator.validate(certificate, application)
        except ServiceError as err:
            logger.warning(
                "%s certificate %s refused: %s (trust folder %s)",
                self.peer,
                certificate.subject.rfc4514_string(),
                ua.StatusCode(ua.UInt32(err.code)).name,
                self.folder,
            )
            raise

    async def _remember(self, certificate: x509.Certificate) -> None:
        der = certificate.public_bytes(Encoding.DER)
        path = self.folder / f"first-use-{hashlib.sha256(der).hexdigest()[:16]}.der"
        path.write_bytes(der)
        logger.warning(
            "trust on first use: trusting the %s certificate %s (SHA-256 %s), saved to %s",
            self.peer,
            certificate.subject.rfc4514_string(),
            hashlib.sha256(der).hexdigest(),
            path,
        )
        await self._store.load_trust()
