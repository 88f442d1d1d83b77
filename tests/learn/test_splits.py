"""Grouped splits never put one group on both sides (property test)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from cnctwin.learn import grouped_folds, holdout_groups


@settings(max_examples=150, deadline=None)
@given(
    groups=st.lists(st.integers(0, 12), min_size=3, max_size=200).filter(
        lambda g: len(set(g)) >= 3
    ),
    fraction=st.floats(0.05, 0.95),
    folds=st.integers(2, 8),
    seed=st.integers(0, 10_000),
)
def test_no_group_on_both_sides(groups: list[int], fraction: float, folds: int, seed: int) -> None:
    names = np.array([f"g{g}" for g in groups], dtype=object)
    held = holdout_groups(names, fraction, seed)
    assert held.any() and not held.all()
    assert not set(names[held]) & set(names[~held])
    assert len(set(names[~held])) >= 2
    rest = names[~held]
    covered = np.zeros(rest.size, dtype=int)
    for train_rows, val_rows in grouped_folds(rest, folds):
        assert not set(rest[train_rows]) & set(rest[val_rows])
        assert val_rows.size and train_rows.size
        covered[val_rows] += 1
    assert np.all(covered == 1)  # every tuning row is validated exactly once


def test_holdout_keeps_every_class_on_both_sides_when_possible() -> None:
    groups = np.array([f"e{k}" for k in range(8) for _ in range(5)], dtype=object)
    labels = np.array([("worn" if k < 2 else "unworn") for k in range(8) for _ in range(5)])
    for seed in range(20):
        held = holdout_groups(groups, 0.25, seed, labels.astype(object))
        assert set(labels[held]) == set(labels[~held]) == {"worn", "unworn"}
