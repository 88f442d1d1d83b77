"""Min/max per bucket against a plain loop over the buckets."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnctwin.errors import InputError
from cnctwin.report.downsample import minmax_buckets


def brute_force(t, y, t0, t1, buckets):
    """Per bucket (a Python loop): the (t, y) of its min and max, or its first NaN sample."""
    points = set()
    inside = [(ti, yi, i) for i, (ti, yi) in enumerate(zip(t, y, strict=True)) if t0 <= ti <= t1]
    width = (t1 - t0) / buckets
    for b in range(buckets):
        mine = [p for p in inside if min(int((p[0] - t0) / width), buckets - 1) == b]
        finite = [p for p in mine if not np.isnan(p[1])]
        if finite:
            points.add(min(finite, key=lambda p: (p[1], p[2]))[2])
            points.add(max(finite, key=lambda p: (p[1], -p[2]))[2])
        elif mine:
            points.add(mine[0][2])
    return sorted(points)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(0, 400),
    buckets=st.integers(1, 60),
    seed=st.integers(0, 2**32 - 1),
    window=st.tuples(st.floats(-0.2, 1.2), st.floats(0.0, 1.0)),
)
def test_points_are_each_buckets_min_and_max(n, buckets, seed, window) -> None:
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0.0, 1.0, n))
    y = rng.integers(-5, 5, n).astype(float)  # ties: min and max may be several samples
    y[rng.random(n) < 0.1] = np.nan
    t0, t1 = window[0], window[0] + window[1]
    got = minmax_buckets(t, y, t0, t1, buckets)
    inside = (t >= t0) & (t <= t1)
    assert got.samples == int(inside.sum())
    if got.raw:
        assert got.samples <= 2 * buckets
        np.testing.assert_array_equal(got.t, t[inside])
        np.testing.assert_array_equal(got.y, y[inside])
        return
    assert got.t.size <= 2 * buckets and np.all(np.diff(got.t) >= 0)
    expected = brute_force(t, y, t0, t1, buckets)
    # The values (a tie may pick another sample of the same value in the same bucket).
    width = (t1 - t0) / buckets
    per_bucket = {}
    for i in expected:
        b = min(int((t[i] - t0) / width), buckets - 1)
        per_bucket.setdefault(b, set()).add(None if np.isnan(y[i]) else y[i])
    got_bucket = {}
    for ti, yi in zip(got.t, got.y, strict=True):
        b = min(int((ti - t0) / width), buckets - 1)
        got_bucket.setdefault(b, set()).add(None if np.isnan(yi) else yi)
    assert got_bucket == per_bucket


def test_a_single_spike_survives_any_zoom() -> None:
    t = np.arange(1_000_000) * 1e-3
    y = np.sin(t)
    y[654_321] = 50.0
    for buckets in (10, 300, 2000):
        got = minmax_buckets(t, y, 0.0, t[-1], buckets)
        assert got.y.max() == 50.0 and got.t[np.argmax(got.y)] == t[654_321]
        assert got.y.min() == pytest.approx(-1.0, abs=1e-6)


def test_bad_arguments() -> None:
    with pytest.raises(InputError, match="buckets=0"):
        minmax_buckets([0.0], [1.0], 0.0, 1.0, 0)
    with pytest.raises(InputError, match="give finite t0 <= t1"):
        minmax_buckets([0.0], [1.0], 1.0, 0.0, 5)
    with pytest.raises(InputError, match="one length"):
        minmax_buckets([0.0, 1.0], [1.0], 0.0, 1.0, 5)


def test_many_samples_at_one_instant() -> None:
    got = minmax_buckets(np.zeros(10), np.arange(10.0), 0.0, 0.0, 2)
    assert not got.raw and got.y.tolist() == [0.0, 9.0]
