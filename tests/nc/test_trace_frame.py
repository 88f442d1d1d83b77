"""canonical_moves and format_trace refuse an unknown frame with an InputError naming it."""

from __future__ import annotations

import pytest

from cnctwin.errors import InputError
from cnctwin.nc import canonical_moves, format_trace, interpret_text


def test_an_unknown_frame_is_an_input_error_naming_it() -> None:
    segments = list(interpret_text("G21 G90\nG1 X10 F600\nM2\n"))
    assert len(list(canonical_moves(segments, frame="machine"))) > 0
    with pytest.raises(InputError, match="not 'workpiece'"):
        list(canonical_moves(segments, frame="workpiece"))
    with pytest.raises(InputError, match="not 'tool'"):
        list(format_trace(segments, frame="tool"))
