"""Example files that ship with cnctwin: the demo configuration and NC program.

``demo.toml`` describes a small 3-axis mill with two tools, a block of aluminium and a G54
offset; ``demo.ngc`` machines a rounded pocket (helical entry, G2/G3 arcs) and drills four
holes (G81) in it, in mm. ``cnctwin demo`` runs them; see examples/README.md.
"""

from __future__ import annotations

from importlib.resources import files
from importlib.resources.abc import Traversable

__all__ = ["example_file"]


def example_file(name: str) -> Traversable:
    """A packaged example file, e.g. ``example_file("demo.ngc")``; use it with ``as_file``."""
    return files(__name__) / name
