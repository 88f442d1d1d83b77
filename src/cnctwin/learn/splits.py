"""Splits by whole groups: a hold-out of groups and grouped folds for tuning.

A group (an experiment, a run, a case) is never on both sides of a split: rows of one run
are correlated in time, and a model scored on rows of runs it has seen reports how well it
interpolates a run, not how well it predicts a new one (Kapoor & Narayanan 2023, "Leakage
and the reproducibility crisis in machine-learning-based science", leakage type L1.4:
non-independence between train and test).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

from cnctwin.errors import InputError

__all__ = ["grouped_folds", "holdout_groups"]


def holdout_groups(
    groups: NDArray[np.object_],
    fraction: float,
    seed: int,
    labels: NDArray[np.object_] | None = None,
) -> NDArray[np.bool_]:
    """Rows of the held-out groups: ``round(fraction * groups)`` whole groups (at least one,
    at most all but two), drawn with ``seed``.

    With ``labels`` (a classification target) the draw is repeated (up to 200 seeds from
    ``seed``) until both sides hold every class, where that is possible.

    Raises
    ------
    cnctwin.errors.InputError
        For fewer than 3 groups or a fraction outside (0, 1).
    """
    if not 0.0 < fraction < 1.0:
        raise InputError(f"--holdout {fraction!r}: give a fraction of the groups in (0, 1)")
    unique = np.unique(groups.astype(str))
    if unique.size < 3:
        raise InputError(
            f"{unique.size} group(s) in the data; grouped training needs at least 3 "
            f"(one held out, two to tune on)"
        )
    n_hold = int(min(max(1, round(fraction * unique.size)), unique.size - 2))
    names = groups.astype(str)
    mask = np.zeros(names.size, dtype=bool)
    for attempt in range(200):
        rng = np.random.default_rng(seed + attempt)
        held = rng.choice(unique, size=n_hold, replace=False)
        mask = np.isin(names, held)
        if labels is None:
            return mask
        classes = set(labels.astype(str))
        if set(labels[mask].astype(str)) == classes and set(labels[~mask].astype(str)) == classes:
            return mask
    return mask


def grouped_folds(
    groups: NDArray[np.object_], n_folds: int
) -> Iterator[tuple[NDArray[np.intp], NDArray[np.intp]]]:
    """Train and validation row indices of ``min(n_folds, groups)`` folds of whole groups.

    Groups are dealt to folds in order of size, largest first, each to the fold with the
    fewest rows (scikit-learn's ``GroupKFold``), so folds are near equal in rows.
    """
    names = groups.astype(str)
    unique, inverse, counts = np.unique(names, return_inverse=True, return_counts=True)
    k = int(min(n_folds, unique.size))
    if k < 2:
        raise InputError(f"{unique.size} group(s) to tune on; grouped folds need at least 2")
    fold_of_group = np.empty(unique.size, dtype=int)
    rows = np.zeros(k, dtype=int)
    for g in np.argsort(-counts, kind="stable"):
        f = int(np.argmin(rows))
        fold_of_group[g] = f
        rows[f] += counts[g]
    fold = fold_of_group[inverse]
    for f in range(k):
        yield np.flatnonzero(fold != f), np.flatnonzero(fold == f)
