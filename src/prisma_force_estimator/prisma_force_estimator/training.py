"""Training loop: Adam on normalised data, seeded, one progress line per epoch.

The loss is the MSE over the normalised output axes, so by default a torque axis
(milli-newton-metres) weighs as much as a force axis; `loss_weights` changes that, and the
validation loss that picks the saved epoch uses the same weights. Validation MSE is reported per
axis in physical units. Optional variance reducers: decoupled weight decay (AdamW) and an
exponential moving average of the weights (the averaged network is validated and saved).
"""
from __future__ import annotations

import copy
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np
import torch

from .bundle import BundleMetadata
from .dataset import ForceDataset, Split, contiguous_block_split
from .networks import MODEL_SPECS, build_model, taxel_image
from .normalisation import Normaliser


@dataclass
class TrainConfig:
    model_kind: str = "cnn2"
    epochs: int = 300
    batch: int = 64
    learning_rate: float = 1e-3
    lr_schedule: str = "constant"  # "constant" or "cosine" (decay to 0 over `epochs`)
    seed: int = 0
    patience: int = 0  # early stopping: epochs without validation improvement; 0 = off
    val_fraction: float = 0.2
    threads: int = 1
    input_noise: float = 0.0  # V rms of Gaussian noise added to training inputs (augmentation); 0 = off
    weight_decay: float = 0.0  # decoupled weight decay (AdamW); 0 = plain Adam
    ema_decay: float = 0.0  # per-step decay of an exponential moving average of the weights; 0 = off
    # per-axis weight of the normalised MSE, e.g. {"tz": 0.25}; axes not named weigh 1
    loss_weights: dict[str, float] = field(default_factory=dict)
    max_steps_per_epoch: int = 0  # 0 = full epochs; tests use a handful of steps

    def validate(self) -> None:
        if self.model_kind not in MODEL_SPECS:
            raise ValueError(f"model_kind {self.model_kind!r} unknown; expected one of {list(MODEL_SPECS)}")
        for name in ("epochs", "batch", "threads"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not self.learning_rate > 0:
            raise ValueError(f"learning_rate must be > 0, got {self.learning_rate}")
        if self.lr_schedule not in ("constant", "cosine"):
            raise ValueError(f"lr_schedule must be 'constant' or 'cosine', got {self.lr_schedule!r}")
        if self.patience < 0 or self.max_steps_per_epoch < 0:
            raise ValueError("patience and max_steps_per_epoch must be >= 0")
        if not self.input_noise >= 0:
            raise ValueError(f"input_noise must be >= 0, got {self.input_noise}")
        if not self.weight_decay >= 0:
            raise ValueError(f"weight_decay must be >= 0, got {self.weight_decay}")
        if not 0 <= self.ema_decay < 1:
            raise ValueError(f"ema_decay must be in [0, 1), got {self.ema_decay}")
        axes = MODEL_SPECS[self.model_kind].axes
        unknown = [a for a in self.loss_weights if a not in axes]
        if unknown:
            raise ValueError(f"loss_weights: axes {unknown} are not outputs of {self.model_kind} {list(axes)}")
        bad = {a: w for a, w in self.loss_weights.items() if not (w >= 0 and math.isfinite(w))}
        if bad:
            raise ValueError(f"loss_weights must be finite and >= 0, got {bad}")
        if not any(self.axis_weights()):
            raise ValueError(f"loss_weights leave every axis at weight 0: {self.loss_weights}")

    def axis_weights(self) -> list[float]:
        """Loss weight of each output axis, in the model's axis order."""
        return [float(self.loss_weights.get(a, 1.0)) for a in MODEL_SPECS[self.model_kind].axes]


@dataclass
class EpochRecord:
    epoch: int
    train_loss: float  # normalised MSE, mean over the epoch's batches
    val_loss: float  # normalised MSE on the validation split
    val_mse: dict[str, float]  # physical units per axis
    seconds: float
    learning_rate: float


@dataclass
class TrainResult:
    model: torch.nn.Module  # the best epoch's weights
    metadata: BundleMetadata
    history: list[EpochRecord] = field(default_factory=list)
    best_epoch: int = 0
    stopped_early: bool = False
    seconds: float = 0.0


def predict_normalised(model: torch.nn.Module, x: torch.Tensor, chunk: int = 8192) -> torch.Tensor:
    with torch.inference_mode():
        return torch.cat([model(x[i:i + chunk]) for i in range(0, len(x), chunk)])


def format_epoch(record: EpochRecord, epochs: int, axes: list[str]) -> str:
    per_axis = " ".join(f"{a} {record.val_mse[a]:.4g}" for a in axes)
    return (f"epoch {record.epoch:>3}/{epochs}  train {record.train_loss:.4f}  val {record.val_loss:.4f}  "
            f"val MSE [{per_axis}]  lr {record.learning_rate:.2e}  {record.seconds:.1f} s")


def weighted_mse(pred: torch.Tensor, target: torch.Tensor, weights: torch.Tensor | None) -> torch.Tensor:
    """MSE over samples and axes; `weights` (one per axis, mean 1) scale each axis' share."""
    if weights is None:
        return torch.nn.functional.mse_loss(pred, target)
    return torch.mean(weights * (pred - target) ** 2)


@dataclass
class NormalisedSplit:
    """The split's tensors in normalised units, with the normalisers fitted on its training part."""
    input_normaliser: Normaliser
    output_normaliser: Normaliser
    x_train: torch.Tensor
    y_train: torch.Tensor
    x_val: torch.Tensor
    y_val: torch.Tensor
    y_val_physical: np.ndarray  # validation targets in physical units, for the per-axis MSE

    @classmethod
    def of(cls, dataset: ForceDataset, split: Split, axes: list[str]) -> NormalisedSplit:
        x_train_raw = dataset.voltages[split.train]
        y_train_raw = dataset.targets(axes)[split.train]
        in_norm = Normaliser.fit(x_train_raw)
        out_norm = Normaliser.fit(y_train_raw)
        y_val_physical = dataset.targets(axes)[split.validation].astype(np.float64)
        return cls(
            in_norm, out_norm,
            x_train=taxel_image(torch.from_numpy(in_norm.apply(x_train_raw))),
            y_train=torch.from_numpy(out_norm.apply(y_train_raw)),
            x_val=taxel_image(torch.from_numpy(in_norm.apply(dataset.voltages[split.validation]))),
            y_val=torch.from_numpy(out_norm.apply(y_val_physical)),
            y_val_physical=y_val_physical)


def normalised_axis_weights(config: TrainConfig) -> torch.Tensor | None:
    """The loss's axis weights scaled to mean 1 (so the loss stays comparable with the unweighted
    one), or None where every axis weighs 1."""
    raw_weights = config.axis_weights()
    if all(w == 1.0 for w in raw_weights):
        return None
    return torch.tensor(raw_weights, dtype=torch.float32) * len(raw_weights) / sum(raw_weights)


def epoch_learning_rate(config: TrainConfig, epoch: int) -> float:
    if config.lr_schedule == "cosine":
        return 0.5 * config.learning_rate * (1 + math.cos(math.pi * (epoch - 1) / config.epochs))
    return config.learning_rate


class Trainer:
    """One model's optimiser, optional weight average and shuffling, stepped an epoch at a time."""

    def __init__(self, config: TrainConfig, data: NormalisedSplit) -> None:
        self.config = config
        self.data = data
        self.model = build_model(config.model_kind)
        self.optimiser: torch.optim.Optimizer
        if config.weight_decay:
            self.optimiser = torch.optim.AdamW(
                self.model.parameters(), lr=config.learning_rate, weight_decay=config.weight_decay)
        else:
            self.optimiser = torch.optim.Adam(self.model.parameters(), lr=config.learning_rate)
        # The averaged copy is what gets validated and saved; the raw weights keep training.
        self.ema = (torch.optim.swa_utils.AveragedModel(
            self.model, multi_avg_fn=torch.optim.swa_utils.get_ema_multi_avg_fn(config.ema_decay))
            if config.ema_decay else None)
        self.evaluated = self.ema.module if self.ema is not None else self.model
        self.weights = normalised_axis_weights(config)
        self.shuffle = torch.Generator().manual_seed(config.seed)
        # noise in volts, per taxel in normalised units
        self.noise_scale = torch.from_numpy(
            (config.input_noise / data.input_normaliser.std).astype(np.float32)).reshape(1, 1, 3, 3)
        self.steps = math.ceil(len(data.x_train) / config.batch)
        if config.max_steps_per_epoch:
            self.steps = min(self.steps, config.max_steps_per_epoch)

    def train_epoch(self, lr: float) -> float:
        """One epoch (or `max_steps_per_epoch` batches) at `lr`; returns the mean batch loss."""
        for group in self.optimiser.param_groups:
            group["lr"] = lr
        self.model.train()
        order = torch.randperm(len(self.data.x_train), generator=self.shuffle)
        batch = self.config.batch
        total = 0.0
        for step in range(self.steps):
            index = order[step * batch:(step + 1) * batch]
            self.optimiser.zero_grad(set_to_none=True)
            x = self.data.x_train[index]
            if self.config.input_noise:
                x = x + self.noise_scale * torch.randn(x.shape, generator=self.shuffle)
            loss = weighted_mse(self.model(x), self.data.y_train[index], self.weights)
            loss.backward()
            self.optimiser.step()
            if self.ema is not None:
                self.ema.update_parameters(self.model)
            total += loss.item()
        return total / self.steps

    def validate(self, axes: list[str]) -> tuple[float, dict[str, float]]:
        """The evaluated network's weighted normalised loss and per-axis MSE in physical units."""
        self.model.eval()
        self.evaluated.eval()
        pred = predict_normalised(self.evaluated, self.data.x_val)
        val_loss = float(weighted_mse(pred, self.data.y_val, self.weights))
        physical = self.data.output_normaliser.invert(pred.numpy())
        truth = self.data.y_val_physical
        return val_loss, {a: float(np.mean((physical[:, i] - truth[:, i]) ** 2)) for i, a in enumerate(axes)}


def train(dataset: ForceDataset, config: TrainConfig, progress: Callable[[str], None] | None = print,
          split: Split | None = None, clock: Callable[[], float] = time.perf_counter) -> TrainResult:
    """Train `config.model_kind` on `dataset`; returns the best-validation model and its metadata."""
    config.validate()
    torch.set_num_threads(config.threads)
    torch.manual_seed(config.seed)
    axes = list(MODEL_SPECS[config.model_kind].axes)
    split = split or contiguous_block_split(dataset.block, config.val_fraction, seed=config.seed)
    if len(split.train) == 0 or len(split.validation) == 0:
        raise ValueError(f"split left {len(split.train)} training and {len(split.validation)} validation samples")
    data = NormalisedSplit.of(dataset, split, axes)
    trainer = Trainer(config, data)

    history: list[EpochRecord] = []
    best_loss, best_epoch, best_state = math.inf, 0, copy.deepcopy(trainer.evaluated.state_dict())
    stopped_early = False
    start = clock()
    for epoch in range(1, config.epochs + 1):
        lr = epoch_learning_rate(config, epoch)
        epoch_start = clock()
        train_loss = trainer.train_epoch(lr)
        val_loss, val_mse = trainer.validate(axes)
        record = EpochRecord(epoch, train_loss, val_loss, val_mse, clock() - epoch_start, lr)
        history.append(record)
        if progress:
            progress(format_epoch(record, config.epochs, axes))
        if val_loss < best_loss:
            best_loss, best_epoch, best_state = val_loss, epoch, copy.deepcopy(trainer.evaluated.state_dict())
        elif config.patience and epoch - best_epoch >= config.patience:
            stopped_early = True
            if progress:
                progress(f"early stop: no validation improvement for {config.patience} epochs; "
                         f"keeping epoch {best_epoch}")
            break
    seconds = clock() - start
    # With EMA this is the averaged copy (a plain network; the AveragedModel wrapper is dropped).
    model = trainer.evaluated
    model.load_state_dict(best_state)
    model.eval()
    run = {"data": dataset.source, "samples_train": int(len(split.train)),
           "samples_validation": int(len(split.validation)), "samples_guard_dropped": int(split.dropped),
           "split": "contiguous blocks (whole trajectories / recording chunks)",
           "epochs_run": len(history), "best_epoch": best_epoch, "stopped_early": stopped_early,
           "seconds": round(seconds, 1)}
    metadata = BundleMetadata(
        model_kind=config.model_kind,
        axes=axes,
        input_normaliser=data.input_normaliser,
        output_normaliser=data.output_normaliser,
        training=training_record(config, axes, run),
        validation_mse={a: history[best_epoch - 1].val_mse[a] for a in axes},
    )
    return TrainResult(model, metadata, history, best_epoch, stopped_early, seconds)


def training_record(config: TrainConfig, axes: list[str], run: dict[str, object]) -> dict[str, object]:
    """The bundle's record of how it was trained: the config, the optimiser, loss and averaging in
    words, then the run's facts (`run`: data, samples, split, epochs, timing)."""
    weighted = normalised_axis_weights(config) is not None
    return {
        **asdict(config),
        "optimiser": "AdamW" if config.weight_decay else "Adam",
        "loss": ("weighted MSE on normalised outputs, axis weights "
                 + ", ".join(f"{a} {w:g}" for a, w in zip(axes, config.axis_weights()))
                 if weighted else "MSE on normalised outputs"),
        "weight_averaging": f"EMA, decay {config.ema_decay:g} per step" if config.ema_decay else "none",
        **run,
        "torch_version": torch.__version__,
    }
