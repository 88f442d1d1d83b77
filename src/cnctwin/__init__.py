"""cnctwin: an open-source digital twin for CNC machining."""

__version__ = "0.1.0"
