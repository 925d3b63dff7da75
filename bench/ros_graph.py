"""The hand and glove graphs over DDS, measured side by side with bare rclpy relays (needs ROS 2).

    python3 bench/ros_graph.py --repeat 2 --out perf_out --plots docs/img

needs ROS 2 Jazzy and this workspace's install/ sourced (bench_ros_graph.py runs the same
measurements as `python bench/run.py` entries). Each measurement runs the project's nodes ("real")
and the relays of bench/ros_relay.py ("relay", the same topics, types, rates, QoS and hop count on
rclpy's default executor) one after the other in the same invocation, in the same ROS_DOMAIN_ID,
all on the control path's scheduling rung (hand.launch.py's: SCHED_FIFO 20 where permitted).
`--parts` picks the measurements (PARTS below; bench/graph_bench does the work, one job a module):

- hand at 100 Hz: the real graph through `ros2 launch prisma_bringup hand.launch.py sim:=true`. After
  `settle_s`, the CPU of every node process over `cpu_s` (utime + stime from /proc/<pid>/stat, all
  threads; per thread name too), with nothing else subscribed. Then the probe, `ros2 bag record`
  (C++, keep-last 1000 per topic), records taxels, wrenches, contacts (the graph's per-hand
  topics, the relays' per-finger ones), /joint_states, /diagnostics and the MoveMotors status and
  feedback topics while pinch Grasp goals run, each followed by a
  MoveMotors position goal that opens the hand. Latencies are from the taxel header stamp (the
  sensor's clock when the scan was read) to the probe's receipt of the ContactState / WrenchStamped
  with that stamp (bag log time) and to their publication (bag publish time = DDS source
  timestamp), counted for samples stamped while a Grasp goal ran. The MoveMotors hop: the goal the
  grasp sends when the index force reaches its target (the first index wrench >= finger_force
  after the goal's acceptance) to its acceptance at the motor driver (GoalInfo.stamp); for the
  relay, the goal every 10th index wrench and the stamp it carries. Throughput: the scans that
  went through the whole chain (a wrench and a contact of the scan's stamp for every finger) in the
  probe's window, per second of one core the four nodes used in that window.
- scan-rate sweep: the four hand nodes started as hand.launch.py does (same executables, parameters
  and scheduling rung) but with `-p rate_hz:=R`; at each R, pinch grasps run while the probe
  records, and dropped = taxel stamps without a wrench / contact of the same stamp, stale = any
  /diagnostics status mentioning "stale" at WARN or above, or a grasp ended with sensor_stale.
- glove at 7.3 frames/s: `ros2 launch prisma_bringup glove.launch.py` (sim backend), CPU of
  glove_driver and glove_perception over `cpu_s`, then frame counts at the probe and the frames
  handled (answered by glove_perception, or rejected as shorted) per second of one core in the
  probe's window.
- tactile markers: on one launched sim graph, the CPU of tactile_markers and of the hand nodes with
  nobody watching the markers, then, alternating, with a display's subscription on them (ros_relay.py
  watch) and with the relay role `markers` (the same inputs, the same MarkerArray at the same rate,
  nothing computed) watched instead.

Every process started here runs in its own process group and is stopped with SIGINT, then SIGTERM,
then SIGKILL; none outlives the run.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from graph_bench.control import Control, ros_missing
from graph_bench.cpu import wait_quiet
from graph_bench.display import DISPLAY_GRAPHS, run_display
from graph_bench.glove import run_glove, run_markers
from graph_bench.hand import max_sustained, relay_entities, run_hand, summarise_hand, sweep
from graph_bench.hosts import HOSTS_GRAPHS, LAYOUTS, enter_netns, run_hosts, summarise_hosts
from graph_bench.profile import profile_hand
from graph_bench.report import markdown, plot

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test" / "support"))  # prisma_testing: not installed


def _hosts(control: Control, args: argparse.Namespace, results: dict, hosts: Any) -> None:
    results["hosts"] = []
    for i in range(args.repeat):
        for layout in LAYOUTS:
            print(f"bimanual graph, {layout}, run {i + 1}/{args.repeat}", flush=True)
            results["hosts"].append(run_hosts(control, layout, args.out, hosts, args.hosts_discovery,
                                              args.hosts_graph, cpu_s=args.cpu_s, grasps=args.grasps,
                                              quiet=args.quiet))
    results["hosts_summary"] = summarise_hosts(results["hosts"])
    print(json.dumps(results["hosts_summary"], indent=1), flush=True)


def _hand(control: Control, args: argparse.Namespace, results: dict, hosts: Any) -> None:
    results["hand"] = []
    for i in range(args.repeat):
        for kind in ("real", "relay"):
            print(f"hand 100 Hz {kind}, run {i + 1}/{args.repeat}", flush=True)
            results["hand"].append(run_hand(control, kind, args.out, grasps=args.grasps, cpu_s=args.cpu_s,
                                            quiet=args.quiet, graph_probe=args.graph_probe))
    results["hand_summary"] = summarise_hand(results["hand"])
    print(json.dumps(results["hand_summary"], indent=1), flush=True)


def _sweep(control: Control, args: argparse.Namespace, results: dict, hosts: Any) -> None:
    rates = [float(r) for r in args.sweep.split(",") if r.strip()]
    if not rates:
        return
    print("scan-rate sweep", flush=True)
    results["sweep"] = sweep(control, args.out, rates, ("real", "relay"), args.sweep_s, args.quiet, args.graph_probe)
    results["sweep_max_sustained_hz"] = {k: max_sustained(results["sweep"], k) for k in ("real", "relay")}
    print(results["sweep_max_sustained_hz"], flush=True)


def _glove(control: Control, args: argparse.Namespace, results: dict, hosts: Any) -> None:
    results["glove"] = []
    for i in range(args.repeat):
        for kind in ("real", "relay"):
            print(f"glove {kind}, run {i + 1}/{args.repeat}", flush=True)
            results["glove"].append(run_glove(control, kind, args.out, cpu_s=max(args.cpu_s, 20.0), quiet=args.quiet))
    print(json.dumps(results["glove"], indent=1), flush=True)


def _markers(control: Control, args: argparse.Namespace, results: dict, hosts: Any) -> None:
    print("tactile markers, idle and watched, beside the relay", flush=True)
    results["markers"] = run_markers(control, args.out, args.repeat, cpu_s=args.cpu_s, quiet=args.quiet)
    print(json.dumps(results["markers"]["summary"], indent=1), flush=True)


def _display(control: Control, args: argparse.Namespace, results: dict, hosts: Any) -> None:
    results["display"] = {}
    for graph in args.display_graph.split(","):
        print(f"the {graph} graph at rest beside the bare relay (markers, watched) and the stretch relay", flush=True)
        results["display"][graph] = run_display(control, graph, args.out, args.repeat, cpu_s=args.cpu_s,
                                                quiet=args.quiet)
        print(json.dumps({graph: results["display"][graph]["summary"]}, indent=1), flush=True)


def _entities(control: Control, args: argparse.Namespace, results: dict, hosts: Any) -> None:
    print("relay manipulation with and without the node's idle entities", flush=True)
    results["entities"] = relay_entities(control, args.out, cpu_s=args.cpu_s, quiet=args.quiet)
    print(json.dumps(results["entities"], indent=1), flush=True)


def _profile(control: Control, args: argparse.Namespace, results: dict, hosts: Any) -> None:
    print("py-spy profiles of the hand nodes at 100 Hz", flush=True)
    wait_quiet(*args.quiet)
    results["profile"] = profile_hand(control, args.out)
    print(json.dumps(results["profile"], indent=1), flush=True)


@dataclass(frozen=True)
class Part:
    run: Callable[[Control, argparse.Namespace, dict, Any], None]
    what: str


# --parts, in the order they run
PARTS = {
    "hosts": Part(_hosts, "alone: the bimanual graph on one host and split across two network namespaces (root)"),
    "hand": Part(_hand, "CPU, latency and throughput at 100 Hz, graph and relay"),
    "sweep": Part(_sweep, "the scan rates of --sweep, graph and relay"),
    "glove": Part(_glove, "the glove graph at 7.3 frames/s and its relay"),
    "markers": Part(_markers, "tactile_markers idle and watched, beside its relay"),
    "display": Part(_display, "the launched graph at rest in bare relays (--display-graph), its tendon_stretch "
                              "in relays"),
    "entities": Part(_entities, "the manipulation relay with the node's idle entities"),
    "profile": Part(_profile, "py-spy of each hand node (needs py-spy)"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("perf_out"), help="logs, bags and results.json")
    parser.add_argument("--repeat", type=int, default=1, help="100 Hz runs of each kind, alternating (spread)")
    parser.add_argument("--grasps", type=int, default=10, help="pinch grasps per real 100 Hz run")
    parser.add_argument("--cpu-s", type=float, default=12.0, help="CPU window (s)")
    parser.add_argument("--sweep", default="100,150,200,250,300,350,400,450,500",
                        help="scan rates (Hz), comma separated; '' = no sweep")
    parser.add_argument("--sweep-s", type=float, default=12.0, help="probe recording per sweep rate (s)")
    parser.add_argument("--parts", default="hand,sweep,glove,entities,profile",
                        help="which measurements, comma separated: "
                             + "; ".join(f"{name} ({part.what})" for name, part in PARTS.items()))
    parser.add_argument("--hosts-discovery", choices=("subnet", "static"), default="subnet",
                        help="--parts hosts: DDS discovery over the link (test/support/prisma_testing/two_hosts.py)")
    parser.add_argument("--hosts-graph", choices=tuple(HOSTS_GRAPHS), default="bimanual",
                        help="--parts hosts: both hands and the glove, or the left hand alone")
    parser.add_argument("--quiet-below", type=float,
                        help="before each run, wait until the machine uses at most this CPU %% (of one core)")
    parser.add_argument("--quiet-wait", type=float, default=600.0, help="... for at most this many seconds")
    parser.add_argument("--plots", type=Path, help="write perf_sweep.png and perf_latency_cdf.png here")
    parser.add_argument("--keep-bags", action="store_true", help="keep the probe's bags under --out")
    parser.add_argument("--graph-probe", choices=("hand", "finger"), default="hand",
                        help="what the probe records from the graph: its per-hand topics (what its own nodes "
                             "take) or the 15 per-finger ones (a recorder of the README's list beside it)")
    parser.add_argument("--display-graph", default="hand",
                        help="--parts display: comma separated, of " + ", ".join(DISPLAY_GRAPHS)
                             + " (bimanual: both hands and the glove)")
    parser.add_argument("--markdown", action="store_true",
                        help="only print the tables of an earlier run's --out/results.json (no ROS needed)")
    return parser


def chosen_parts(parser: argparse.ArgumentParser, text: str) -> list[str]:
    """The --parts in the order they run; a parser error names an unknown or ill-combined one."""
    parts = {p.strip() for p in text.split(",") if p.strip()}
    unknown = parts - set(PARTS)
    if unknown:
        parser.error(f"unknown --parts {sorted(unknown)}; choose from {', '.join(PARTS)}")
    if "hosts" in parts and parts != {"hosts"}:
        parser.error("--parts hosts runs alone: it moves this process onto the workstation's network namespace")
    if "profile" in parts and shutil.which("py-spy") is None:
        parser.error("--parts profile needs py-spy on PATH (pip install py-spy)")
    return [name for name in PARTS if name in parts]


def open_hosts(discovery: str) -> Any:
    """The two network namespaces, this process moved onto the workstation's (the goals' client runs
    there, with its DDS settings); None with a message where they cannot be made."""
    from prisma_testing.two_hosts import HostsUnavailable, TwoHosts

    try:
        hosts = TwoHosts.create()
    except HostsUnavailable as exc:
        print(f"skipped: two hosts need network namespaces: {exc}", file=sys.stderr)
        return None
    enter_netns(hosts.workstation.netns)
    os.environ.update(hosts.dds_env(hosts.workstation, discovery))
    return hosts


def save(results: dict, args: argparse.Namespace, partial: bool) -> None:
    """results.json written whole (a partial run updates what it measured and keeps the rest), its
    tables printed and the plots written."""
    path = args.out / "results.json"
    if path.is_file() and partial:
        results = {**json.loads(path.read_text()), **{k: v for k, v in results.items() if k != "machine"},
                   "machine": results["machine"]}
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(results, indent=1))
    tmp.replace(path)
    print(markdown(results))
    for written in plot(results, args.plots) if args.plots else []:
        print(f"wrote {written}")
    print(f"wrote {path}")


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.markdown:
        path = args.out / "results.json"
        if not path.is_file():
            parser.error(f"no {path}: run the measurements with --out {args.out} first")
        print(markdown(json.loads(path.read_text())))
        return 0
    missing = ros_missing()
    if missing:
        print(f"skipped: {missing}", file=sys.stderr)
        return 2
    parts = chosen_parts(parser, args.parts)
    unknown_graphs = set(args.display_graph.split(",")) - set(DISPLAY_GRAPHS)
    if "display" in parts and unknown_graphs:
        parser.error(f"unknown --display-graph {sorted(unknown_graphs)}; choose from {', '.join(DISPLAY_GRAPHS)}")
    args.quiet = (args.quiet_below, args.quiet_wait)
    args.out.mkdir(parents=True, exist_ok=True)
    results: dict = {"machine": {"cpus": os.cpu_count(), "uname": " ".join(os.uname()[2:5]),
                                 "loadavg_at_start": [round(x, 2) for x in os.getloadavg()],
                                 "ros_domain_id": os.environ.get("ROS_DOMAIN_ID"),
                                 "rmw": os.environ.get("RMW_IMPLEMENTATION")},
                     "started": time.strftime("%Y-%m-%d %H:%M:%S"), "command": " ".join(sys.argv),
                     "graph_probe": args.graph_probe}
    hosts = None
    if "hosts" in parts:
        hosts = open_hosts(args.hosts_discovery)
        if hosts is None:
            return 2
        results["hosts_discovery"] = args.hosts_discovery
    try:
        control = Control()
        try:
            for name in parts:
                PARTS[name].run(control, args, results, hosts)
        finally:
            control.close()
    finally:
        if hosts is not None:
            hosts.delete()
        if not args.keep_bags:
            for bag in [*args.out.glob("*/probe"), *args.out.glob("*/link_*")]:
                if bag.is_dir():
                    shutil.rmtree(bag, ignore_errors=True)
    results["finished"] = time.strftime("%Y-%m-%d %H:%M:%S")
    results["machine"]["loadavg_at_end"] = [round(x, 2) for x in os.getloadavg()]
    save(results, args, partial=args.parts != parser.get_default("parts"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
