"""PNG figures for the glove experiments (small files, for docs/glove.md)."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from prisma_common.atomic import atomic_output  # noqa: E402

PAPER_CURVE = {1: 38.0, 7: 75.0}  # STAG paper, Fig. 2b anchors (top-1 %, their 26 objects + empty)


def _save(fig, path: str | Path) -> Path:
    """savefig whole or not at all (staged under a temporary name, renamed when complete)."""
    path = Path(path)
    try:
        with atomic_output(path) as staged:
            fig.savefig(staged, dpi=90)
    finally:
        plt.close(fig)
    return path


def confusion_png(panels: list[tuple[str, np.ndarray]], labels: list[str], path: str | Path) -> Path:
    """One or more row-normalised confusion matrices side by side."""
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 5.0), squeeze=False)
    short = [label.replace("object_", "o") for label in labels]
    for ax, (title, matrix) in zip(axes[0], panels):
        rows = matrix.sum(axis=1, keepdims=True)
        norm = np.divide(matrix, rows, out=np.zeros(matrix.shape, float), where=rows > 0)
        ax.imshow(norm, vmin=0, vmax=1, cmap="viridis")
        ax.set_title(title, fontsize=9)
        ax.set_xticks(range(len(labels)), short, rotation=90, fontsize=5)
        ax.set_yticks(range(len(labels)), short, fontsize=5)
        ax.set_xlabel("predicted", fontsize=8)
        ax.set_ylabel("true", fontsize=8)
    fig.tight_layout()
    return _save(fig, path)


def accuracy_curve_png(summary: list[dict], path: str | Path, title: str) -> Path:
    fig, ax = plt.subplots(figsize=(5.6, 3.8))
    for selection, colour in (("random", "tab:blue"), ("cluster", "tab:orange")):
        rows = sorted((r for r in summary if r["selection"] == selection), key=lambda r: r["n"])
        if not rows:
            continue
        n = np.array([r["n"] for r in rows])
        top1 = 100 * np.array([r["top1"] for r in rows])
        std = 100 * np.array([r["top1_std"] for r in rows])
        ax.errorbar(n, top1, yerr=std, marker="o", capsize=3, color=colour, label=f"top-1, {selection}")
        ax.plot(n, 100 * np.array([r["top3"] for r in rows]), ls=":", color=colour, label=f"top-3, {selection}")
        if all("warm_top1" in r for r in rows):
            ax.plot(n, 100 * np.array([r["warm_top1"] for r in rows]), ls="--", lw=1, color=colour, alpha=0.6,
                    label=f"top-1, {selection}, warm start only")
    ax.plot(list(PAPER_CURVE), list(PAPER_CURVE.values()), "k*", ms=10, label="paper (real data), top-1")
    ax.set_xlabel("input frames N")
    ax.set_ylabel("held-out accuracy (%)")
    ax.set_ylim(0, 100)
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=6, loc="lower right")
    fig.tight_layout()
    return _save(fig, path)


def weight_png(rows: list[dict], path: str | Path) -> Path:
    """Per held-out object: true weight vs median prediction of the CNN and the linear baseline."""
    fig, ax = plt.subplots(figsize=(4.6, 4.0))
    true = np.array([r["grams"] for r in rows])
    ax.loglog(true, [r["cnn_median_pred_g"] for r in rows], "o", label="CNN (median per object)")
    ax.loglog(true, np.clip([r["linear_median_pred_g"] for r in rows], 1, None), "s", mfc="none",
              label="linear a*sum+b (median)")
    lim = [true.min() / 1.5, true.max() * 1.5]
    ax.plot(lim, lim, "k-", lw=0.8)
    ax.set_xlabel("true weight (g)")
    ax.set_ylabel("predicted (g), object held out")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    return _save(fig, path)


def correlation_png(maps: list[tuple[str, np.ndarray, tuple[int, int]]], cca: tuple[list[str], np.ndarray],
                    path: str | Path, title: str) -> Path:
    fig, axes = plt.subplots(1, len(maps) + 1, figsize=(2.6 * len(maps) + 4.2, 3.6), layout="constrained",
                             gridspec_kw={"width_ratios": [1] * len(maps) + [1.6]})
    for ax, (name, corr, ref) in zip(axes, maps):
        image = ax.imshow(corr, vmin=-1, vmax=1, cmap="RdBu_r")
        ax.plot(ref[1], ref[0], "k+", ms=8)
        ax.set_title(f"Pearson r with\n{name} {ref}", fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.colorbar(image, ax=axes[len(maps) - 1], fraction=0.05, pad=0.02)
    names, matrix = cca
    ax = axes[-1]
    shown = ax.imshow(matrix, vmin=0, vmax=1, cmap="magma")
    fig.colorbar(shown, ax=ax, fraction=0.05, pad=0.02)
    ax.set_xticks(range(len(names)), [n.replace("_", " ") for n in names], rotation=90, fontsize=5)
    ax.set_yticks(range(len(names)), [n.replace("_", " ") for n in names], fontsize=5)
    ax.set_title("CCA between regions\n(first canonical r)", fontsize=8)
    fig.suptitle(title, fontsize=9)
    return _save(fig, path)
