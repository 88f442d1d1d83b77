"""Example files that ship with cnctwin: configurations and NC programs.

``demo.toml`` describes a small 3-axis mill with two tools, a block of aluminium and a G54
offset; ``demo.ngc`` machines a rounded pocket (helical entry, G2/G3 arcs) and drills four
holes (G81) in it, in mm (the examples of ``cnctwin nc``, ``simulate``, ``signals``; see
examples/README.md). ``demo_twin.toml`` and ``demo_twin.ngc`` are what ``cnctwin demo``
runs: a twin configuration with its virtual machine (a slender end mill, a hole in the
blank) and three passes that trigger both of the twin's use cases (docs/demo.md).
"""

from __future__ import annotations

from importlib.resources import files
from importlib.resources.abc import Traversable

__all__ = ["example_file"]


def example_file(name: str) -> Traversable:
    """A packaged example file, e.g. ``example_file("demo.ngc")``; use it with ``as_file``."""
    return files(__name__) / name
