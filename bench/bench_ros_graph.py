"""The hand and glove graphs over DDS beside a bare rclpy relay chain (python bench/run.py --only ros_...).

Needs ROS 2 Jazzy and this workspace's install/ sourced; without them every entry prints
`skipped: needs ROS 2 (...)` and the value nan. bench/graph_bench does the work (and
bench/ros_graph.py, run as a script, the repeated runs, the profiles and the plots of
docs/performance.md); each entry here is one figure of a single run of it, in the ROS_DOMAIN_ID of
the calling shell, every process on the control path's scheduling rung. The real graph is
`hand.launch.py sim:=true` / `glove.launch.py` (the sweep starts the same executables with
`-p rate_hz:=R`), the relays are bench/ros_relay.py. Every ratio is "higher is better":

ros_graph_cpu_100hz: scans per second of one core the four hand nodes use at 100 Hz, counted: the
  scans that went through the whole chain (a wrench and a contact of the scan's stamp for every
  finger) in the probe's window during pinch grasps, over the nodes' summed CPU in that window. A
  scan dropped anywhere is not counted, so dropping scans lowers the figure. Needed: 100, the whole
  graph at 100 Hz in at most one core.
ros_cpu_vs_relay_<node>: relay CPU / node CPU at 100 Hz, the relay handling the same messages.
  Needed: 1 / 1.5 (the node at most 1.5x its relay).
ros_latency_<hop>_p99: relay p99 / graph p99 of taxel stamp -> ContactState / WrenchStamped
  received at the probe, and -> MoveMotors goal accepted at the motor driver, at 100 Hz during pinch
  Grasp goals. Needed: 0.5 (p99 at most 2x the relay chain's).
ros_scan_rate_max: highest swept scan rate (100..500 Hz) the real graph sustains with no taxel
  sample dropped by force_estimator or manipulation, no stale sample and >= 98% of the scans.
  Needed: 350 Hz (the I2C bus's limit for 5 fingers).
ros_glove_cpu: glove frames handled (answered by glove_perception, or rejected as shorted) per
  second of one core of glove_driver + glove_perception at 7.3 frames/s, counted in the probe's
  window. Needed: 7.3.
"""
from __future__ import annotations

import functools
import math
import tempfile
from pathlib import Path

from graph_bench.control import measured_with_ros, shared_control
from graph_bench.facts import GLOVE_NODES, GLOVE_RATE_HZ, HAND_NODES
from graph_bench.glove import run_glove
from graph_bench.hand import max_sustained, run_hand, summarise_hand, sweep
from run import Benchmark

SWEEP_RATES = [100.0, 150.0, 200.0, 250.0, 300.0, 350.0, 400.0, 450.0, 500.0]


@functools.cache
def _out() -> Path:
    return Path(tempfile.mkdtemp(prefix="prisma_ros_bench_"))


@functools.cache
def _hand() -> dict:
    runs = [run_hand(shared_control(), kind, _out()) for kind in ("real", "relay")]
    return {"runs": runs, "summary": summarise_hand(runs)}


@functools.cache
def _sweep() -> list[dict]:
    return sweep(shared_control(), _out(), SWEEP_RATES, ("real", "relay"), probe_s=12.0)


@functools.cache
def _glove() -> dict:
    return {kind: run_glove(shared_control(), kind, _out()) for kind in ("real", "relay")}


def _graph_cpu() -> float:
    cpu = _hand()["summary"]["cpu_pct"]
    for node in HAND_NODES:
        GRAPH_CPU.notes[f"{node} % (relay %)"] = f"{cpu[node]['real']['median']} ({cpu[node]['relay']['median']})"
    total = cpu["graph (4 nodes)"]
    GRAPH_CPU.notes["graph % of one core (relay chain %)"] = f"{total['real']['median']} ({total['relay']['median']})"
    GRAPH_CPU.notes["machine: others % during the window"] = _hand()["summary"]["machine"]["others_pct"]
    for run in _hand()["runs"]:
        t = run["throughput"]
        GRAPH_CPU.notes[f"{run['kind']}: scans handled in the probe's window"] = (
            f"{t['handled_scans']} in {t['window_s']} s ({t['handled_hz']}/s) for {t['nodes_cpu_pct']} % of one core, "
            f"{', '.join(sorted(set(run['rungs'].values())))}")
    real = _hand()["summary"]["throughput"]["real"]["scans_per_core_s"]["median"]
    return math.nan if real is None else real


def _node_vs_relay(node: str, bench: Benchmark) -> float:
    cpu = _hand()["summary"]["cpu_pct"][node]
    bench.notes.update({"node %": cpu["real"]["median"], "relay %": cpu["relay"]["median"],
                        "node / relay": cpu["ratio"]["median"]})
    return cpu["relay"]["median"] / cpu["real"]["median"]


def _latency(hop: str, bench: Benchmark) -> float:
    lat = _hand()["summary"]["latency_ms"][hop]
    bench.notes.update({"p50 ms (relay)": f"{lat['p50_ms']['real']['median']} ({lat['p50_ms']['relay']['median']})",
                        "p99 ms (relay)": f"{lat['p99_ms']['real']['median']} ({lat['p99_ms']['relay']['median']})",
                        "samples (relay)": f"{lat['n']['real']} ({lat['n']['relay']})"})
    real, relay = lat["p99_ms"]["real"]["median"], lat["p99_ms"]["relay"]["median"]
    if not real or not relay:
        bench.notes["no ratio"] = "no samples of this hop in one of the runs"
        return math.nan
    return relay / real


def _scan_rate() -> float:
    rows = _sweep()
    for row in rows:
        SCAN_RATE.notes[f"{row['kind']} {row['rate_hz']:g} Hz"] = (
            f"received {row['received_hz']} Hz, dropped wrench {row['dropped_wrench']} contact "
            f"{row['dropped_contact']}, stale {len(row['stale'])}, aborts {row['sensor_stale_aborts']}")
    rungs = {kind: sorted({v for r in rows if r["kind"] == kind for v in r["rungs"].values()})
             for kind in ("real", "relay")}
    SCAN_RATE.notes["scheduling (graph; relay)"] = f"{', '.join(rungs['real'])}; {', '.join(rungs['relay'])}"
    SCAN_RATE.notes["relay chain sustains (Hz)"] = max_sustained(rows, "relay")
    return max_sustained(rows, "real")


def _glove_cpu() -> float:
    runs = _glove()
    total = {}
    for kind, run in runs.items():
        total[kind] = sum(run["cpu"]["processes"][n]["cpu_pct"] for n in GLOVE_NODES)
        for n in GLOVE_NODES:
            GLOVE_CPU.notes[f"{kind} {n} %"] = run["cpu"]["processes"][n]["cpu_pct"]
    GLOVE_CPU.notes["frames/s at the probe"] = runs["real"]["rates_hz"].get("/stag/frame")
    GLOVE_CPU.notes["nodes / relay"] = round(total["real"] / total["relay"], 2)
    for kind, run in runs.items():
        t = run["throughput"]
        GLOVE_CPU.notes[f"{kind}: frames handled in the probe's window"] = (
            f"{t['handled_frames']} ({t['shorted_frames']} shorted) in {t['window_s']} s for {t['nodes_cpu_pct']} % "
            f"of one core")
    per_core = runs["real"]["throughput"]["frames_per_core_s"]
    return math.nan if per_core is None else per_core


def _make(name: str, fn, unit: str, need: float) -> Benchmark:
    bench = Benchmark(name, lambda: measured_with_ros(bench.notes, _out, lambda: fn(bench)), unit, need)
    return bench


GRAPH_CPU = _make("ros_graph_cpu_100hz", lambda b: _graph_cpu(), "scans/s/core", 100.0)
NODE_CPU = [_make(f"ros_cpu_vs_relay_{node}", functools.partial(_node_vs_relay, node), "relay/node", 1 / 1.5)
            for node in HAND_NODES]
LATENCY = [_make(f"ros_latency_{hop.split('_')[0]}_p99", functools.partial(_latency, hop), "relay/graph", 0.5)
           for hop in ("contact_received", "wrench_received", "move_accepted")]
SCAN_RATE = _make("ros_scan_rate_max", lambda b: _scan_rate(), "Hz", 350.0)
GLOVE_CPU = _make("ros_glove_cpu", lambda b: _glove_cpu(), "frames/s/core", GLOVE_RATE_HZ)
BENCHMARKS = [GRAPH_CPU, *NODE_CPU, *LATENCY, SCAN_RATE, GLOVE_CPU]
