"""Force estimator inference: five-finger calls per second on one core (need 100: the 100 Hz scan).

One call = ForceEstimator.estimate on a [5, 9] batch (all fingers of one scan). force_infer_cnn2
uses the shipped default bundle (config/models/cnn2) when present; the other models, whose
speed does not depend on their weights, use freshly initialised bundles.
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from prisma_force_estimator.bundle import DEFAULT_BUNDLE, resolve_bundle_path, save_untrained_bundle
from prisma_force_estimator.inference import ForceEstimator
from prisma_force_estimator.networks import MODEL_KINDS
from run import Benchmark

SCAN_RATE_HZ = 100.0
SECONDS = 2.0


def _bundle(kind: str, scratch: Path) -> tuple[Path, str]:
    """The bundle to time and how to name it in the notes."""
    if kind == "cnn2":
        default = resolve_bundle_path(DEFAULT_BUNDLE)
        if (default / "model.pt").is_file():
            return default, f"default {DEFAULT_BUNDLE}"
    return save_untrained_bundle(scratch / kind, kind), f"untrained {kind}"


def _measure(kind: str, bench: Benchmark) -> float:
    previous = torch.get_num_threads()
    try:
        with tempfile.TemporaryDirectory() as scratch:
            path, label = _bundle(kind, Path(scratch))
            estimator = ForceEstimator.from_bundle(path, threads=1)
        rng = np.random.default_rng(0)
        batches = rng.uniform(0.4, 3.0, (256, 5, 9)).astype(np.float32)
        for k in range(50):  # warm-up: TorchScript profiling runs and allocator
            estimator.estimate(batches[k % 256])
        latencies = []
        start = time.perf_counter()
        while time.perf_counter() - start < SECONDS:
            t = time.perf_counter()
            estimator.estimate(batches[len(latencies) % 256])
            latencies.append(time.perf_counter() - t)
        elapsed = time.perf_counter() - start
        lat = np.array(latencies) * 1e3
        bench.notes.update({"bundle": label,
                            "calls": len(latencies), "p50 latency ms": round(float(np.percentile(lat, 50)), 3),
                            "p99 latency ms": round(float(np.percentile(lat, 99)), 3), "torch threads": 1})
        return len(latencies) / elapsed
    finally:
        torch.set_num_threads(previous)


def _make(kind: str) -> Benchmark:
    bench = Benchmark(f"force_infer_{kind}", lambda: _measure(kind, bench), "calls/s", SCAN_RATE_HZ)
    return bench


BENCHMARKS = [_make(kind) for kind in MODEL_KINDS]
