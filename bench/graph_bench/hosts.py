"""The bimanual graph (or one hand) on one host and split across two network namespaces (robot and
workstation, prisma_testing.two_hosts): CPU of every node, what crosses the link, and the latency
probe on the workstation while pinch grasps run on the left hand."""
from __future__ import annotations

import json
import os
import subprocess
import time
from pathlib import Path
from typing import Any

from graph_bench.cpu import measure_cpu, wait_quiet
from graph_bench.facts import MOVE_FEEDBACK, MOVE_STATUS
from graph_bench.hand import Quiet
from graph_bench.probe import bag_rates, read_probe, start_probe
from graph_bench.processes import Proc, check_alive, namespaced_node_pids, start, stop
from graph_bench.stats import latencies, median_spread, move_latency_real, percentiles

# bimanual.launch.py's nodes: (label, node name, namespace, the computer parts:= puts it on)
BIMANUAL_NODES = ([(f"{hand}/{node}", node, f"/{hand}", side) for hand in ("left", "right")
                   for node, side in (("tactile_driver", "robot"), ("motor_driver", "robot"),
                                      ("robot_state_publisher", "robot"), ("force_estimator", "workstation"),
                                      ("manipulation", "workstation"), ("tactile_markers", "workstation"))]
                  + [("glove/glove_driver", "glove_driver", "", "robot"),
                     ("glove/glove_perception", "glove_perception", "", "workstation")])
HOSTS_HAND = "/left"  # the hand the grasps run on and the latency probe records
# --hosts-graph: the launch command and its nodes (hand: the one hand alone, under the same namespace)
HOSTS_GRAPHS = {"bimanual": (["bimanual.launch.py"], BIMANUAL_NODES),
                "hand": (["hand.launch.py", f"namespace:={HOSTS_HAND[1:]}"],
                         [n for n in BIMANUAL_NODES if n[2] == HOSTS_HAND])}
LAYOUTS = ("one host", "two hosts")
CLONE_NEWNET = 0x40000000


def enter_netns(name: str) -> None:
    """Move this process's main thread into the network namespace `name` (`ip netns add`): every
    thread and process it starts from then on (rclpy's DDS participant, ros2 launch, the probes) is
    on that host."""
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    fd = os.open(f"/run/netns/{name}", os.O_RDONLY)
    try:
        if libc.setns(fd, CLONE_NEWNET) != 0:
            errno = ctypes.get_errno()
            raise OSError(errno, f"setns into network namespace {name}: {os.strerror(errno)}")
    finally:
        os.close(fd)


def link_counters(interface: str) -> dict[str, int]:
    """Bytes and packets through this namespace's end of the veth (rx: from the robot)."""
    done = subprocess.run(["ip", "-j", "-s", "link", "show", "dev", interface], capture_output=True, text=True,
                          check=True)
    stats = json.loads(done.stdout)[0]["stats64"]
    return {f"{way}_{what}": int(stats[way][what]) for way in ("rx", "tx") for what in ("bytes", "packets")}


def link_rates(before: dict[str, int], after: dict[str, int], seconds: float) -> dict:
    """Per direction: packets/s and bytes/s on the link (IP packets of UDP: DDS data, acks, discovery)."""
    return {direction: {"packets_s": round((after[f"{way}_packets"] - before[f"{way}_packets"]) / seconds, 1),
                        "bytes_s": round((after[f"{way}_bytes"] - before[f"{way}_bytes"]) / seconds)}
            for direction, way in (("robot -> workstation", "rx"), ("workstation -> robot", "tx"))}


def crossing_topics(control: Any) -> list[dict]:
    """Every topic published on one computer and subscribed on the other (bimanual.launch.py split):
    its direction and how many subscriber processes on the far side (DDS sends each its own copy)."""
    side = {(ns or "/", node): where for _, node, ns, where in BIMANUAL_NODES}
    out = []
    for topic, _ in control.node.get_topic_names_and_types():
        pubs = {side.get((i.node_namespace, i.node_name)) for i in control.node.get_publishers_info_by_topic(topic)}
        subs = [side.get((i.node_namespace, i.node_name)) for i in control.node.get_subscriptions_info_by_topic(topic)]
        for where in ("robot", "workstation"):
            far = [s for s in subs if s is not None and s != where]
            if where in pubs and far:
                out.append({"topic": topic, "direction": f"{where} -> {far[0]}", "far_subscribers": len(far)})
    return sorted(out, key=lambda t: (t["direction"], t["topic"]))


def _link_window(control: Any, hosts: Any, logdir: Path, robot_env: dict[str, str], cpu_window_s: float,
                 link0: dict[str, int], link_s: float) -> dict:
    """The link while idle, and each crossing topic's rate, recorded on the side that publishes it
    (where the recorder adds no copy to the link)."""
    out: dict = {"link_idle": link_rates(link0, link_counters(hosts.workstation.interface), cpu_window_s)}
    crossing = crossing_topics(control)
    bags, probes = {}, []
    try:
        for where, host in (("robot", hosts.robot), ("workstation", None)):
            topics = [t["topic"] for t in crossing if t["direction"].startswith(where)]
            if topics:
                probes.append(start_probe(topics, logdir / f"link_{where}", logdir, control, host,
                                          robot_env if host else None))
                bags[where] = logdir / f"link_{where}"
        time.sleep(link_s)
    finally:
        stop(probes)
    rates = {t: r for bag in bags.values() for t, r in bag_rates(bag).items()}
    out["crossing"] = [t | rates.get(t["topic"], {"msgs_s": 0.0, "bytes_s": 0}) for t in crossing]
    return out


def _start_layout(layout: str, launch: list[str], logdir: Path, hosts: Any, robot_env: dict[str, str]) -> list[Proc]:
    if layout == "one host":
        return [start("bimanual", launch, logdir)]
    return [start("bimanual_robot", hosts.robot.run([*launch, "parts:=robot"]), logdir, robot_env),
            start("bimanual_workstation", [*launch, "parts:=workstation"], logdir)]


def run_hosts(control: Any, layout: str, out: Path, hosts: Any, discovery: str, graph: str = "bimanual",
              settle_s: float = 5.0, cpu_s: float = 12.0, link_s: float = 10.0, grasps: int = 5,
              quiet: Quiet = (None, 0.0)) -> dict:
    """The graph of HOSTS_GRAPHS on one host (parts:=all in the workstation's namespace) or split
    (the robot part in the robot's namespace): CPU of every node, then (split) what crosses the
    link, then the latency probe on the workstation while pinch grasps run on the left hand."""
    launch_args, nodes = HOSTS_GRAPHS[graph]
    before = wait_quiet(*quiet)
    logdir = out / f"hosts_{layout.replace(' ', '_')}_{time.strftime('%H%M%S')}"
    logdir.mkdir(parents=True, exist_ok=True)
    robot_env = hosts.dds_env(hosts.robot, discovery)
    procs = _start_layout(layout, ["ros2", "launch", "prisma_bringup", *launch_args], logdir, hosts, robot_env)
    split = layout == "two hosts"
    result: dict = {"kind": layout, "machine_before": before, "discovery": discovery, "graph": graph}
    probe = None
    try:
        hands = sorted({ns for _, _, ns, _ in nodes if ns})
        control.wait_publishers([f"{h}/prisma/hand/{s}" for h in hands for s in ("taxels", "wrench")]
                                + (["/stag/hand_pose"] if graph == "bimanual" else []), 120.0, procs)
        pids = namespaced_node_pids([p.popen.pid for p in procs], nodes)
        pids.update({f"launch ({p.name})": p.popen.pid for p in procs})
        time.sleep(settle_s)
        link0 = link_counters(hosts.workstation.interface) if split else {}
        result["cpu"] = measure_cpu(pids, cpu_s)
        if split:
            result |= _link_window(control, hosts, logdir, robot_env, result["cpu"]["window_s"], link0, link_s)
        topics = [f"{HOSTS_HAND}{t}" for t in ("/prisma/hand/contact", "/prisma/hand/wrench", MOVE_STATUS,
                                               MOVE_FEEDBACK)]
        probe = start_probe(topics, logdir / "probe", logdir, control)
        link0 = link_counters(hosts.workstation.interface) if split else {}
        t0 = time.monotonic()
        cycles = [control.grasp_cycle(HOSTS_HAND) for _ in range(grasps)]
        if split:
            result["link_grasping"] = link_rates(link0, link_counters(hosts.workstation.interface),
                                                 time.monotonic() - t0)
        stop([probe])
        check_alive(procs)
        rec = read_probe(logdir / "probe", HOSTS_HAND)
    finally:
        stop(([probe] if probe else []) + procs)
    result["grasps"] = [{k: g[k] for k in ("success", "reason", "opened")} for g in cycles]
    stats, _ = latencies(rec, [(g["accept_ns"], g["end_ns"]) for g in cycles if g["accepted"]])
    move, counts = move_latency_real(rec, cycles)
    stats["move_accepted"] = percentiles(move) | counts
    result["latency"] = {k: v for k, v in stats.items() if "/" not in k}
    return result


def _host_groups(nodes: list[tuple[str, str, str, str]]) -> dict[str, list[str]]:
    """The process groups the CPU table sums: each node, each hand's robot and workstation parts,
    each hand, each computer and all nodes."""
    groups = {label: [label] for label, *_ in nodes}
    for hand in sorted({ns for _, _, ns, _ in nodes if ns}):
        for where in ("robot", "workstation"):
            groups[f"{hand[1:]} hand, {where} part"] = [lb for lb, _, ns, w in nodes if ns == hand and w == where]
        groups[f"{hand[1:]} hand"] = [lb for lb, _, ns, _ in nodes if ns == hand]
    for where in ("robot", "workstation"):
        groups[f"{where} computer (its nodes)"] = [lb for lb, *_, w in nodes if w == where]
    groups["all nodes"] = [lb for lb, *_ in nodes]
    return groups


def summarise_hosts(runs: list[dict]) -> dict:
    """Medians (and spread over repeats) of the one-host and two-host runs, side by side."""
    by = {k: [r for r in runs if r["kind"] == k] for k in LAYOUTS}
    graph = runs[0].get("graph", "bimanual")
    out: dict = {"cpu_pct": {}, "latency_ms": {}, "repeats": len(by["two hosts"]),
                 "graph": " ".join(HOSTS_GRAPHS[graph][0])}
    for name, labels in _host_groups(HOSTS_GRAPHS[graph][1]).items():
        one = [sum(r["cpu"]["processes"][label]["cpu_pct"] for label in labels) for r in by["one host"]]
        two = [sum(r["cpu"]["processes"][label]["cpu_pct"] for label in labels) for r in by["two hosts"]]
        out["cpu_pct"][name] = {"one host": median_spread(one), "two hosts": median_spread(two),
                                "ratio": median_spread([b / a for a, b in zip(one, two) if a])}
    for hop in ("contact_received", "wrench_received", "move_accepted", "contact_published", "wrench_published"):
        entry: dict = {}
        for q in ("p50_ms", "p99_ms"):
            one = [r["latency"][hop].get(q) for r in by["one host"]]
            two = [r["latency"][hop].get(q) for r in by["two hosts"]]
            entry[q] = {"one host": median_spread(one), "two hosts": median_spread(two),
                        "added": median_spread([b - a for a, b in zip(one, two) if a is not None and b is not None])}
        entry["n"] = {k: [r["latency"][hop]["n"] for r in by[k]] for k in LAYOUTS}
        out["latency_ms"][hop] = entry
    out["grasps"] = {k: [f"{sum(g['success'] for g in r['grasps'])}/{len(r['grasps'])}" for r in by[k]]
                     for k in LAYOUTS}
    split = by["two hosts"]
    for window in ("link_idle", "link_grasping"):
        out[window] = {d: {q: median_spread([r[window][d][q] for r in split]) for q in ("packets_s", "bytes_s")}
                       for d in ("robot -> workstation", "workstation -> robot")}
    topics: dict[tuple[str, str], list] = {}
    for r in split:
        for t in r["crossing"]:
            topics.setdefault((t["direction"], t["topic"]), []).append(t)
    out["crossing"] = [{"direction": d, "topic": t, "far_subscribers": rows[0]["far_subscribers"],
                        "msgs_s": median_spread([x["msgs_s"] for x in rows]),
                        "bytes_s": median_spread([x["bytes_s"] for x in rows])}
                       for (d, t), rows in sorted(topics.items())]
    out["machine"] = {k: [r["cpu"][k] for r in runs] for k in ("others_pct", "loadavg_1min")}
    return out
