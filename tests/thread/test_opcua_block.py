"""The vibration block read from a machine over OPC UA is untrusted (cnctwin.thread.opcua).

Every malformed value is refused with one line naming the node and what is wrong; a good one
keeps the samples from the index asked for. The layout is the one the virtual machine's
server writes (``[first index, rate (Hz), channels, samples row by row]``, float64 LE).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.errors import DataError
from cnctwin.thread.opcua import _decode_block


def _packed(first: float, rate: float, channels: float, samples: np.ndarray) -> bytes:
    head = np.array([first, rate, channels], dtype="<f8")
    return np.concatenate((head, samples.ravel())).astype("<f8").tobytes()


def test_a_good_block_keeps_the_samples_from_the_index_asked_for() -> None:
    samples = np.arange(20.0).reshape(10, 2)
    block = _decode_block("vibration", _packed(100, 10_000.0, 2, samples), 104)
    assert block.first_index == 104 and block.rate_hz == 10_000.0
    np.testing.assert_array_equal(block.samples, samples[4:])
    assert block.end_index == 110
    older = _decode_block("vibration", _packed(100, 10_000.0, 2, samples), 0)
    assert older.first_index == 100 and older.samples.shape == (10, 2)
    newer = _decode_block("vibration", _packed(100, 10_000.0, 2, samples), 500)
    assert newer.first_index == 110 and newer.samples.shape == (0, 2)


ROWS = np.zeros((4, 2))


@pytest.mark.parametrize(
    ("packed", "message"),
    [
        ("text", "holds str; expected a ByteString"),
        (None, "holds NoneType"),
        (b"\x00" * 20, "of 20 bytes; expected whole float64 values"),
        (b"\x00" * 17, "of 17 bytes"),
        (b"\x00" * (8 * 2**21 + 8), "bytes; expected whole float64 values"),
        (_packed(0, 10_000.0, math.nan, ROWS), "nan channels"),
        (_packed(0, 10_000.0, math.inf, ROWS), "inf channels"),
        (_packed(0, 10_000.0, 0, ROWS), "0.0 channels"),
        (_packed(0, 10_000.0, 1.5, ROWS), "1.5 channels"),
        (_packed(0, 10_000.0, 1e18, ROWS), "channels; valid: whole numbers 1 to 8"),
        (_packed(0, math.nan, 2, ROWS), "rate nan Hz"),
        (_packed(0, -5.0, 2, ROWS), "rate -5.0 Hz"),
        (_packed(0, 1e12, 2, ROWS), "rate 1000000000000.0 Hz"),
        (_packed(math.nan, 10_000.0, 2, ROWS), "first index nan"),
        (_packed(-1, 10_000.0, 2, ROWS), "first index -1.0"),
        (_packed(0.5, 10_000.0, 2, ROWS), "first index 0.5"),
        (_packed(1e300, 10_000.0, 2, ROWS), "first index 1e+300"),
        (_packed(0, 10_000.0, 3, ROWS), "8 samples are not whole rows of 3"),
        (_packed(0, 10_000.0, 2, np.array([[0.0, math.nan]])), "a sample is not a finite"),
        (_packed(0, 10_000.0, 2, np.array([[math.inf, 0.0]])), "a sample is not a finite"),
    ],
)
def test_a_malformed_block_is_refused_in_one_line(packed: object, message: str) -> None:
    with pytest.raises(DataError) as caught:
        _decode_block("vibration", packed, 0)
    text = str(caught.value)
    assert message in text and "Machine.Vibration.Block" in text and "\n" not in text
