"""The launched graph in bare relays: every node's CPU over one window with the relay role `stretch`
(bench/ros_relay.py) running beside it, so the graph and its yardstick see the same machine.

The bare relay takes the graph's own /joint_states and /prisma/hand/wrench (what tendon_stretch
reads) and copies out one JointState per /joint_states message, nothing computed. Figures per window:
the graph's nodes together over the relay ("graph in relays": issue 42 asks at most 4.0 for the sim
hand, 8 for two hands and the glove) and each tendon_stretch over the relay (at most 1.5). Nobody
watches the markers and no goal runs: the graph at rest, as it runs beside RViz's robot model.
The executor of the graph's nodes is whatever PRISMA_EXECUTOR asks (inherited by the launch); the
relay always runs on rclpy's SingleThreadedExecutor.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from graph_bench.cpu import measure_cpu, wait_quiet
from graph_bench.facts import HAND_NODES
from graph_bench.hand import Quiet
from graph_bench.hosts import BIMANUAL_NODES
from graph_bench.processes import check_alive, namespaced_node_pids, relay_command, start, stop
from graph_bench.stats import median_spread

DISPLAY_NODES = ("robot_state_publisher", "tendon_stretch", "tactile_markers")
# --display-graph: the launch arguments, its nodes ((label, node, namespace) rows) and the namespace
# of the hand the relay stands beside
DISPLAY_GRAPHS: dict[str, tuple[list[str], list[tuple[str, str, str]], str]] = {
    "hand": (["hand.launch.py", "sim:=true"], [(n, n, "") for n in HAND_NODES + DISPLAY_NODES], ""),
    "bimanual": (["bimanual.launch.py"],
                 [(label, node, ns) for label, node, ns, _ in BIMANUAL_NODES]
                 + [(f"{hand}/tendon_stretch", "tendon_stretch", f"/{hand}") for hand in ("left", "right")],
                 "/left"),
}
RELAY = "relay (stretch)"


def run_display(control: Any, graph: str, out: Path, repeat: int, settle_s: float = 8.0, cpu_s: float = 12.0,
                quiet: Quiet = (None, 0.0)) -> dict:
    """One launch of `graph` and the relay beside it; `repeat` CPU windows over both."""
    launch_args, nodes, namespace = DISPLAY_GRAPHS[graph]
    before = wait_quiet(*quiet)
    logdir = out / f"display_{graph}_{time.strftime('%H%M%S')}"
    logdir.mkdir(parents=True, exist_ok=True)
    launch = start(f"{graph}_launch", ["ros2", "launch", "prisma_bringup", *launch_args], logdir)
    procs = [launch]
    try:
        pids = namespaced_node_pids([launch.popen.pid], [(label, node, ns, "") for label, node, ns in nodes])
        relay_args = ["--ros-args", "-r", f"__ns:={namespace}"] if namespace else []
        relay = start("relay_stretch", relay_command("ros_relay.py", "stretch", *relay_args), logdir)
        procs.append(relay)
        control.wait_publishers([f"{namespace}/prisma/hand/wrench", f"{namespace}/joint_states",
                                 f"{namespace}/prisma/model_joint_states",
                                 f"{namespace}/prisma/relay_model_joint_states"], 120.0, procs)
        time.sleep(settle_s)
        windows = []
        for i in range(repeat):
            print(f"display {graph}: window {i + 1}/{repeat}", flush=True)
            windows.append(measure_cpu({**pids, RELAY: relay.popen.pid, "launch": launch.popen.pid}, cpu_s))
            check_alive(procs)
    finally:
        stop(procs)
    return {"graph": graph, "launch": " ".join(launch_args), "machine_before": before, "windows": windows,
            "summary": summarise_display(windows, [label for label, _, _ in nodes])}


def summarise_display(windows: list[dict], nodes: list[str]) -> dict:
    """Median (min-max) over the windows: the graph's nodes and each tendon_stretch in relays."""
    def pct(window: dict, name: str) -> float:
        return window["processes"][name]["cpu_pct"]

    relay = [pct(w, RELAY) for w in windows]
    graph = [sum(pct(w, n) for n in nodes) for w in windows]
    stretch = [n for n in nodes if n.endswith("tendon_stretch")]
    return {
        "relay_pct": median_spread(relay),
        "graph_nodes_pct": median_spread(graph),
        "graph_in_relays": median_spread([g / max(1e-9, r) for g, r in zip(graph, relay)]),
        "per_node_pct": {n: median_spread([pct(w, n) for w in windows]) for n in nodes},
        "tendon_stretch_in_relays": {n: median_spread([pct(w, n) / max(1e-9, r) for w, r in zip(windows, relay)])
                                     for n in stretch},
        "launch_process_pct": median_spread([pct(w, "launch") for w in windows]),
        "loadavg_1min": [w["loadavg_1min"] for w in windows],
        "others_pct": [w["others_pct"] for w in windows],
    }
