"""Self-signed OPC UA application certificates for tests: the package's
:func:`cnctwin.virtual.application_certificate`, by the name the tests use."""

from cnctwin.virtual import application_certificate as certificate

__all__ = ["certificate"]
