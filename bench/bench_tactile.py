"""Tactile driver benchmarks (python bench/run.py --only tactile_parse).

tactile_parse: five-finger hub frames parsed per second on one core (sync search, CRC check,
12-bit unpacking, conversion to voltages), fed in 4 KiB reads as the serial backend does.
Needed: 100 frames/s, the paper's rate; a ratio of 10 covers the 1 Mbaud link's ~1 kHz ceiling.
tactile_sim_scan: simulated five-finger scans per second (scripted contacts + pad models),
needed 100 Hz so the sim backend keeps up in real time.
"""
from __future__ import annotations

import time

import numpy as np

from prisma_common.hand import counts_to_voltages
from prisma_hand_sim.contact_source import ScriptedContactSource
from prisma_tactile_driver.protocol import FrameParser, encode_frame
from prisma_tactile_driver.sim_backend import SimHubBackend
from run import Benchmark

N_FRAMES = 20_000
READ_SIZE = 4096


def _parse_rate() -> float:
    rng = np.random.default_rng(0)
    stream = b"".join(encode_frame(i, rng.integers(0, 4096, (5, 9))) for i in range(N_FRAMES))
    parser = FrameParser()
    latencies = []
    decoded = 0
    start = time.perf_counter()
    for offset in range(0, len(stream), READ_SIZE):
        t0 = time.perf_counter()
        for frame in parser.feed(stream[offset:offset + READ_SIZE]):
            counts_to_voltages(frame.counts)
            decoded += 1
        latencies.append(time.perf_counter() - t0)
    elapsed = time.perf_counter() - start
    assert decoded == N_FRAMES and parser.stats.crc_errors == 0
    PARSE.notes["us_per_frame"] = round(elapsed / decoded * 1e6, 2)
    PARSE.notes["p99_read_latency_ms (4 KiB = 52 frames)"] = round(float(np.percentile(latencies, 99)) * 1e3, 3)
    return decoded / elapsed


def _sim_rate() -> float:
    backend = SimHubBackend(ScriptedContactSource())
    n = 2000
    start = time.perf_counter()
    for i in range(n):
        backend.read(i * 10_000_000)
    elapsed = time.perf_counter() - start
    SIM.notes["us_per_scan"] = round(elapsed / n * 1e6, 1)
    return n / elapsed


PARSE = Benchmark("tactile_parse", _parse_rate, "frames/s", 100.0)
SIM = Benchmark("tactile_sim_scan", _sim_rate, "scans/s", 100.0)
BENCHMARKS = [PARSE, SIM]
