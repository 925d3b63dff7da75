"""A first policy: behaviour cloning from a LeRobot dataset of demonstrations, ROS-free (torch, CPU).

Per frame, the observation is the fingertips' taxel voltages (`observation.tactile`, 5 x 3 x 3 V),
their estimated wrenches (`observation.wrench`, 5 x 6) and the motors' positions and velocities
(`observation.state`, 6), flattened into 81 numbers; the action is the three motor targets the hand
followed (`action`, rad). Each is normalised with the dataset's own stats (meta/stats.json: mean and
std per element; an element that never changed, std ~ 0, is only centred). A small MLP (two hidden
layers, ReLU) maps the normalised observation to the normalised action, trained with MSE and Adam on
the frames of every episode where the operator closes and holds (`grasp_span`): from the first frame
whose action left the episode's first (the operator at rest) by more than `IDLE_RAD` to the last
within `HOLD_RAD` of the farthest it went (the end of the hold). The rest before and the letting go
after are left out: nothing a reactive policy observes tells it when an operator starts or lets go.
The open, still hand at rest looks like the same hand a moment before closing, and the held ball
like the moment before letting go; trained on whole episodes the policy waited at the open hand
(it closed on 1 of 10 unseen balls; trained without the rest frames alone, on 8 of 10 with one
threshold and 1 of 10 with another). So the policy closes and holds; letting go stays the
operator's, by cancelling the goal (docs/policy.md).

The model file (`save` / `load`) holds the weights, the normalisation, the feature shapes, the
training's loss curve and what the demonstrations showed (the balls' contact-angle and stiffness
ranges, when the dataset came from prisma-sim), so that the trials can pick balls it was not shown.
It is written whole or not at all.
"""
from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from prisma_common.atomic import atomic_output
from prisma_dataset.bag_export import ACTION, STATE, TACTILE, WRENCH
from prisma_dataset.lerobot_format import EXPORT_NOTES_PATH, STATS_PATH, read_dataset, read_info

INPUTS = (TACTILE, WRENCH, STATE)
SHAPES = {TACTILE: (5, 3, 3), WRENCH: (5, 6), STATE: (6,), ACTION: (3,)}
MODEL_FORMAT = "prisma-policy behaviour cloning v1"
MIN_STD = 1e-6  # below it a feature element is taken as constant: centred, not scaled
BALL_KEYS = ("index_contact_rad", "thumb_contact_rad", "stiffness_n_per_mm")
# An action within IDLE_RAD of an episode's first action is the operator still at rest (the teleop
# core's position tolerance, above the synthetic glove's noise on the targets); within HOLD_RAD of the
# farthest the action went, the operator still holds (the glove's noise retargeted stays well below it).
IDLE_RAD = 0.02
HOLD_RAD = 0.1


class PolicyError(ValueError):
    """A dataset or model the policy cannot use; the message names it and what to do."""


@dataclass
class TrainConfig:
    hidden: int = 128
    steps: int = 3000
    batch: int = 256
    learning_rate: float = 1e-3
    seed: int = 0


@dataclass
class TrainingSet:
    """A dataset's frames as the network sees them, and what normalises them."""

    inputs: np.ndarray  # [frames, 81] float32, raw
    actions: np.ndarray  # [frames, 3] float32, raw
    input_mean: np.ndarray
    input_std: np.ndarray
    action_mean: np.ndarray
    action_std: np.ndarray
    episodes: int
    fps: int
    idle_frames: int = 0  # frames left out: the operator at rest or letting go (`grasp_span`)
    shown: dict[str, list[float]] = field(default_factory=dict)  # ball key -> [min, max] over the episodes


def _stat(stats: Mapping[str, Any], name: str, which: str, root: Path) -> np.ndarray:
    try:
        return np.asarray(stats[name][which], dtype=np.float64).reshape(-1)
    except (KeyError, TypeError, ValueError):
        raise PolicyError(f"dataset {root}: meta/stats.json has no {which} of {name}; export the dataset again "
                          f"with prisma-dataset export") from None


def flatten_observation(tactile: np.ndarray, wrench: np.ndarray, state: np.ndarray) -> np.ndarray:
    """[frames, 81] (or [81] for one frame) in INPUTS order."""
    parts = [np.asarray(v, dtype=np.float32) for v in (tactile, wrench, state)]
    if parts[2].ndim == 1:
        return np.concatenate([p.reshape(-1) for p in parts])
    return np.concatenate([p.reshape(len(p), -1) for p in parts], axis=1)


def grasp_span(actions: np.ndarray, idle_rad: float = IDLE_RAD, hold_rad: float = HOLD_RAD) -> slice:
    """One episode's frames from the first whose action left the first frame's by more than
    `idle_rad` to the last within `hold_rad` of the farthest the action went from it (inclusive);
    the whole episode when its action never moves."""
    actions = np.asarray(actions, dtype=np.float64)
    away = np.max(np.abs(actions - actions[0]), axis=1)
    moved = np.nonzero(away > idle_rad)[0]
    if not moved.size:
        return slice(0, len(actions))
    held = np.nonzero(away >= away.max() - hold_rad)[0]
    return slice(int(moved[0]), int(held[-1]) + 1)


def load_training_set(root: str | Path, whole_episodes: bool = False) -> TrainingSet:
    """The dataset at `root` as frames and normalisation; PolicyError naming a missing or misshapen
    feature, DatasetFormatError (prisma_dataset) for a directory that is not a readable dataset.
    `whole_episodes` keeps every frame (no `grasp_span`)."""
    root = Path(root)
    info = read_info(root)
    features = info.get("features", {})
    for name in (*INPUTS, ACTION):
        spec = features.get(name)
        if spec is None:
            raise PolicyError(f"dataset {root} has no feature {name}; prisma-policy learns from {', '.join(INPUTS)} "
                              f"to {ACTION} (prisma-dataset export writes them)")
        if tuple(spec.get("shape", ())) != SHAPES[name]:
            raise PolicyError(f"dataset {root}: feature {name} has shape {spec.get('shape')}, the policy needs "
                              f"{list(SHAPES[name])}")
    dataset = read_dataset(root)
    if not dataset.episodes:
        raise PolicyError(f"dataset {root} has no episodes")
    spans = [slice(0, e.length) if whole_episodes else grasp_span(e.values[ACTION]) for e in dataset.episodes]
    values = {name: np.concatenate([e.values[name][span] for e, span in zip(dataset.episodes, spans)])
              for name in (*INPUTS, ACTION)}
    idle = sum(e.length for e in dataset.episodes) - len(values[ACTION])
    try:
        stats = json.loads((root / STATS_PATH).read_text())
    except (OSError, ValueError) as exc:
        raise PolicyError(f"dataset {root}: cannot read meta/stats.json ({exc})") from None
    mean = np.concatenate([_stat(stats, n, "mean", root) for n in INPUTS])
    std = np.concatenate([_stat(stats, n, "std", root) for n in INPUTS])
    return TrainingSet(
        flatten_observation(values[TACTILE], values[WRENCH], values[STATE]),
        np.asarray(values[ACTION], dtype=np.float32),
        mean, std, _stat(stats, ACTION, "mean", root), _stat(stats, ACTION, "std", root),
        len(dataset.episodes), dataset.fps, idle, shown_balls(root))


def shown_balls(root: Path) -> dict[str, list[float]]:
    """The range of each ball parameter over the episodes prisma-sim's demonstrations recorded
    (meta/prisma_export.json); empty for a dataset without them."""
    try:
        notes = json.loads((root / EXPORT_NOTES_PATH).read_text())
    except (OSError, ValueError):
        return {}
    demos: list[dict[str, Any]] = [
        e["demonstration"] for e in notes.get("episodes", [])
        if isinstance(e, dict) and isinstance(e.get("demonstration"), dict)
        and all(k in e["demonstration"] for k in BALL_KEYS)]
    if not demos:
        return {}
    return {k: [min(float(d[k]) for d in demos), max(float(d[k]) for d in demos)] for k in BALL_KEYS}


def _scale(std: np.ndarray) -> np.ndarray:
    """The std to divide by: 1 where an element is constant or has no std (NaN: an axis the force
    estimator bundle does not estimate)."""
    std = np.asarray(std, dtype=np.float64)
    return np.where(np.isfinite(std) & (std > MIN_STD), std, 1.0)


def normalise(values: np.ndarray, mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    """(values - mean) / std per element; a NaN (not estimated) becomes 0, the mean."""
    centred = np.asarray(values, dtype=np.float64) - np.nan_to_num(np.asarray(mean, dtype=np.float64))
    return np.nan_to_num(centred / _scale(std), nan=0.0, posinf=0.0, neginf=0.0)


def _network(inputs: int, hidden: int, outputs: int):
    import torch

    return torch.nn.Sequential(torch.nn.Linear(inputs, hidden), torch.nn.ReLU(),
                               torch.nn.Linear(hidden, hidden), torch.nn.ReLU(),
                               torch.nn.Linear(hidden, outputs))


@dataclass
class Policy:
    """The trained network and its normalisation: `act` maps one frame's observation to the three
    motor targets (rad)."""

    network: Any
    input_mean: np.ndarray
    input_std: np.ndarray
    action_mean: np.ndarray
    action_std: np.ndarray
    hidden: int
    fps: int
    losses: list[float] = field(default_factory=list)
    shown: dict[str, list[float]] = field(default_factory=dict)
    episodes: int = 0

    def act_flat(self, observation: np.ndarray) -> np.ndarray:
        import torch

        x = normalise(observation, self.input_mean, self.input_std)
        with torch.no_grad():
            y = self.network(torch.as_tensor(x, dtype=torch.float32).reshape(1, -1)).numpy().reshape(-1)
        return y.astype(np.float64) * _scale(self.action_std) + np.nan_to_num(self.action_mean)

    def act(self, tactile: np.ndarray, wrench: np.ndarray, state: np.ndarray) -> np.ndarray:
        return self.act_flat(flatten_observation(tactile, wrench, state))


def train(data: TrainingSet, config: TrainConfig | None = None,
          progress: Callable[[int, float], None] | None = None) -> Policy:
    """Fit the MLP to the frames (MSE on the normalised action); `progress(step, loss)` every 100
    steps. The loss curve is the mean loss of each 100 steps."""
    import torch

    config = config or TrainConfig()
    torch.set_num_threads(1)  # a network this small trains fastest on one thread (and leaves the others be)
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    x = torch.as_tensor(normalise(data.inputs, data.input_mean, data.input_std), dtype=torch.float32)
    y = torch.as_tensor(normalise(data.actions, data.action_mean, data.action_std), dtype=torch.float32)
    network = _network(x.shape[1], config.hidden, y.shape[1])
    optimiser = torch.optim.Adam(network.parameters(), lr=config.learning_rate)
    losses: list[float] = []
    window: list[float] = []
    for step in range(1, config.steps + 1):
        rows = torch.as_tensor(rng.integers(0, len(x), min(config.batch, len(x))))
        loss = torch.nn.functional.mse_loss(network(x[rows]), y[rows])
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        window.append(float(loss.detach()))
        if step % 100 == 0 or step == config.steps:
            losses.append(float(np.mean(window)))
            window = []
            if progress:
                progress(step, losses[-1])
    network.eval()
    return Policy(network, data.input_mean, data.input_std, data.action_mean, data.action_std, config.hidden,
                  data.fps, losses, data.shown, data.episodes)


def evaluate_loss(policy: Policy, data: TrainingSet) -> float:
    """MSE of the normalised action over every frame of `data`."""
    import torch

    x = torch.as_tensor(normalise(data.inputs, policy.input_mean, policy.input_std), dtype=torch.float32)
    with torch.no_grad():
        predicted = policy.network(x).numpy()
    target = normalise(data.actions, policy.action_mean, policy.action_std)
    return float(np.mean((predicted - target) ** 2))


def save(policy: Policy, path: str | Path) -> Path:
    """The model file, whole or not at all."""
    import torch

    content = {
        "format": MODEL_FORMAT, "hidden": policy.hidden, "fps": policy.fps, "episodes": policy.episodes,
        "inputs": list(INPUTS), "output": ACTION, "shapes": {k: list(v) for k, v in SHAPES.items()},
        "state_dict": policy.network.state_dict(),
        "input_mean": policy.input_mean.tolist(), "input_std": policy.input_std.tolist(),
        "action_mean": policy.action_mean.tolist(), "action_std": policy.action_std.tolist(),
        "losses": list(policy.losses), "shown": {k: list(v) for k, v in policy.shown.items()},
    }
    with atomic_output(path) as staged:
        torch.save(content, staged)
    return Path(path)


def load(path: str | Path) -> Policy:
    """A model file `save` wrote; PolicyError naming the file for anything else."""
    import torch

    try:
        content = torch.load(Path(path), map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises pickle, zip and runtime errors alike for a file that is not a model
        first = (str(exc).strip().splitlines() or [""])[0][:120]  # torch's messages run over many lines
        raise PolicyError(f"{path} is not a prisma-policy model ({type(exc).__name__}: {first}); give the file "
                          f"prisma-policy train --out wrote") from None
    if not isinstance(content, dict) or content.get("format") != MODEL_FORMAT:
        raise PolicyError(f"{path} is not a prisma-policy model (format "
                          f"{content.get('format') if isinstance(content, dict) else None!r}); give the file "
                          f"prisma-policy train --out wrote")
    inputs = sum(math.prod(SHAPES[n]) for n in INPUTS)
    network = _network(inputs, int(content["hidden"]), math.prod(SHAPES[ACTION]))
    network.load_state_dict(content["state_dict"])
    network.eval()
    return Policy(network, np.asarray(content["input_mean"]), np.asarray(content["input_std"]),
                  np.asarray(content["action_mean"]), np.asarray(content["action_std"]), int(content["hidden"]),
                  int(content["fps"]), list(content["losses"]), dict(content["shown"]), int(content["episodes"]))
