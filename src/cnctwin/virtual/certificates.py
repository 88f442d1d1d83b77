"""Self-signed OPC UA application certificates for the twin and the virtual machine, made with
``cryptography``: loopback trials of message security without OpenSSL.

The same extensions as the OpenSSL commands of docs/opcua.md: the application URI and
``localhost`` in the subject alternative name, key usage digitalSignature, nonRepudiation,
keyEncipherment, dataEncipherment, and serverAuth or clientAuth; RSA 2048, SHA-256.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path
from typing import Literal

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import rsa
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from cnctwin.thread import CLIENT_APPLICATION_URI
from cnctwin.virtual.opcua_server import SERVER_APPLICATION_URI

__all__ = ["application_certificate"]

Role = Literal["server", "client"]


def application_certificate(
    folder: Path, name: str, role: Role, expired: bool = False, der: bool = False
) -> tuple[Path, Path]:
    """Write a self-signed application certificate and its key into ``folder``.

    Parameters
    ----------
    folder
        Where to write ``NAME-cert.pem`` (``NAME-cert.der`` with ``der``) and ``NAME-key.pem``
        (PKCS#8, unencrypted); made if missing.
    name
        The file names' stem and the certificate's common name.
    role
        ``"server"``: the virtual machine's application URI, serverAuth; ``"client"``: the
        twin's, clientAuth.
    expired
        Valid from two days ago until yesterday (to try a refusal); else from 5 min ago for
        one day.
    der
        Write the certificate DER-encoded rather than PEM.

    Returns
    -------
    tuple
        The certificate's and the key's paths.
    """
    uri, usage = (
        (SERVER_APPLICATION_URI, ExtendedKeyUsageOID.SERVER_AUTH)
        if role == "server"
        else (CLIENT_APPLICATION_URI, ExtendedKeyUsageOID.CLIENT_AUTH)
    )
    key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)])
    now = dt.datetime.now(dt.UTC) - dt.timedelta(days=2 if expired else 0)
    cert = (
        x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=1))
        .add_extension(
            x509.SubjectAlternativeName(
                [x509.UniformResourceIdentifier(uri), x509.DNSName("localhost")]
            ),
            critical=False,
        )
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                content_commitment=True,
                key_encipherment=True,
                data_encipherment=True,
                key_agreement=False,
                key_cert_sign=False,
                crl_sign=False,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.ExtendedKeyUsage([usage]), critical=False)
        .sign(key, hashes.SHA256())
    )
    folder.mkdir(parents=True, exist_ok=True)
    encoding = serialization.Encoding.DER if der else serialization.Encoding.PEM
    cert_path = folder / f"{name}-cert.{'der' if der else 'pem'}"
    key_path = folder / f"{name}-key.pem"
    cert_path.write_bytes(cert.public_bytes(encoding))
    key_path.write_bytes(
        key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
    )
    return cert_path, key_path
