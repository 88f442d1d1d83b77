"""The training report's figure (matplotlib, Agg): predicted vs measured and residuals per
group for a regression; confusion matrix and ROC curve for a classification; the lead-time
study's score traces."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cnctwin.learn.lead_time import LeadTimeResult
from cnctwin.learn.training import TrainResult

__all__ = ["plot_lead_time", "plot_report"]


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


def plot_lead_time(result: LeadTimeResult, path: str | Path) -> Path:
    """Draw each run's online score against the time left to its end of machining (s):
    alarm runs on the left, the others on the right, the flags marked; returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    report = result.report
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5), sharey=True)
    for run in report["runs"]:
        ax = axes[0] if run["alarm"] else axes[1]
        left, score = result.traces[run["run"]]
        (line,) = ax.plot(left, score, lw=1, label=f"run {run['run']}")
        if run["flagged"]:
            ax.plot(run["before_end_s"], run["threshold"], "o", color=line.get_color())
    summary, rule = report["summary"], report["rule"]
    axes[0].set_title(
        f"{rule['alarm']} (left out in turn): {summary['alarm_runs_flagged']} of "
        f"{summary['alarm_runs']} flagged, lead times "
        + ", ".join(f"{t:.1f}" for t in summary["lead_times_s"])
        + " s",
        fontsize=9,
    )
    axes[1].set_title(
        f"the other runs: {summary['false_alarms']} of {summary['other_runs']} flagged "
        f"(false alarms)",
        fontsize=9,
    )
    for ax in axes:
        ax.invert_xaxis()
        ax.set_xlabel("time before the end of machining (s)")
        ax.legend(fontsize=6, ncol=2)
    axes[0].set_ylabel(f"score: mean probability over {rule['smooth_s']:g} s (dot: flag)")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
