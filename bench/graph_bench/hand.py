"""The hand graph at a scan rate, real or relay: CPU with nothing else subscribed, then the probe
while pinch grasps run; the scan-rate sweep; the relay with the node's idle entities.

Every run puts the control path on one rung, hand.launch.py's (prisma_common.scheduling
control_path_env: SCHED_FIFO 20 where permitted): the launched graph, the node executables the
sweep starts and the relays alike, so the real and relay runs and the 100 Hz and swept runs compare
like with like. Each run records the rung every process was seen at (`rungs`).
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

from graph_bench.cpu import CpuSampler, measure_cpu, rung, wait_quiet
from graph_bench.facts import FINGER_STREAMS, GRAPH_TOPICS, HAND_NODES, HAND_TOPICS, RELAY_ROLE
from graph_bench.probe import Recording, read_probe, start_probe
from graph_bench.processes import Proc, check_alive, launch_nodes, relay_command, start, stop
from graph_bench.stats import (
    drops,
    handled_scans,
    latencies,
    median_spread,
    move_latency_real,
    move_latency_relay,
    percentiles,
    stale_statuses,
)
from prisma_common.hand import FINGERS
from prisma_common.scheduling import control_path_env

Quiet = tuple[float | None, float]  # (max machine CPU %, max wait s) before a run: cpu.wait_quiet


def _share() -> Path:
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory("prisma_bringup"))


def _executable(package: str, name: str) -> str:
    from ament_index_python.packages import get_package_prefix

    return str(Path(get_package_prefix(package)) / "lib" / package / name)


def start_hand(kind: str, rate_hz: float, logdir: Path, launch: bool,
               relay_args: dict[str, list[str]] | None = None) -> tuple[list[Proc], dict[str, int]]:
    """The hand graph on the control path's rung; returns the processes to stop and the pid of each
    node (or its relay). relay_args: extra arguments of a relay role (bench/ros_relay.py), by node."""
    rung_env = control_path_env()
    if kind == "relay":
        relay = {node: start(f"relay_{RELAY_ROLE[node]}",
                             relay_command("ros_relay.py", RELAY_ROLE[node],
                                           "--rate-hz", str(rate_hz if node == "tactile_driver" else 100.0),
                                           "--goal-every", str(max(1, round(rate_hz / 10))),
                                           *(relay_args or {}).get(node, [])), logdir, rung_env)
                 for node in HAND_NODES}
        return list(relay.values()), {node: p.popen.pid for node, p in relay.items()}
    if launch:  # hand.launch.py's rt_priority:= and nice:= defaults are the same rung
        if rate_hz != 100.0:
            raise ValueError(f"hand.launch.py runs the sim scan at config/tactile_driver.yaml's rate_hz; "
                             f"{rate_hz} Hz needs launch=False")
        proc, pids = launch_nodes("hand_launch", ["ros2", "launch", "prisma_bringup", "hand.launch.py", "sim:=true"],
                                  logdir, HAND_NODES)
        return [proc], {**pids, "launch": proc.popen.pid}
    config = _share() / "config"
    # as hand.launch.py sim:=true starts them: config/<node>.yaml plus its inline parameters
    args = {
        "tactile_driver": ("prisma_tactile_driver", ["-p", "backend:=sim", "-p", "contact_source:=hand_world",
                                                     "-p", f"rate_hz:={rate_hz:.1f}"]),
        "force_estimator": ("prisma_force_estimator", ["-p", f"model_bundle:={config / 'models' / 'cnn2'}"]),
        "manipulation": ("prisma_manipulation", []),
        "motor_driver": ("prisma_motor_driver", ["-p", "backend:=sim"]),
    }
    procs = {node: start(node, [_executable(package, node), "--ros-args", "-r", f"__node:={node}",
                                "--params-file", str(config / f"{node}.yaml"), *extra], logdir, rung_env)
             for node, (package, extra) in args.items()}
    return list(procs.values()), {node: p.popen.pid for node, p in procs.items()}


def _probe_window(control: Any, kind: str, procs: list[Proc], pids: dict[str, int], logdir: Path,
                  grasps: int, probe_s: float | None, relay_s: float, graph_probe: str) -> dict:
    """The probe records while grasps run (real) or for relay_s (relay); the nodes' CPU meanwhile."""
    topics = GRAPH_TOPICS if kind == "real" and graph_probe == "hand" else HAND_TOPICS
    probe = start_probe(topics, logdir / "probe", logdir, control)
    try:
        t_lo = time.time_ns()
        cycles: list[dict] = []
        sampler = CpuSampler({**pids, "probe (ros2 bag record)": probe.popen.pid})
        if kind == "real":
            deadline = time.monotonic() + (probe_s or math.inf)
            while (len(cycles) < grasps) if probe_s is None else (time.monotonic() < deadline):
                cycles.append(control.grasp_cycle())
                check_alive(procs)
        else:
            time.sleep(probe_s or relay_s)
        cpu = sampler.done()
        t_hi = time.time_ns()
    finally:
        stop([probe])
    return {"cycles": cycles, "t_lo": t_lo, "t_hi": t_hi, "cpu_with_probe": cpu,
            "rec": read_probe(logdir / "probe")}


def throughput(rec: Recording, cpu_with_probe: dict) -> dict:
    """Scans the chain handled in the probe's CPU window per second of one core the four nodes used
    in it: counted, so a graph that drops scans scores lower, not higher."""
    lo, hi = cpu_with_probe["window_ns"]
    seconds = (hi - lo) / 1e9
    scans = handled_scans(rec, lo, hi)
    nodes_pct = sum(cpu_with_probe[n] for n in HAND_NODES)
    return {"handled_scans": scans, "window_s": round(seconds, 2), "handled_hz": round(scans / seconds, 1),
            "nodes_cpu_pct": round(nodes_pct, 1),
            "scans_per_core_s": round(scans / seconds / (nodes_pct / 100), 1) if nodes_pct > 0 else None}


def _hand_figures(kind: str, window: dict, rate_hz: float) -> dict:
    """Latencies, flow, stale statuses and throughput of one probe window."""
    rec, cycles, t_lo, t_hi = window["rec"], window["cycles"], window["t_lo"], window["t_hi"]
    out: dict = {"grasps": [{k: g[k] for k in ("success", "reason", "opened")}
                            | {"duration_s": round((g["end_ns"] - g["accept_ns"]) / 1e9, 3)} for g in cycles]}
    windows = [(g["accept_ns"], g["end_ns"]) for g in cycles if g["accepted"]] if kind == "real" else [(t_lo, t_hi)]
    stats, samples = latencies(rec, windows)
    if kind == "real":
        move, counts = move_latency_real(rec, cycles)
        stats["move_accepted"] = percentiles(move) | counts
    else:
        move = move_latency_relay(rec)
        stats["move_accepted"] = percentiles(move)
    samples["move_accepted"] = move
    out["latency"] = stats
    out["latency_all_samples"] = {k: v for k, v in latencies(rec, [(t_lo, t_hi)])[0].items()
                                  if k in ("contact_received", "wrench_received")}
    lo, hi = t_lo + 500_000_000, t_hi - 500_000_000  # by stamp: leave the edges of the recording
    out["flow"] = drops(rec, lo, hi, rate_hz)
    out["stale"] = stale_statuses(rec, lo, hi)
    out["sensor_stale_aborts"] = sum(1 for g in cycles if g["reason"] == "sensor_stale")
    out["throughput"] = throughput(rec, window["cpu_with_probe"])
    out["samples_ms"] = {k: [round(float(x), 4) for x in v] for k, v in samples.items()}
    return out


def run_hand(control: Any, kind: str, out: Path, rate_hz: float = 100.0, launch: bool = True,
             settle_s: float = 3.0, cpu_s: float = 12.0, grasps: int = 10, relay_s: float = 20.0,
             probe_s: float | None = None, quiet: Quiet = (None, 0.0), graph_probe: str = "hand") -> dict:
    """One hand graph: CPU window, then the probe while grasps run (real) or for relay_s (relay).
    probe_s: record for this long (grasping meanwhile) instead of a number of grasps (the sweep).
    graph_probe: "hand" records the graph's per-hand topics, "finger" its 15 per-finger ones."""
    before = wait_quiet(*quiet)
    logdir = out / f"hand_{kind}_{rate_hz:g}hz_{time.strftime('%H%M%S')}"
    logdir.mkdir(parents=True, exist_ok=True)
    started_by = ("bench/ros_relay.py" if kind == "relay" else "ros2 launch hand.launch.py" if launch
                  else "the node executables with config/<node>.yaml")
    result: dict = {"kind": kind, "rate_hz": rate_hz, "machine_before": before, "started_by": started_by}
    procs, pids = start_hand(kind, rate_hz, logdir, launch)
    try:
        control.wait_publishers(FINGER_STREAMS + ["/joint_states"], 90.0, procs)
        time.sleep(settle_s)
        result["rungs"] = {node: rung(pids[node]) for node in HAND_NODES}
        result["cpu"] = measure_cpu(pids, cpu_s) if cpu_s > 0 else None
        check_alive(procs)
        window = _probe_window(control, kind, procs, pids, logdir, grasps, probe_s, relay_s, graph_probe)
        check_alive(procs)
    finally:
        stop(procs)
    result["cpu_with_probe"] = window["cpu_with_probe"]
    return result | _hand_figures(kind, window, rate_hz)


def summarise_hand(runs: list[dict]) -> dict:
    """Median (and spread over repeats) of every figure of the 100 Hz runs, real vs relay."""
    by = {k: [r for r in runs if r["kind"] == k] for k in ("real", "relay")}
    out: dict = {"cpu_pct": {}, "latency_ms": {}, "repeats": len(by["real"])}
    for node in (*HAND_NODES, "graph (4 nodes)"):
        names = HAND_NODES if node == "graph (4 nodes)" else (node,)
        real = [sum(r["cpu"]["processes"][n]["cpu_pct"] for n in names) for r in by["real"]]
        relay = [sum(r["cpu"]["processes"][n]["cpu_pct"] for n in names) for r in by["relay"]]
        out["cpu_pct"][node] = {"real": median_spread(real), "relay": median_spread(relay),
                                "ratio": median_spread([a / max(1e-9, b) for a, b in zip(real, relay)])}
    out["cpu_pct"]["ros2 launch process"] = {"real": median_spread(
        [r["cpu"]["processes"]["launch"]["cpu_pct"] for r in by["real"] if "launch" in r["cpu"]["processes"]])}
    for hop in ("contact_received", "wrench_received", "move_accepted", "contact_published", "wrench_published",
                "taxels_published"):
        entry: dict = {}
        for q in ("p50_ms", "p99_ms"):
            real = [r["latency"][hop].get(q) for r in by["real"]]
            relay = [r["latency"][hop].get(q) for r in by["relay"]]
            entry[q] = {"real": median_spread(real), "relay": median_spread(relay),
                        "ratio": median_spread([a / b for a, b in zip(real, relay) if a is not None and b])}
        entry["n"] = {kind: [r["latency"][hop]["n"] for r in by[kind]] for kind in ("real", "relay")}
        out["latency_ms"][hop] = entry
    out["throughput"] = {kind: {key: median_spread([r["throughput"][key] for r in by[kind]])
                                for key in ("scans_per_core_s", "handled_hz", "nodes_cpu_pct")}
                         for kind in ("real", "relay")}
    out["rungs"] = {kind: sorted({r["rungs"][n] for r in by[kind] for n in HAND_NODES}) for kind in by}
    out["grasps"] = {"real": [f"{sum(g['success'] for g in r['grasps'])}/{len(r['grasps'])}" for r in by["real"]]}
    out["machine"] = {k: [r["cpu"][k] for r in runs] for k in ("others_pct", "loadavg_1min")}
    return out


def sweep(control: Any, out: Path, rates: list[float], kinds: tuple[str, ...], probe_s: float,
          quiet: Quiet = (None, 0.0), graph_probe: str = "hand") -> list[dict]:
    """Each rate, each kind: the nodes started with `-p rate_hz:=R`, grasping while the probe records."""
    rows = []
    for rate in rates:
        for kind in kinds:
            r = run_hand(control, kind, out, rate_hz=rate, launch=False, cpu_s=0.0, probe_s=probe_s, quiet=quiet,
                         graph_probe=graph_probe)
            f = r["flow"]
            row = {"kind": kind, "rate_hz": rate, **f, "stale": r["stale"],
                   "sensor_stale_aborts": r["sensor_stale_aborts"],
                   "grasps": f"{sum(g['success'] for g in r['grasps'])}/{len(r['grasps'])}" if kind == "real" else "",
                   "cpu_with_probe": r["cpu_with_probe"], "machine_before": r["machine_before"],
                   "rungs": r["rungs"], "throughput": r["throughput"],
                   "contact_received_p99_ms": r["latency_all_samples"]["contact_received"].get("p99_ms")}
            row["sustained"] = (f["dropped_wrench"] == 0 and f["dropped_contact"] == 0 and not r["stale"]
                                and r["sensor_stale_aborts"] == 0 and f["received_hz"] >= 0.98 * rate)
            print(f"  sweep {kind:5s} {rate:5.0f} Hz ({', '.join(sorted(set(r['rungs'].values())))}): received "
                  f"{f['received_hz']:6.1f} Hz, dropped wrench {f['dropped_wrench']}, contact {f['dropped_contact']}, "
                  f"scan gaps {f['scan_gaps']}, stale {len(r['stale'])}, sustained {row['sustained']}", flush=True)
            rows.append(row)
    return rows


def max_sustained(rows: list[dict], kind: str) -> float:
    """The highest rate of the sweep below which (inclusive) every rate was sustained."""
    best = 0.0
    for row in sorted((r for r in rows if r["kind"] == kind), key=lambda r: r["rate_hz"]):
        if not row["sustained"]:
            break
        best = row["rate_hz"]
    return best


def relay_entities(control: Any, out: Path, settle_s: float = 3.0, cpu_s: float = 12.0,
                   quiet: Quiet = (None, 0.0)) -> dict:
    """CPU of the relay chain at 100 Hz with the manipulation relay bare and with the node's idle
    entities added (--like-node): what the executor charges for a bigger wait set."""
    out_rows = {}
    for label, extra in (("bare", []), ("with the node's idle action servers and timer", ["--like-node"])):
        wait_quiet(*quiet)
        logdir = out / f"entities_{time.strftime('%H%M%S')}"
        logdir.mkdir(parents=True, exist_ok=True)
        procs, pids = start_hand("relay", 100.0, logdir, launch=False, relay_args={"manipulation": extra})
        try:
            control.wait_publishers([f"/prisma/{f}/contact" for f in FINGERS], 60.0, procs)
            time.sleep(settle_s)
            cpu = measure_cpu(pids, cpu_s)
        finally:
            stop(procs)
        out_rows[label] = {"manipulation relay %": cpu["processes"]["manipulation"]["cpu_pct"],
                           "others_pct": cpu["others_pct"]}
    return out_rows
