"""STAG glove benchmarks (python bench/run.py --only glove_process --only glove_classify_n8).

glove_process: glove frames per second through the frame processing core (normalisation 500..650,
shorted-frame check, contact flag against an empty-hand calibration over the 548-sensor mask) on
one thread. Needed: 7.3 frames/s, the glove's readout rate.
glove_classify_n8: object decisions per second of the perception core with the N=8 classifier:
cluster selection (PCA to 8 dims + k-means, k=8) over a full 64-frame buffer plus the forward
pass, on one thread. Uses the shipped bundle config/models/glove_object when it is N=8, else an
untrained network of the same shape. Needed: 7.3 decisions/s (one per frame).
"""
from __future__ import annotations

import time

import numpy as np
import torch

from run import Benchmark
from stag_glove.bundle import Bundle, BundleError, load_bundle
from stag_glove.glove_perception_core import GlovePerception, PerceptionConfig, limit_threads
from stag_glove.layout import load_layout
from stag_glove.models import TouchNet
from stag_glove.processing import FrameProcessor
from stag_glove.synthetic import SyntheticConfig, SyntheticGlove

GLOVE_RATE_HZ = 7.3


def _frames(n: int, seed: int = 0) -> np.ndarray:
    glove = SyntheticGlove(SyntheticConfig(seed=seed))
    stream = glove.stream()
    return np.stack([next(stream)[0] for _ in range(n)])


def _process_rate() -> float:
    limit_threads(1)
    raw = _frames(600)
    processor = FrameProcessor(mask=load_layout().mask)
    processor.calibrate(raw[:60])
    frames = raw[60:]
    reps = 20
    latencies = []
    start = time.perf_counter()
    for _ in range(reps):
        for i, frame in enumerate(frames):
            t0 = time.perf_counter()
            processor.process(frame, i)
            latencies.append(time.perf_counter() - t0)
    elapsed = time.perf_counter() - start
    PROCESS.notes["us_per_frame"] = round(elapsed / (reps * len(frames)) * 1e6, 1)
    PROCESS.notes["p99_us"] = round(float(np.percentile(latencies, 99)) * 1e6, 1)
    return reps * len(frames) / elapsed


def _object_bundle() -> Bundle:
    try:
        bundle = load_bundle("config/models/glove_object", "object")
        if bundle.n_frames == 8:
            CLASSIFY.notes["model"] = f"{bundle.path.name} (width {bundle.metadata['width']}, N=8)"
            return bundle
    except BundleError:
        pass
    torch.manual_seed(0)
    model = TouchNet(27, 8, width=16).eval()
    CLASSIFY.notes["model"] = "untrained TouchNet width 16, N=8 (shipped bundle missing)"
    return Bundle(None, "object", model, {"labels": [f"c{i}" for i in range(27)], "n_frames": 8, "width": 16})


def _classify_rate() -> float:
    limit_threads(1)
    perception = GlovePerception(_object_bundle(), config=PerceptionConfig(selection="cluster", buffer_size=64))
    for pressure in _frames(200, seed=1)[-64:]:
        perception.buffer.append(np.clip((pressure.astype(np.float32) - 500) / 150, 0, 1))
    for _ in range(5):
        perception.classify_object()
    n = 150
    latencies = []
    start = time.perf_counter()
    for _ in range(n):
        t0 = time.perf_counter()
        perception.classify_object()
        latencies.append(time.perf_counter() - t0)
    elapsed = time.perf_counter() - start
    CLASSIFY.notes["ms_per_decision"] = round(elapsed / n * 1e3, 2)
    CLASSIFY.notes["p99_ms"] = round(float(np.percentile(latencies, 99)) * 1e3, 2)
    return n / elapsed


PROCESS = Benchmark("glove_process", _process_rate, "frames/s", GLOVE_RATE_HZ)
CLASSIFY = Benchmark("glove_classify_n8", _classify_rate, "decisions/s", GLOVE_RATE_HZ)
BENCHMARKS = [PROCESS, CLASSIFY]
