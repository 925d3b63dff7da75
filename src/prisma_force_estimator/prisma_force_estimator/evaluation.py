"""The paper's held-out tests: push (Fz) and slide (Fx, Fy), per-axis MSE, low-force error, plots.

Held-out trajectories come from the tactile driver's `generate_trajectory` with seeds the
default training set does not use, so every number here is on data no model has seen.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from prisma_common.atomic import atomic_output
from prisma_hand_sim.calibration import generate_trajectory

from .dataset import ForceDataset
from .inference import ForceEstimator
from .wrench import WRENCH_AXES

# Seeds far from the training set's (generate_calibration_set(seed=0)).
PUSH_SEED = 10_001
SLIDE_SEED = 10_002
LOW_FORCE_N = 1.2
CONTACT_N = 0.05  # below this the pad is considered untouched; excluded from the low-force error

# The paper's numbers on its own data (docs/force_estimation.md); None = not reported.
PAPER = {
    "ann": {"val": {"fx": 0.053, "fy": 0.049, "fz": 0.319}, "push_fz": None, "slide_fx": None, "slide_fy": None},
    "cnn": {"val": {"fx": 0.022, "fy": 0.022, "fz": 0.148}, "push_fz": 0.35, "slide_fx": 0.023, "slide_fy": 0.012},
    "cnn_t": {"val": None, "push_fz": None, "slide_fx": None, "slide_fy": None},
    "cnn2": {"val": None, "push_fz": 0.19, "slide_fx": 0.015, "slide_fy": 0.008},
}
TARGETS = {"push_fz": 0.19, "slide_fx": 0.015, "slide_fy": 0.008, "low_force_mae": 0.15}


@dataclass
class HeldOutTests:
    push: ForceDataset
    slide: ForceDataset
    rate_hz: float = 100.0


def held_out_tests(push_samples: int = 30_000, slide_samples: int = 30_000,
                   push_seed: int = PUSH_SEED, slide_seed: int = SLIDE_SEED) -> HeldOutTests:
    push = ForceDataset.from_calibration_set(generate_trajectory("push", push_samples, push_seed),
                                             f"push(n={push_samples}, seed={push_seed})")
    slide = ForceDataset.from_calibration_set(generate_trajectory("slide", slide_samples, slide_seed),
                                              f"slide(n={slide_samples}, seed={slide_seed})")
    return HeldOutTests(push, slide)


def _force_mse(pred: np.ndarray, ref: np.ndarray, axis: str) -> float:
    i = WRENCH_AXES.index(axis)
    return float(np.nanmean((pred[:, i] - ref[:, i]) ** 2))


@dataclass
class EvalResult:
    name: str
    model_kind: str
    push_fz_mse: float
    slide_fx_mse: float
    slide_fy_mse: float
    low_force_mae: dict[str, float]  # per force axis, samples in contact with |F| < 1.2 N
    low_force_samples: int
    validation_mse: dict[str, float] = field(default_factory=dict)
    training_seconds: float | None = None
    epochs_run: int | None = None
    push_pred: np.ndarray | None = None  # [N, 6] with NaN for axes the model lacks
    slide_pred: np.ndarray | None = None

    @property
    def low_force_mae_max(self) -> float:
        return max(self.low_force_mae.values())

    def meets_targets(self) -> dict[str, bool]:
        return {"push_fz": self.push_fz_mse <= TARGETS["push_fz"],
                "slide_fx": self.slide_fx_mse <= TARGETS["slide_fx"],
                "slide_fy": self.slide_fy_mse <= TARGETS["slide_fy"],
                "low_force_mae": self.low_force_mae_max <= TARGETS["low_force_mae"]}


def predict_full(estimator: ForceEstimator, voltages: np.ndarray) -> np.ndarray:
    out = np.full((len(voltages), len(WRENCH_AXES)), np.nan)
    pred = estimator.estimate(voltages)
    for j, axis in enumerate(estimator.axes):
        out[:, WRENCH_AXES.index(axis)] = pred[:, j]
    return out


def low_force_mae(preds: Sequence[np.ndarray], refs: Sequence[np.ndarray],
                  limit_n: float = LOW_FORCE_N) -> tuple[dict[str, float], int]:
    """Per-axis mean absolute force error over samples in contact with |F| below `limit_n`."""
    pred = np.concatenate(preds)
    ref = np.concatenate(refs)
    magnitude = np.linalg.norm(ref[:, :3], axis=1)
    mask = (magnitude > CONTACT_N) & (magnitude < limit_n)
    if not mask.any():
        return {a: float("nan") for a in WRENCH_AXES[:3]}, 0
    return ({a: float(np.mean(np.abs(pred[mask, i] - ref[mask, i]))) for i, a in enumerate(WRENCH_AXES[:3])},
            int(mask.sum()))


def evaluate(estimator: ForceEstimator, tests: HeldOutTests, name: str = "") -> EvalResult:
    push_pred = predict_full(estimator, tests.push.voltages)
    slide_pred = predict_full(estimator, tests.slide.voltages)
    mae, n_low = low_force_mae([push_pred, slide_pred], [tests.push.wrench, tests.slide.wrench])
    training = estimator.metadata.training
    return EvalResult(
        name=name or estimator.model_kind,
        model_kind=estimator.model_kind,
        push_fz_mse=_force_mse(push_pred, tests.push.wrench, "fz"),
        slide_fx_mse=_force_mse(slide_pred, tests.slide.wrench, "fx"),
        slide_fy_mse=_force_mse(slide_pred, tests.slide.wrench, "fy"),
        low_force_mae=mae,
        low_force_samples=n_low,
        validation_mse=dict(estimator.metadata.validation_mse),
        training_seconds=training.get("seconds"),
        epochs_run=training.get("epochs_run"),
        push_pred=push_pred,
        slide_pred=slide_pred,
    )


def _fmt(value: float | None, digits: int = 4) -> str:
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return "-"
    return f"{value:.{digits}f}"


def results_table(results: Sequence[EvalResult]) -> str:
    """Markdown table: validation MSE per axis, held-out push/slide MSE, low-force MAE."""
    header = ("| model | epochs | train time [s] | val MSE fx | fy | fz | tx | ty | tz | push Fz MSE | "
              "slide Fx MSE | slide Fy MSE | MAE <1.2 N (max axis) |")
    lines = [header, "|" + "---|" * (header.count("|") - 1)]
    for r in results:
        val = [_fmt(r.validation_mse.get(a), 4 if a.startswith("f") else 8) for a in WRENCH_AXES]
        lines.append(f"| {r.name} | {r.epochs_run or '-'} | {_fmt(r.training_seconds, 0)} | " + " | ".join(val)
                     + f" | {_fmt(r.push_fz_mse)} | {_fmt(r.slide_fx_mse)} | {_fmt(r.slide_fy_mse)} | "
                     f"{_fmt(r.low_force_mae_max, 3)} |")
    return "\n".join(lines)


def _save(fig, path: Path) -> None:
    """savefig whole or not at all (staged, renamed when complete)."""
    with atomic_output(path) as staged:
        fig.savefig(staged, dpi=90)


def plot_tests(results: Sequence[EvalResult], tests: HeldOutTests, out_dir: str | Path,
               prefix: str = "force_", seconds: float = 30.0) -> list[Path]:
    """Prediction vs reference over time, one column per model (cf. the paper's Figs. 7, 8, 13, 14).

    The time plots show the first `seconds` of each test (the MSE in the titles is over the
    whole test); the error plot uses every sample.

    Writes <prefix>push_fz.png (push test, Fz), <prefix>slide_fxfy.png (slide test, Fx and Fy)
    and <prefix>error_vs_force.png (absolute Fz error against reference normal force).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    n = len(results)
    n_push = min(len(tests.push), int(seconds * tests.rate_hz))
    n_slide = min(len(tests.slide), int(seconds * tests.rate_hz))
    t_push = np.arange(n_push) / tests.rate_hz
    t_slide = np.arange(n_slide) / tests.rate_hz

    fig, axs = plt.subplots(1, n, figsize=(3.6 * n, 3.0), sharey=True, squeeze=False)
    for ax, r in zip(axs[0], results):
        assert r.push_pred is not None  # results of evaluate(), which keeps the predictions
        ax.plot(t_push, tests.push.wrench[:n_push, 2], color="k", lw=1.2, label="reference")
        ax.plot(t_push, r.push_pred[:n_push, 2], color="tab:red", lw=0.8, label="estimate")
        ax.set_title(f"{r.name}: push Fz (MSE {r.push_fz_mse:.3f} N²)", fontsize=9)
        ax.set_xlabel("time [s]")
    axs[0][0].set_ylabel("Fz [N]")
    axs[0][0].legend(fontsize=8)
    fig.tight_layout()
    paths.append(out_dir / f"{prefix}push_fz.png")
    _save(fig, paths[-1])
    plt.close(fig)

    fig, axs = plt.subplots(2, n, figsize=(3.6 * n, 5.0), sharex=True, squeeze=False)
    for col, r in enumerate(results):
        assert r.slide_pred is not None  # results of evaluate(), which keeps the predictions
        for row, (axis, mse) in enumerate((("fx", r.slide_fx_mse), ("fy", r.slide_fy_mse))):
            i = WRENCH_AXES.index(axis)
            ax = axs[row][col]
            ax.plot(t_slide, tests.slide.wrench[:n_slide, i], color="k", lw=1.2, label="reference")
            ax.plot(t_slide, r.slide_pred[:n_slide, i], color="tab:blue", lw=0.8, label="estimate")
            ax.set_title(f"{r.name}: slide {axis.upper()} (MSE {mse:.4f} N²)", fontsize=9)
            if col == 0:
                ax.set_ylabel(f"{axis.upper()} [N]")
        axs[1][col].set_xlabel("time [s]")
    axs[0][0].legend(fontsize=8)
    fig.tight_layout()
    paths.append(out_dir / f"{prefix}slide_fxfy.png")
    _save(fig, paths[-1])
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(5.5, 3.5))
    ref = np.concatenate([tests.push.wrench, tests.slide.wrench])
    magnitude = np.linalg.norm(ref[:, :3], axis=1)
    bins = np.linspace(0, max(float(magnitude.max()), LOW_FORCE_N), 16)
    centres = 0.5 * (bins[1:] + bins[:-1])
    for r in results:
        pred = np.concatenate([r.push_pred, r.slide_pred])
        err = np.abs(pred[:, :3] - ref[:, :3]).mean(axis=1)
        which = np.digitize(magnitude, bins) - 1
        mean_err = [err[which == b].mean() if np.any(which == b) else np.nan for b in range(len(centres))]
        ax.plot(centres, mean_err, marker="o", ms=3, label=r.name)
    ax.axhline(0.15, color="grey", ls="--", lw=0.8)
    ax.axvline(LOW_FORCE_N, color="grey", ls=":", lw=0.8)
    ax.set_xlabel("reference |F| [N]")
    ax.set_ylabel("mean |error| over Fx, Fy, Fz [N]")
    ax.set_title("held-out push + slide: error against force", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    paths.append(out_dir / f"{prefix}error_vs_force.png")
    _save(fig, paths[-1])
    plt.close(fig)
    return paths
