"""Figures of the learned components: detector ROC and confusion matrices, fusion RMSE.

Functions take report objects and return the figure; nothing is imported by
``import ftnav``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["detector_figure", "fusion_figure"]


def detector_figure(report, title: str = ""):
    """ROC curves (RBF output and chi-square statistic) and confusion matrices per sensor.

    Parameters
    ----------
    report : :class:`ftnav.fdi.training.DetectorReport` (held-out epochs).
    """
    from matplotlib.figure import Figure
    from sklearn.metrics import roc_auc_score, roc_curve

    sensors = list(report.roc)
    fig = Figure(figsize=(4.2 * len(sensors), 7.5))
    axes = fig.subplots(2, len(sensors), squeeze=False)
    for j, s in enumerate(sensors):
        y, rbf, chi2 = report.roc[s]
        ax = axes[0, j]
        for name, score, style in (("RBF output", rbf, "-"), ("chi-square NIS", chi2, "--")):
            if y.any() and not y.all():
                fpr, tpr, _ = roc_curve(y, score)
                auc = roc_auc_score(y, score)
                ax.plot(fpr, tpr, style, label=f"{name} (AUC {auc:.3f})")
        ax.set_xscale("log")
        ax.set_xlim(1e-5, 1)
        ax.set_ylim(0, 1.01)
        ax.set_xlabel("false-alarm rate per epoch")
        ax.set_ylabel("detection rate per epoch")
        ax.set_title(f"{s}: held-out ROC")
        ax.legend(loc="lower right", fontsize=8)
        ax.grid(True, alpha=0.3)
        cm = report.confusion[s]
        ax = axes[1, j]
        frac = cm / np.maximum(cm.sum(1, keepdims=True), 1)
        ax.imshow(frac, cmap="Blues", vmin=0, vmax=1)
        for (a, b), v in np.ndenumerate(cm):
            ax.text(
                b,
                a,
                f"{v}\n({frac[a, b]:.1%})",
                ha="center",
                va="center",
                color="white" if frac[a, b] > 0.6 else "black",
                fontsize=9,
            )
        ax.set_xticks([0, 1], ["no alarm", "alarm"])
        ax.set_yticks([0, 1], ["healthy", "faulty"])
        ax.set_title(f"{s}: RBF flags (after hysteresis)")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def fusion_figure(model, report, title: str = ""):
    """Held-out RMSE per configuration (bars per source) and the learned weights."""
    from matplotlib.figure import Figure

    states = report.states
    configs = report.configurations
    sources = list(report.rmse)
    fig = Figure(figsize=(4.5 * len(states), 7.5))
    axes = fig.subplots(2, len(states), squeeze=False)
    x = np.arange(len(configs))
    width = 0.8 / len(sources)
    for j, st in enumerate(states):
        ax = axes[0, j]
        for k, src in enumerate(sources):
            vals = [report.rmse[src][c][st] for c in configs]
            ax.bar(x + (k - (len(sources) - 1) / 2) * width, vals, width, label=src)
        ax.set_yscale("log")
        ax.set_xticks(x, configs)
        ax.set_ylabel(f"RMSE of {st}")
        ax.set_title(f"{st}: held-out RMSE per configuration")
        ax.grid(True, axis="y", alpha=0.3)
        if j == 0:
            ax.legend(fontsize=7)
        ax = axes[1, j]
        W = model.weights[:, j]
        ax.imshow(W, cmap="viridis", vmin=0, vmax=1, aspect="auto")
        for (a, b), v in np.ndenumerate(W):
            ax.text(
                b,
                a,
                f"{v:.2f}",
                ha="center",
                va="center",
                color="black" if v > 0.6 else "white",
                fontsize=9,
            )
        ax.set_xticks(range(len(model.inputs)), model.inputs)
        ax.set_yticks(range(len(configs)), configs)
        ax.set_xlabel("input")
        ax.set_title(f"{st}: neuron weights")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig
