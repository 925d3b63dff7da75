"""The launched graph in bare relays: every node's CPU over one window with the bare relays running
beside it, so the graph and its yardstick see the same machine.

The bare relay (issue 42's yardstick) is the relay role `markers` of bench/ros_relay.py watched by a
display (the role `watch` on its MarkerArray, as in `--parts markers`): it takes the graph's own
/prisma/hand/contact and /prisma/hand/wrench at 100 Hz and sends tactile_markers' MarkerArray at
30 Hz, nothing computed. It is the relay of the issue's figures: its "3.8 bare relays" is the
markers bench's unwatched hand graph over this relay watched (77.9 / 20.5 % of a core,
docs/performance.md "The pads in RViz"), and its tendon_stretch at "12.1% of a core (0.68 of a bare
relay)" puts the relay at 17.7-17.8 %. The relay role `stretch` runs in the same window as
tendon_stretch's own relay: the same two 100 Hz inputs (/joint_states and /prisma/hand/wrench), one
JointState copied out per /joint_states message, nothing computed; each tendon_stretch is given over
it (issue 42: a node at most 1.5 of its relay), and the graph over it too, for the figures of the
session that measured against it (about half the bare relay's CPU, so twice the count).

Before the relays start, one window of the graph alone (`graph_alone`: the issue's protocol, graph
and relay one after the other, given over the median relay). Figures per window: the graph's nodes
together over the bare relay ("graph in relays": issue 42 asks at most 4.0 for the sim hand, 8 for
two hands and the glove) and each tendon_stretch over its relay. Nobody watches the graph's markers
and no goal runs: the graph at rest, as it runs beside RViz's robot model (the bare relay's
subscription to /prisma/hand/contact has manipulation build and send it, as a watched
tactile_markers does; beside the relay that cost is counted in the graph).

The executor of the graph's nodes is whatever PRISMA_EXECUTOR asks (inherited by the launch); the
relays always run on rclpy's SingleThreadedExecutor, on the control path's rung (SCHED_FIFO 20
where permitted, as the hand bench's relays), the bare relay's display too: at the default rung a
loaded machine starves a relay, which then drops samples and reads cheap. The graph runs as
launched (its control path on that rung, the display nodes at the default one). Run it in a
ROS_DOMAIN_ID of its own on a shared machine: another graph in the domain feeds the relays too.
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
from prisma_common.scheduling import control_path_env

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
RELAY = "relay (markers, watched)"  # the bare relay
STRETCH_RELAY = "relay (stretch)"  # tendon_stretch's own relay


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
        # one window of the graph alone first (the protocol: the graph, then the relay, one
        # after the other): beside the bare relay, manipulation also builds /prisma/hand/contact for it
        control.wait_publishers([f"{namespace}/prisma/hand/wrench", f"{namespace}/prisma/model_joint_states"],
                                120.0, procs)
        time.sleep(settle_s)
        print(f"display {graph}: the graph alone", flush=True)
        alone = measure_cpu({**pids, "launch": launch.popen.pid}, cpu_s)
        relay_args = ["--ros-args", "-r", f"__ns:={namespace}"] if namespace else []
        # the relays and the bare relay's display on the control path's rung, as the hand bench's
        # relays: on a loaded machine a relay at the default rung is starved, drops samples and reads cheap
        relay = start("relay_markers", relay_command("ros_relay.py", "markers", *relay_args), logdir,
                      control_path_env())
        # the display that watches the bare relay; beside the graph, in neither figure
        watch = start("watch_relay_markers", relay_command("ros_relay.py", "watch", "--topic",
                                                           f"{namespace}/prisma/relay_markers"), logdir,
                      control_path_env())
        stretch = start("relay_stretch", relay_command("ros_relay.py", "stretch", *relay_args), logdir,
                        control_path_env())
        procs += [relay, watch, stretch]
        control.wait_publishers([f"{namespace}/prisma/hand/wrench", f"{namespace}/joint_states",
                                 f"{namespace}/prisma/model_joint_states", f"{namespace}/prisma/relay_markers",
                                 f"{namespace}/prisma/relay_model_joint_states"], 120.0, procs)
        time.sleep(settle_s)
        windows = []
        for i in range(repeat):
            print(f"display {graph}: window {i + 1}/{repeat}", flush=True)
            windows.append(measure_cpu({**pids, RELAY: relay.popen.pid, STRETCH_RELAY: stretch.popen.pid,
                                        "launch": launch.popen.pid}, cpu_s))
            check_alive(procs)
    finally:
        stop(procs)
    labels = [label for label, _, _ in nodes]
    summary = summarise_display(windows, labels)
    graph_alone = round(sum(alone["processes"][n]["cpu_pct"] for n in labels), 1)
    summary["graph_alone"] = {"graph_nodes_pct": graph_alone, "loadavg_1min": alone["loadavg_1min"],
                              "in_median_relays": round(graph_alone / max(1e-9, summary["relay_pct"]["median"]), 3),
                              "per_node_pct": {n: alone["processes"][n]["cpu_pct"] for n in labels}}
    return {"graph": graph, "launch": " ".join(launch_args), "machine_before": before, "alone": alone,
            "windows": windows, "summary": summary}


def summarise_display(windows: list[dict], nodes: list[str]) -> dict:
    """Median (min-max) over the windows: the graph's nodes in bare relays, and each tendon_stretch
    (and the graph) over the stretch relay; each ratio is taken within its window."""
    def pct(window: dict, name: str) -> float:
        return window["processes"][name]["cpu_pct"]

    relay = [pct(w, RELAY) for w in windows]
    stretch_relay = [pct(w, STRETCH_RELAY) for w in windows]
    graph = [sum(pct(w, n) for n in nodes) for w in windows]
    stretch = [n for n in nodes if n.endswith("tendon_stretch")]
    return {
        "relay_pct": median_spread(relay),
        "stretch_relay_pct": median_spread(stretch_relay),
        "graph_nodes_pct": median_spread(graph),
        "graph_in_relays": median_spread([g / max(1e-9, r) for g, r in zip(graph, relay)]),
        "graph_in_stretch_relays": median_spread([g / max(1e-9, r) for g, r in zip(graph, stretch_relay)]),
        "per_node_pct": {n: median_spread([pct(w, n) for w in windows]) for n in nodes},
        "tendon_stretch_in_relays": {
            n: median_spread([pct(w, n) / max(1e-9, r) for w, r in zip(windows, stretch_relay)]) for n in stretch},
        "launch_process_pct": median_spread([pct(w, "launch") for w in windows]),
        "loadavg_1min": [w["loadavg_1min"] for w in windows],
        "others_pct": [w["others_pct"] for w in windows],
    }
