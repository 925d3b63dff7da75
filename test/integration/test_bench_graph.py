"""bench/graph_bench and bench/ros_graph.py without ROS: counted throughput, the scheduling rung read
from /proc, the table of parts."""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from prisma_common.hand import FINGERS
from prisma_testing.repo_paths import ROOT


@pytest.fixture()
def bench(monkeypatch):
    """bench/ importable as when a script there runs (its folder first on sys.path)."""
    monkeypatch.syspath_prepend(str(ROOT / "bench"))
    import graph_bench.display
    import graph_bench.hand
    import graph_bench.stats
    import ros_graph

    return graph_bench, ros_graph


def _recording(bench_pkg, scans: int, missing: list[tuple[str, str, int]]):
    """`scans` scans 10 ms apart on every finger's wrench and contact topics, less the (finger,
    kind, scan index) samples in `missing` (a node that dropped them)."""
    stamps = np.arange(scans, dtype=np.int64) * 10_000_000 + 1_000_000_000
    rec = bench_pkg.probe.Recording()
    for f in FINGERS:
        for kind in ("wrench", "contact"):
            keep = [i for i in range(scans) if (f, kind, i) not in missing]
            rec.stamps[f"/prisma/{f}/{kind}"] = stamps[keep]
    return rec, int(stamps[0]), int(stamps[-1])


def test_a_dropped_scan_is_not_handled_and_lowers_the_throughput(bench):
    graph_bench, _ = bench
    whole, lo, hi = _recording(graph_bench, 100, [])
    dropped, _, _ = _recording(graph_bench, 100, [("index", "wrench", 3), ("little", "contact", 3),
                                                   ("thumb", "contact", 70)])
    assert graph_bench.stats.handled_scans(whole, lo, hi) == 100
    assert graph_bench.stats.handled_scans(dropped, lo, hi) == 98
    assert graph_bench.stats.handled_scans(whole, lo + 1, hi) == 99  # the window's edges count
    cpu = {"window_ns": [lo, lo + 1_000_000_000], "tactile_driver": 10.0, "force_estimator": 10.0,
           "manipulation": 20.0, "motor_driver": 10.0}
    full = graph_bench.hand.throughput(whole, cpu)
    assert full == {"handled_scans": 100, "window_s": 1.0, "handled_hz": 100.0, "nodes_cpu_pct": 50.0,
                    "scans_per_core_s": 200.0}
    # at the same CPU the graph that dropped two scans scores 196, not 200
    assert graph_bench.hand.throughput(dropped, cpu)["scans_per_core_s"] == pytest.approx(196.0)
    # the estimator skipped the work of the dropped scans (8 % instead of 10 %): the old figure,
    # 100 Hz x 100 / CPU %, rose to 208.3; the counted one is 98 scans / 0.48 core-s = 204.2
    fewer = graph_bench.hand.throughput(dropped, cpu | {"force_estimator": 8.0})
    assert fewer["handled_scans"] == 98 and fewer["scans_per_core_s"] == pytest.approx(204.2, abs=0.05)
    assert fewer["scans_per_core_s"] < 100 * 100 / fewer["nodes_cpu_pct"]

def test_rung_reads_niceness_and_default(bench):
    graph_bench, _ = bench
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"],
                             preexec_fn=lambda: os.nice(7))
    try:
        time.sleep(0.2)
        assert graph_bench.cpu.rung(child.pid) == "nice 7"
    finally:
        child.kill()
        child.wait()
    assert graph_bench.cpu.rung(child.pid) == "gone"
    if os.getpriority(os.PRIO_PROCESS, 0) == 0 and os.sched_getscheduler(0) == os.SCHED_OTHER:
        assert graph_bench.cpu.rung(os.getpid()) == "default"


def test_parts_run_in_table_order_and_hosts_runs_alone(bench):
    _, ros_graph = bench
    parser = ros_graph.build_parser()
    assert ros_graph.chosen_parts(parser, "glove,hand,sweep") == ["hand", "sweep", "glove"]
    for bad in ("hand,nope", "hosts,hand"):
        with pytest.raises(SystemExit):
            ros_graph.chosen_parts(parser, bad)
    assert set(ros_graph.PARTS) == {"hosts", "hand", "sweep", "glove", "markers", "display", "entities", "profile"}
    assert isinstance(parser.parse_args(["--parts", "hand"]), argparse.Namespace)


def test_the_display_bench_counts_the_graph_in_bare_relays_and_each_tendon_stretch_in_its_relay(bench):
    graph_bench, ros_graph = bench

    def window(relay: float, stretch_relay: float, nodes: dict[str, float]) -> dict:
        relays = {"relay (markers, watched)": relay, "relay (stretch)": stretch_relay}
        processes = {name: {"cpu_pct": pct} for name, pct in {**nodes, **relays, "launch": 3.0}.items()}
        return {"processes": processes, "loadavg_1min": [9.5, 9.9], "others_pct": 40.0}

    nodes = ["left/tendon_stretch", "right/tendon_stretch", "left/manipulation"]
    windows = [window(10.0, 5.0, {"left/tendon_stretch": 5.0, "right/tendon_stretch": 6.0, "left/manipulation": 29.0}),
               window(20.0, 8.0, {"left/tendon_stretch": 5.0, "right/tendon_stretch": 5.0, "left/manipulation": 30.0})]
    summary = graph_bench.display.summarise_display(windows, nodes)
    # each window's ratio against its own bare relay (40 / 10 and 40 / 20), not the medians' ratio (40 / 15)
    assert summary["graph_in_relays"] == {"median": 3.0, "min": 2.0, "max": 4.0, "runs": 2}
    assert summary["graph_in_stretch_relays"] == {"median": 6.5, "min": 5.0, "max": 8.0, "runs": 2}
    # tendon_stretch over the stretch relay of its window: 6 / 5 and 5 / 8
    assert summary["tendon_stretch_in_relays"]["right/tendon_stretch"] == {"median": 0.912, "min": 0.625,
                                                                          "max": 1.2, "runs": 2}
    assert summary["launch_process_pct"]["median"] == 3.0  # beside the graph, not in it
    assert set(summary["tendon_stretch_in_relays"]) == {"left/tendon_stretch", "right/tendon_stretch"}
    # both hands' tendon_stretch and the glove are in the bimanual graph's nodes
    labels = [label for label, _, _ in graph_bench.display.DISPLAY_GRAPHS["bimanual"][1]]
    assert {"left/tendon_stretch", "right/tendon_stretch", "glove/glove_perception"} <= set(labels)
    parser = ros_graph.build_parser()
    assert ros_graph.chosen_parts(parser, "display,hand") == ["hand", "display"]
