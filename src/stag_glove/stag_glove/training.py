"""Training and evaluation loops for the glove networks (CPU-friendly, with per-epoch progress).

Paper recipe (docs/glove.md): Adam 1e-3, learning rate x0.1 every 100 epochs, batch 32,
Gaussian noise 0.015 on training inputs. Epoch counts here are parameters; the CPU runs documented
in docs/glove.md use fewer epochs and a narrower trunk.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from .models import TouchNet, WeightNet

Progress = Callable[[str], None]
TupleMaker = Callable[[int], tuple[np.ndarray, np.ndarray]]  # epoch -> (tuples [A, N], labels [A])


@dataclass(frozen=True)
class TrainConfig:
    width: int = 16
    epochs: int = 20
    batch_size: int = 32
    lr: float = 1e-3
    lr_step_epochs: int = 100    # x lr_gamma every this many epochs (paper: 100)
    lr_gamma: float = 0.1
    noise_std: float = 0.015     # Gaussian noise on training inputs (paper: 0.015)
    dropout: float = 0.2
    weight_decay: float = 0.0
    seed: int = 0
    threads: int = 1

    def __post_init__(self) -> None:
        for name in ("width", "epochs", "batch_size", "lr_step_epochs", "threads"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.lr <= 0 or self.noise_std < 0:
            raise ValueError(f"lr must be > 0 and noise_std >= 0, got lr={self.lr} noise_std={self.noise_std}")


def setup_torch(config: TrainConfig) -> torch.Generator:
    torch.set_num_threads(config.threads)
    torch.manual_seed(config.seed)
    return torch.Generator().manual_seed(config.seed)


def _optimizer(params, config: TrainConfig):
    optimizer = torch.optim.Adam(params, lr=config.lr, weight_decay=config.weight_decay)
    scheduler = torch.optim.lr_scheduler.StepLR(optimizer, config.lr_step_epochs, config.lr_gamma)
    return optimizer, scheduler


def _descend(optimizer: torch.optim.Optimizer, loss: torch.Tensor, samples: int) -> float:
    """One optimiser step on `loss`; returns the loss summed over the batch's `samples`."""
    optimizer.zero_grad()
    loss.backward()
    optimizer.step()
    return loss.item() * samples


def _print(progress: Progress | None, text: str) -> None:
    if progress is not None:
        progress(text)


def _run_epochs(config: TrainConfig, scheduler: torch.optim.lr_scheduler.LRScheduler,
                train_epoch: Callable[[int], dict], evaluate: Callable[[], dict] | None,
                describe: Callable[[dict], str], progress: Progress | None, seconds_digits: int = 1) -> list[dict]:
    """The epoch loop every training here shares: train one epoch (its row: loss and the like), step
    the learning rate, add the held-out evaluation's fields, time it and report one line."""
    history = []
    for epoch in range(config.epochs):
        started = time.perf_counter()
        row = {"epoch": epoch + 1, **train_epoch(epoch)}
        scheduler.step()
        if evaluate is not None:
            row.update(evaluate())
        text = describe(row)
        row["seconds"] = time.perf_counter() - started
        _print(progress, f"{text} ({row['seconds']:.{seconds_digits}f} s)")
        history.append(row)
    return history


# -------------------------------------------------------------------------------- classification
@dataclass
class ClassifierEval:
    top1: float
    top3: float
    confusion: np.ndarray      # [classes, classes], rows = truth
    predictions: np.ndarray    # [A]
    probabilities: np.ndarray  # [A, classes]


def topk_accuracy(probabilities: np.ndarray, labels: np.ndarray, k: int) -> float:
    k = min(k, probabilities.shape[1])
    top = np.argsort(-probabilities, axis=1)[:, :k]
    return float(np.mean(np.any(top == labels[:, None], axis=1)))


def _eval_from_probs(probs: np.ndarray, labels: np.ndarray, n_classes: int) -> ClassifierEval:
    pred = probs.argmax(axis=1)
    confusion = np.zeros((n_classes, n_classes), dtype=np.int64)
    np.add.at(confusion, (labels, pred), 1)
    return ClassifierEval(float(np.mean(pred == labels)), topk_accuracy(probs, labels, 3), confusion, pred, probs)


@torch.no_grad()
def predict_proba(model: TouchNet, frames: torch.Tensor, tuples: np.ndarray, batch: int = 256) -> np.ndarray:
    model.eval()
    out = []
    for start in range(0, len(tuples), batch):
        idx = torch.from_numpy(tuples[start:start + batch])
        out.append(torch.softmax(model(frames[idx]), dim=1).numpy())
    return np.concatenate(out) if out else np.zeros((0, model.n_classes), np.float32)


def evaluate_classifier(model: TouchNet, frames: torch.Tensor, tuples: np.ndarray,
                        labels: np.ndarray) -> ClassifierEval:
    return _eval_from_probs(predict_proba(model, frames, tuples), labels, model.n_classes)


def train_classifier(model: TouchNet, frames: torch.Tensor, make_tuples: TupleMaker, config: TrainConfig,
                     progress: Progress | None = None,
                     evaluate: Callable[[TouchNet], ClassifierEval] | None = None,
                     label: str = "") -> list[dict]:
    """End-to-end training (the paper's procedure). frames: float tensor [M, 32, 32], normalised.
    Returns the per-epoch history."""
    generator = setup_torch(config)
    optimizer, scheduler = _optimizer(model.parameters(), config)
    loss_fn = nn.CrossEntropyLoss()

    def train_epoch(epoch: int) -> dict:
        tuples, labels = make_tuples(epoch)
        model.train()
        order = torch.randperm(len(tuples), generator=generator).numpy()
        total, correct, seen = 0.0, 0, 0
        for start in range(0, len(order), config.batch_size):
            batch = order[start:start + config.batch_size]
            if len(batch) < 2:  # BatchNorm needs more than one sample
                continue
            x = frames[torch.from_numpy(tuples[batch])]
            if config.noise_std:
                x = x + config.noise_std * torch.randn(x.shape, generator=generator)
            y = torch.from_numpy(labels[batch])
            logits = model(x)
            total += _descend(optimizer, loss_fn(logits, y), len(batch))
            correct += int((logits.argmax(1) == y).sum())
            seen += len(batch)
        return {"loss": total / max(seen, 1), "train_top1": correct / max(seen, 1)}

    def describe(row: dict) -> str:
        return (f"{label}epoch {row['epoch']}/{config.epochs} loss {row['loss']:.3f} "
                f"train top-1 {100 * row['train_top1']:.1f}%{_held_out_text(row)}")

    return _run_epochs(config, scheduler, train_epoch, _held_out(model, evaluate), describe, progress)


def _held_out(model: TouchNet, evaluate: Callable[[TouchNet], ClassifierEval] | None) -> Callable[[], dict] | None:
    """The history fields of a classifier's held-out evaluation, where there is one."""
    if evaluate is None:
        return None

    def fields() -> dict:
        result = evaluate(model)
        return {"test_top1": result.top1, "test_top3": result.top3}
    return fields


def _held_out_text(row: dict) -> str:
    if "test_top1" not in row:
        return ""
    return f" test top-1 {100 * row['test_top1']:.1f}% top-3 {100 * row['test_top3']:.1f}%"


@torch.no_grad()
def trunk_features(model: TouchNet, frames: torch.Tensor, batch: int = 512) -> torch.Tensor:
    """Per-frame trunk features [M, C, 8, 8] in eval mode (for training heads on a frozen trunk)."""
    model.eval()
    return torch.cat([model.trunk(frames[i:i + batch].unsqueeze(1)) for i in range(0, len(frames), batch)])


@torch.no_grad()
def head_proba(model: TouchNet, features: torch.Tensor, tuples: np.ndarray, batch: int = 1024) -> np.ndarray:
    model.eval()
    out = []
    for start in range(0, len(tuples), batch):
        f = features[torch.from_numpy(tuples[start:start + batch])]
        out.append(torch.softmax(model.head(f.flatten(1, 2)), dim=1).numpy())
    return np.concatenate(out)


def train_head(model: TouchNet, features: torch.Tensor, make_tuples: TupleMaker, config: TrainConfig,
               progress: Progress | None = None,
               evaluate: Callable[[TouchNet], ClassifierEval] | None = None,
               label: str = "") -> list[dict]:
    """Train only the fusion conv and classifier on precomputed (frozen) trunk features."""
    generator = setup_torch(config)
    params = list(model.combination.parameters()) + list(model.classifier.parameters())
    optimizer, scheduler = _optimizer(params, config)
    loss_fn = nn.CrossEntropyLoss()

    def train_epoch(epoch: int) -> dict:
        tuples, labels = make_tuples(epoch)
        model.eval()  # trunk BN/dropout frozen; the head has neither
        order = torch.randperm(len(tuples), generator=generator).numpy()
        total, seen = 0.0, 0
        for start in range(0, len(order), config.batch_size):
            batch = order[start:start + config.batch_size]
            f = features[torch.from_numpy(tuples[batch])].flatten(1, 2)
            y = torch.from_numpy(labels[batch])
            total += _descend(optimizer, loss_fn(model.head(f), y), len(batch))
            seen += len(batch)
        return {"loss": total / max(seen, 1)}

    def describe(row: dict) -> str:
        return f"{label}head epoch {row['epoch']}/{config.epochs} loss {row['loss']:.3f}{_held_out_text(row)}"

    return _run_epochs(config, scheduler, train_epoch, _held_out(model, evaluate), describe, progress,
                       seconds_digits=2)


# -------------------------------------------------------------------------------- weight
def grams_to_target(grams: np.ndarray) -> np.ndarray:
    """Regression target: natural log of grams (the paper regresses in log space)."""
    return np.log(np.asarray(grams, dtype=np.float64)).astype(np.float32)


def target_to_grams(target: np.ndarray) -> np.ndarray:
    return np.exp(np.asarray(target, dtype=np.float64))


def train_weight(model: WeightNet, frames: torch.Tensor, grams: np.ndarray, config: TrainConfig,
                 progress: Progress | None = None, label: str = "",
                 evaluate: Callable[[WeightNet], float] | None = None) -> list[dict]:
    """MSE on log(grams), single frames [M, 32, 32]."""
    generator = setup_torch(config)
    optimizer, scheduler = _optimizer(model.parameters(), config)
    target = torch.from_numpy(grams_to_target(grams))
    # start the output at the mean log weight so early epochs are not spent learning the offset
    with torch.no_grad():
        model.fc.bias.fill_(float(target.mean()))

    def train_epoch(epoch: int) -> dict:
        model.train()
        order = torch.randperm(len(frames), generator=generator)
        total, seen = 0.0, 0
        for start in range(0, len(order), config.batch_size):
            batch = order[start:start + config.batch_size]
            if len(batch) < 2:
                continue
            x = frames[batch].unsqueeze(1)
            if config.noise_std:
                x = x + config.noise_std * torch.randn(x.shape, generator=generator)
            total += _descend(optimizer, nn.functional.mse_loss(model(x), target[batch]), len(batch))
            seen += len(batch)
        return {"loss": total / max(seen, 1)}

    def describe(row: dict) -> str:
        held_out = f" held-out mean error {row['test_error_g']:.1f} g" if "test_error_g" in row else ""
        return f"{label}epoch {row['epoch']}/{config.epochs} log-MSE {row['loss']:.4f}{held_out}"

    held_out_error = (lambda: {"test_error_g": evaluate(model)}) if evaluate is not None else None
    return _run_epochs(config, scheduler, train_epoch, held_out_error, describe, progress)


@torch.no_grad()
def predict_grams(model: WeightNet, frames: torch.Tensor, batch: int = 512) -> np.ndarray:
    model.eval()
    out = [model(frames[i:i + batch].unsqueeze(1)).numpy() for i in range(0, len(frames), batch)]
    return target_to_grams(np.concatenate(out)) if out else np.zeros(0)


@dataclass(frozen=True)
class LinearBaseline:
    """grams = a * sum(frame) + b (the paper's baseline), fitted by least squares."""

    a: float
    b: float

    @classmethod
    def fit(cls, pressure_sums: np.ndarray, grams: np.ndarray) -> LinearBaseline:
        a, b = np.polyfit(np.asarray(pressure_sums, float), np.asarray(grams, float), 1)
        return cls(float(a), float(b))

    def predict(self, pressure_sums: np.ndarray) -> np.ndarray:
        return self.a * np.asarray(pressure_sums, float) + self.b
