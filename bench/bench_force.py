"""Force estimator inference: five-finger calls per second on one core (need 100: the 100 Hz scan).

One call = ForceEstimator.estimate on a [5, 9] batch (all fingers of one scan). force_infer_cnn2
uses the shipped default bundle (config/models/cnn2) when present; the other models, whose
speed does not depend on their weights, use freshly initialised bundles. Each runs the precision
ForceEstimator picks by default (float16 weights for CNN2, float32 for the others).

force_cnn2_float16_cold: the default bundle's float16 dense chain against its float32 TorchScript
network, side by side in one process: calls alternate between the two, each after a 10 ms sleep
as in the node (one call per 100 Hz scan, caches cold), timed in thread CPU time. Measured: how
many times cheaper float16 is (median per-call CPU of float32 / of float16; the range is over five
consecutive fifths of the run); needed 1.8, what the node's CPU needs (docs/performance.md). The
notes give the per-call medians, the same ratio in a hot loop and the largest force difference.
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from prisma_force_estimator.bundle import DEFAULT_BUNDLE, resolve_bundle_path, save_untrained_bundle
from prisma_force_estimator.evaluation import held_out_tests
from prisma_force_estimator.inference import ForceEstimator
from prisma_force_estimator.networks import MODEL_KINDS
from run import Benchmark

SCAN_RATE_HZ = 100.0
SECONDS = 2.0
SCAN_PERIOD_S = 1.0 / SCAN_RATE_HZ
COLD_CALLS = 300  # per precision: 6 s of sleeps
HOT_CALLS = 3000
NEEDED_SPEEDUP = 1.8


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
        bench.notes.update({"bundle": label, "precision": estimator.precision,
                            "calls": len(latencies), "p50 latency ms": round(float(np.percentile(lat, 50)), 3),
                            "p99 latency ms": round(float(np.percentile(lat, 99)), 3), "torch threads": 1})
        return len(latencies) / elapsed
    finally:
        torch.set_num_threads(previous)


def _make(kind: str) -> Benchmark:
    bench = Benchmark(f"force_infer_{kind}", lambda: _measure(kind, bench), "calls/s", SCAN_RATE_HZ)
    return bench


def _alternating_cpu_us(estimators: list[ForceEstimator], batches: np.ndarray, calls: int,
                        sleep_s: float) -> list[np.ndarray]:
    """Thread CPU time of each estimator's calls in us, the estimators called in turn (the order
    flipped every round) so that both see the same machine; `sleep_s` before every call."""
    times: list[list[float]] = [[] for _ in estimators]
    order = list(range(len(estimators)))
    for k in range(calls):
        for i in (order if k % 2 == 0 else order[::-1]):
            if sleep_s:
                time.sleep(sleep_s)
            start = time.thread_time_ns()
            estimators[i].estimate(batches[k % len(batches)])
            times[i].append((time.thread_time_ns() - start) / 1e3)
    return [np.array(t) for t in times]


def _speedup(reference: np.ndarray, fast: np.ndarray) -> tuple[float, float, float]:
    """Median ratio reference / fast, and its range over five consecutive fifths of the run."""
    parts = [float(np.median(reference[c]) / np.median(fast[c])) for c in np.array_split(np.arange(len(fast)), 5)]
    return float(np.median(reference) / np.median(fast)), min(parts), max(parts)


def _measure_float16(bench: Benchmark) -> float:
    previous = torch.get_num_threads()
    try:
        path = resolve_bundle_path(DEFAULT_BUNDLE)
        fast = ForceEstimator.from_bundle(path, threads=1, precision="float16")
        exact = ForceEstimator.from_bundle(path, threads=1, precision="float32")
        if fast.precision != "float16":
            bench.notes["skipped"] = "no float16 path in this torch build (fbgemm)"
            return 0.0
        # the node's input: five fingertips of held-out push and slide voltages per call
        tests = held_out_tests(push_samples=2000, slide_samples=2000)
        voltages = np.concatenate([tests.push.voltages, tests.slide.voltages]).astype(np.float32)
        force_diff = float(np.abs(fast.estimate(voltages) - exact.estimate(voltages))[:, :3].max())
        batches = voltages[: len(voltages) // 5 * 5].reshape(-1, 5, 9)
        _alternating_cpu_us([exact, fast], batches, 50, 0.0)  # warm-up: TorchScript profiling runs
        cold = _alternating_cpu_us([exact, fast], batches, COLD_CALLS, SCAN_PERIOD_S)
        hot = _alternating_cpu_us([exact, fast], batches, HOT_CALLS, 0.0)
        ratio, low, high = _speedup(*cold)
        hot_ratio, hot_low, hot_high = _speedup(*hot)
        bench.notes.update({
            "cold: us per call float32 / float16 (median)": f"{np.median(cold[0]):.0f} / {np.median(cold[1]):.0f}",
            "cold: speedup range": f"{low:.2f}-{high:.2f}",
            "hot: us per call float32 / float16 (median)": f"{np.median(hot[0]):.0f} / {np.median(hot[1]):.0f}",
            "hot: speedup": f"{hot_ratio:.2f} ({hot_low:.2f}-{hot_high:.2f})",
            "max force difference N": f"{force_diff:.1e}", "calls": f"{COLD_CALLS} cold, {HOT_CALLS} hot each",
            "torch threads": 1})
        return ratio
    finally:
        torch.set_num_threads(previous)


def _make_float16() -> Benchmark:
    bench = Benchmark("force_cnn2_float16_cold", lambda: _measure_float16(bench), "x cheaper", NEEDED_SPEEDUP)
    return bench


BENCHMARKS = [*(_make(kind) for kind in MODEL_KINDS), _make_float16()]
