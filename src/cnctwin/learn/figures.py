"""The training report's figure (matplotlib, Agg): predicted vs measured and residuals per
group for a regression; confusion matrix and ROC curve for a classification."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cnctwin.learn.training import TrainResult

__all__ = ["plot_report"]


def plot_report(result: TrainResult, path: str | Path) -> Path:
    """Draw the hold-out figure of ``result`` into the PNG ``path``; returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    report, hold = result.report, result.holdout
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.5))
    groups = hold["group"]
    names = sorted(set(groups.tolist()))
    title = f"{report['model']} -> {report['target']}, held-out {report['group_by']}"
    if result.task == "regression":
        y, pred = hold["y"], hold["prediction"]
        for g in names:
            m = groups == g
            left.scatter(y[m], pred[m], s=6, alpha=0.6, label=str(g))
        lo, hi = float(min(y.min(), pred.min())), float(max(y.max(), pred.max()))
        left.plot([lo, hi], [lo, hi], "k-", lw=1)
        metrics = report["holdout"]
        left.set_title(
            f"{title}\nMAE {metrics['mae']:.3g}, R2 {metrics['r2']:.3f}, "
            f"band coverage {metrics['band_coverage']:.2f} (stated {metrics['band_level']:.2f})",
            fontsize=9,
        )
        left.set_xlabel(f"measured {report['target']}")
        left.set_ylabel(f"predicted {report['target']}")
        if len(names) <= 12:
            left.legend(fontsize=7, title=report["group_by"], title_fontsize=7)
        right.boxplot([y[groups == g] - pred[groups == g] for g in names], showfliers=False)
        right.set_xticks(range(1, len(names) + 1), [str(g) for g in names], fontsize=7)
        right.axhline(0.0, color="k", lw=1)
        right.set_xlabel(report["group_by"])
        right.set_ylabel("residual (measured - predicted)")
        right.set_title("residuals per held-out group", fontsize=9)
    else:
        from sklearn.metrics import roc_curve

        matrix = np.array(report["holdout"]["confusion_matrix"])
        classes = report["classes"]
        left.imshow(matrix, cmap="Blues")
        for (i, j), v in np.ndenumerate(matrix):
            left.text(j, i, str(v), ha="center", va="center")
        left.set_xticks(range(len(classes)), classes)
        left.set_yticks(range(len(classes)), classes)
        left.set_xlabel("predicted")
        left.set_ylabel("true")
        metrics = report["holdout"]
        left.set_title(
            f"{title}\nbalanced accuracy {metrics['balanced_accuracy']:.3f}, "
            f"ROC AUC {metrics['roc_auc']:.3f}",
            fontsize=9,
        )
        y, proba = hold["y"].astype(int), hold["probabilities"]
        for k, label in enumerate(classes):
            if 0 < np.sum(y == k) < y.size:
                fpr, tpr, _ = roc_curve(y == k, proba[:, k])
                right.plot(fpr, tpr, label=str(label))
            if len(classes) == 2:
                break
        right.plot([0, 1], [0, 1], "k:", lw=1)
        right.set_xlabel("false positive rate")
        right.set_ylabel("true positive rate")
        right.set_title("ROC on held-out groups (windows)", fontsize=9)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
