"""Glove perception core: buffers valid contact frames and runs the object (N frames), hand-pose
and weight networks. ROS-free; the glove_perception node feeds it frames and publishes its output.

Rules: a shorted frame never reaches any network and is never buffered. The object buffer holds
the most recent contact frames; after `release_frames` consecutive frames without contact the
object is taken as released and the buffer is cleared, so the next object starts fresh. The hand
pose is estimated on every non-shorted frame (an empty hand is a pose); the weight on contact frames.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace

import numpy as np
import torch

from .bundle import Bundle
from .processing import ProcessedFrame
from .ros_conversions import Estimate, WeightResult
from .selection import check_selection, select_from_buffer

_thread_limit = None


def limit_threads(threads: int) -> None:
    """Use `threads` threads for torch and for BLAS. OpenBLAS otherwise starts one thread per core,
    which on a shared 2-core machine makes a 64x1024 PCA ~10x slower than single-threaded."""
    global _thread_limit
    from threadpoolctl import threadpool_limits

    torch.set_num_threads(threads)
    _thread_limit = threadpool_limits(limits=threads)  # kept referenced: applies to the whole process


@dataclass(frozen=True)
class PerceptionConfig:
    selection: str = "cluster"
    buffer_size: int = 64
    release_frames: int = 15
    kmeans_restarts: int = 3
    seed: int = 0

    def __post_init__(self) -> None:
        check_selection(self.selection)
        if self.buffer_size < 1:
            raise ValueError(f"buffer_size must be >= 1, got {self.buffer_size}")
        if self.release_frames < 1:
            raise ValueError(f"release_frames must be >= 1, got {self.release_frames}")


@dataclass
class PerceptionOutput:
    object: Estimate | None = None
    pose: Estimate | None = None
    weight: WeightResult | None = None


@dataclass
class PerceptionStats:
    frames: int = 0
    shorted_rejected: int = 0
    contact_frames: int = 0
    releases: int = 0
    object_decisions: int = 0


def _estimate(probabilities: np.ndarray, labels: list[str], frames_used: int) -> Estimate:
    best = int(np.argmax(probabilities))
    return Estimate(labels[best], float(probabilities[best]), list(labels), probabilities.astype(np.float32),
                    frames_used)


class GlovePerception:
    def __init__(self, object_bundle: Bundle | None = None, pose_bundle: Bundle | None = None,
                 weight_bundle: Bundle | None = None, config: PerceptionConfig = PerceptionConfig()) -> None:
        for bundle, kind in ((object_bundle, "object"), (pose_bundle, "pose"), (weight_bundle, "weight")):
            if bundle is not None and bundle.kind != kind:
                raise ValueError(f"{bundle.path} holds a {bundle.kind!r} model, given as the {kind} model")
        self.object_bundle, self.pose_bundle, self.weight_bundle = object_bundle, pose_bundle, weight_bundle
        self.config = config
        self.n_frames = object_bundle.n_frames if object_bundle is not None else 0
        if object_bundle is not None and config.buffer_size < self.n_frames:
            raise ValueError(f"buffer_size {config.buffer_size} is smaller than the object model's "
                             f"{self.n_frames} input frames")
        self.buffer: deque[np.ndarray] = deque(maxlen=config.buffer_size)
        self.stats = PerceptionStats()
        self._no_contact_run = 0
        self._rng = np.random.default_rng(config.seed)
        baseline = (weight_bundle.metadata.get("linear_baseline") if weight_bundle is not None else None) or {}
        self._baseline = (float(baseline.get("a", 0.0)), float(baseline.get("b", 0.0)))

    def reconfigure(self, release_frames: int) -> None:
        """Live parameter changed: frames without contact that release the object, from the next frame."""
        self.config = replace(self.config, release_frames=release_frames)

    def reset(self) -> None:
        self.buffer.clear()
        self._no_contact_run = 0

    def update(self, frame: ProcessedFrame) -> PerceptionOutput:
        self.stats.frames += 1
        if frame.shorted:
            self.stats.shorted_rejected += 1
            return PerceptionOutput()
        out = PerceptionOutput()
        if self.pose_bundle is not None:
            out.pose = self.classify_pose(frame.pressure)
        if not frame.contact:
            self._no_contact_run += 1
            if self._no_contact_run >= self.config.release_frames and self.buffer:
                self.buffer.clear()
                self.stats.releases += 1
            return out
        self._no_contact_run = 0
        self.stats.contact_frames += 1
        self.buffer.append(np.asarray(frame.pressure, dtype=np.float32))
        if self.object_bundle is not None and len(self.buffer) >= self.n_frames:
            out.object = self.classify_object()
        if self.weight_bundle is not None:
            out.weight = self.estimate_weight(frame.pressure)
        return out

    @staticmethod
    def _loaded(bundle: Bundle | None, kind: str) -> Bundle:
        if bundle is None:
            raise RuntimeError(f"no {kind} model was given to GlovePerception")
        return bundle

    @torch.no_grad()
    def classify_object(self) -> Estimate:
        bundle = self._loaded(self.object_bundle, "object")
        frames = np.stack(self.buffer)
        index = select_from_buffer(frames, self.n_frames, self.config.selection, self._rng,
                                   n_init=self.config.kmeans_restarts)
        logits = bundle.model(torch.from_numpy(frames[index][None]))
        self.stats.object_decisions += 1
        return _estimate(torch.softmax(logits[0], 0).numpy(), bundle.labels, self.n_frames)

    @torch.no_grad()
    def classify_pose(self, pressure: np.ndarray) -> Estimate:
        bundle = self._loaded(self.pose_bundle, "pose")
        x = torch.from_numpy(np.asarray(pressure, dtype=np.float32)[None, None])
        return _estimate(torch.softmax(bundle.model(x)[0], 0).numpy(), bundle.labels, 1)

    @torch.no_grad()
    def estimate_weight(self, pressure: np.ndarray) -> WeightResult:
        bundle = self._loaded(self.weight_bundle, "weight")
        x = torch.from_numpy(np.asarray(pressure, dtype=np.float32)[None, None])
        grams = float(np.exp(float(bundle.model(x)[0])))
        a, b = self._baseline
        return WeightResult(grams, a * float(np.sum(pressure)) + b)
