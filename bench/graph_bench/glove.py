"""The glove graph at 7.3 frames/s, real or relay, and tactile_markers idle and watched beside its
relay role: CPU windows and what the probe (or a display) received."""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from graph_bench.cpu import CpuSampler, measure_cpu, wait_quiet
from graph_bench.facts import GLOVE_NODES, GLOVE_TOPICS, HAND_NODES, MARKER_TOPIC, RELAY_MARKER_TOPIC, RELAY_ROLE
from graph_bench.hand import Quiet
from graph_bench.probe import Recording, read_messages, read_probe, start_probe
from graph_bench.processes import check_alive, launch_nodes, relay_command, start, stop
from graph_bench.stats import median_spread

PERCEIVED = ("/stag/object", "/stag/hand_pose", "/stag/weight")  # each published for a frame when estimated


def handled_frames(rec: Recording, shorted: set[int], lo: int, hi: int) -> int:
    """Frames stamped in [lo, hi] that glove_perception took: answered (any of its outputs with the
    frame's stamp) or, for a frame the driver marked shorted, rejected by design with no answer."""
    frames = rec.stamps.get("/stag/frame", np.array([], dtype=np.int64))
    frames = np.unique(frames[(frames >= lo) & (frames <= hi)])
    answered = np.concatenate([rec.stamps.get(t, np.array([], dtype=np.int64)) for t in PERCEIVED])
    return int(np.sum(np.isin(frames, answered) | np.isin(frames, list(shorted))))


def run_glove(control: Any, kind: str, out: Path, settle_s: float = 5.0, cpu_s: float = 20.0,
              probe_s: float = 10.0, quiet: Quiet = (None, 0.0)) -> dict:
    """CPU with nothing else subscribed, then the probe's frame rates and the frames handled per
    second of one core in the probe's window (counted: a dropped frame lowers the figure)."""
    before = wait_quiet(*quiet)
    logdir = out / f"glove_{kind}_{time.strftime('%H%M%S')}"
    logdir.mkdir(parents=True, exist_ok=True)
    if kind == "relay":
        relay = {node: start(f"relay_{RELAY_ROLE[node]}", relay_command("ros_relay.py", RELAY_ROLE[node]), logdir)
                 for node in GLOVE_NODES}
        procs, pids = list(relay.values()), {n: p.popen.pid for n, p in relay.items()}
    else:
        proc, nodes = launch_nodes("glove_launch", ["ros2", "launch", "prisma_bringup", "glove.launch.py"], logdir,
                                   GLOVE_NODES)
        procs, pids = [proc], {**nodes, "launch": proc.popen.pid}
    probe = None
    try:
        control.wait_publishers(["/stag/frame", "/stag/hand_pose", "/stag/weight"], 90.0, procs)
        time.sleep(settle_s)
        result = {"kind": kind, "machine_before": before, "cpu": measure_cpu(pids, cpu_s)}
        probe = start_probe(GLOVE_TOPICS, logdir / "probe", logdir, control)
        sampler = CpuSampler(pids)
        time.sleep(probe_s)
        cpu_with_probe = sampler.done()
        stop([probe])
        check_alive(procs)
    finally:
        stop(([probe] if probe else []) + procs)
    rec = read_probe(logdir / "probe")
    shorted = {stamp for stamp, frame in read_messages(logdir / "probe", "/stag/frame") if frame.shorted}
    lo, hi = cpu_with_probe["window_ns"]
    result["rates_hz"] = {t: round(float(np.sum((s >= lo + 5e8) & (s <= hi - 5e8)) / ((hi - lo - 1e9) / 1e9)), 2)
                          for t, s in rec.stamps.items()}
    frames, seconds = handled_frames(rec, shorted, lo, hi), (hi - lo) / 1e9
    nodes_pct = sum(cpu_with_probe[n] for n in GLOVE_NODES)
    result["throughput"] = {"handled_frames": frames, "shorted_frames": sum(lo <= t <= hi for t in shorted),
                            "window_s": round(seconds, 2), "handled_hz": round(frames / seconds, 2),
                            "nodes_cpu_pct": round(nodes_pct, 1),
                            "frames_per_core_s": round(frames / seconds / (nodes_pct / 100), 1) if nodes_pct else None}
    return result


def _watched(log: Path) -> dict:
    """What a `ros_relay.py watch` received, from its last line."""
    text = log.read_text().strip() if log.is_file() else ""
    words = text.splitlines()[-1].split() if text else []
    if len(words) >= 5 and words[0] == "watch:":
        count, seconds = int(words[1]), float(words[4])
        return {"messages": count, "seconds": seconds, "rate_hz": round(count / seconds, 1) if seconds else None}
    return {"messages": None}


def _watched_pair(pids: dict[str, int], logdir: Path, i: int, settle_s: float, cpu_s: float) -> tuple[dict, dict]:
    """tactile_markers watched by a display, then the relay role `markers` watched instead."""
    watch = start(f"watch_real_{i}", relay_command("ros_relay.py", "watch", "--topic", MARKER_TOPIC), logdir)
    time.sleep(settle_s)
    cpu = measure_cpu(pids, cpu_s)
    stop([watch])
    real = {**cpu, "watched": _watched(watch.log)}
    relay = start(f"relay_markers_{i}", relay_command("ros_relay.py", "markers"), logdir)
    watch = start(f"watch_relay_{i}", relay_command("ros_relay.py", "watch", "--topic", RELAY_MARKER_TOPIC), logdir)
    time.sleep(settle_s)
    cpu = measure_cpu({**pids, "relay_markers": relay.popen.pid}, cpu_s)
    stop([watch, relay])
    return real, {**cpu, "watched": _watched(watch.log)}


def run_markers(control: Any, out: Path, repeat: int, settle_s: float = 4.0, cpu_s: float = 12.0,
                quiet: Quiet = (None, 0.0)) -> dict:
    """tactile_markers on the launched sim graph: idle (nobody watches), then `repeat` times watched
    by a display and, right after, the relay role `markers` watched instead."""
    before = wait_quiet(*quiet)
    logdir = out / f"markers_{time.strftime('%H%M%S')}"
    logdir.mkdir(parents=True, exist_ok=True)
    launch, pids = launch_nodes("hand_launch", ["ros2", "launch", "prisma_bringup", "hand.launch.py", "sim:=true"],
                                logdir, HAND_NODES + ("tactile_markers",))
    procs = [launch]
    try:
        control.wait_publishers(["/prisma/hand/taxels", "/joint_states"], 90.0, procs)
        time.sleep(settle_s)
        result: dict = {"machine_before": before, "idle": measure_cpu(pids, cpu_s), "real": [], "relay": []}
        for i in range(repeat):
            print(f"markers watched, then the relay's, run {i + 1}/{repeat}", flush=True)
            real, relay = _watched_pair(pids, logdir, i, settle_s, cpu_s)
            result["real"].append(real)
            result["relay"].append(relay)
            check_alive(procs)
    finally:
        stop(procs)
    result["summary"] = _markers_summary(result)
    return result


def _markers_summary(result: dict) -> dict:
    real = [r["processes"]["tactile_markers"]["cpu_pct"] for r in result["real"]]
    relay = [r["processes"]["relay_markers"]["cpu_pct"] for r in result["relay"]]

    def graph(row: dict) -> float:
        return sum(row["processes"][n]["cpu_pct"] for n in HAND_NODES + ("tactile_markers",))

    return {
        "tactile_markers_idle_pct": result["idle"]["processes"]["tactile_markers"]["cpu_pct"],
        "tactile_markers_watched_pct": median_spread(real),
        "relay_markers_watched_pct": median_spread(relay),
        "ratio": median_spread([a / max(1e-9, b) for a, b in zip(real, relay)]),
        "graph_idle_pct": round(graph(result["idle"]), 1),
        "graph_watched_pct": median_spread([graph(r) for r in result["real"]]),
        "markers_hz": [r["watched"].get("rate_hz") for r in result["real"]],
        "relay_markers_hz": [r["watched"].get("rate_hz") for r in result["relay"]],
    }
