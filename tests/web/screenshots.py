"""Screenshots the browser tests take, kept for the documentation on request.

With ``CNCTWIN_DOCS_IMG=docs/img`` set, :func:`keep` also writes each screenshot there under
its name (docs/run-browser.md and docs/reports.md show them); without it nothing is written
outside the test's own folder.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np
from PIL import Image


def distinct_colours(png: bytes) -> int:
    """How many different RGB colours a PNG holds (a blank area: 1)."""
    pixels = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).reshape(-1, 3)
    return len(np.unique(pixels, axis=0))


def keep(png: bytes, name: str) -> None:
    """Write ``png`` as ``$CNCTWIN_DOCS_IMG/name`` when that variable is set."""
    folder = os.environ.get("CNCTWIN_DOCS_IMG")
    if folder:
        Path(folder).mkdir(parents=True, exist_ok=True)
        (Path(folder) / name).write_bytes(png)
