"""Soak of the launched sim graph beside the load harness (needs ROS 2 and the workspace sourced):

    python3 bench/soak.py --minutes 20 --out soak_out [--plot docs/img/soak.png] [--no-load]
                          [--rt-priority 0]

Cycles of a pinch Grasp, a horizontal Manipulate, a vertical Manipulate cancelled after 0.3 s and a
GripperCommand open, back to back (test/support/prisma_testing/goal_soak.py), on `hand.launch.py sim:=true` with a
CPU hog per core and a memory-bandwidth hog beside it (test/support/prisma_testing/load_harness.py). Prints each
goal kind's outcomes, the nodes' resident memory after the first cycle and its growth, and writes
soak.json (and the plot: RSS per node over time, each goal's duration and outcome). Exit 1 when a
goal missed its paper outcome, a node died or grew 5 MB or more. `--rt-priority 0` launches the
control path without real-time scheduling (at hand.launch.py's `nice`), to see what the priority buys.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

from prisma_common.scheduling import CONTROL_PATH_RT_PRIORITY

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test" / "support"))  # prisma_testing: not installed

HERE = Path(__file__).resolve().parent

NODES = ("tactile_driver", "force_estimator", "motor_driver", "manipulation")
MAX_RSS_GROWTH_MB = 5.0


def minute_medians(report) -> dict[str, list[float]]:
    """Each goal kind's median duration (s) in the soak's first minute and in its last: a creep shows
    as the second above the first."""
    last_start = report.goals[-1].started_s - 60.0 if report.goals else 0.0
    medians = {}
    for name in dict.fromkeys(g.name for g in report.goals):
        first = [g.seconds for g in report.goals if g.name == name and g.started_s < 60.0]
        last = [g.seconds for g in report.goals if g.name == name and g.started_s >= last_start]
        medians[name] = [round(statistics.median(first), 3), round(statistics.median(last), 3)]
    return medians


def plot(report, path: Path, beside_load: bool = True) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (rss, goals) = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    times = [t / 60 for t, _ in report.rss_timeline]
    for name in NODES:
        values = [sample.get(name, float("nan")) for _, sample in report.rss_timeline]
        rss.plot(times, values, label=name)
    rss.set_ylabel("resident memory (MiB)")
    where = "beside the load harness" if beside_load else "without the load harness"
    rss.set_title(f"Soak {where}: {len(report.goals)} goals, {len(report.failures)} missed their outcome")
    rss.legend(loc="center right")
    colours = {"grasp pinch": "tab:blue", "manipulate horizontal": "tab:green",
               "manipulate vertical, cancelled": "tab:orange", "gripper open": "tab:purple"}
    for name, colour in colours.items():
        done = [g for g in report.goals if g.name == name]
        goals.scatter([g.started_s / 60 for g in done if g.as_expected], [g.seconds for g in done if g.as_expected],
                      s=8, color=colour, label=f"{name}: {sum(g.as_expected for g in done)}/{len(done)} as expected")
        missed = [g for g in done if not g.as_expected]
        goals.scatter([g.started_s / 60 for g in missed], [g.seconds for g in missed], s=40, marker="x", color="red")
    goals.set_xlabel("minutes")
    goals.set_ylabel("goal duration (s)")
    goals.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    tmp = path.with_name(path.name + ".partial.png")
    fig.savefig(tmp, dpi=90)
    plt.close(fig)
    tmp.replace(path)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=20.0, help="how long to send goals (default 20)")
    parser.add_argument("--out", type=Path, default=Path("soak_out"), help="where soak.json goes")
    parser.add_argument("--plot", type=Path, help="write the plot (PNG) here")
    parser.add_argument("--no-load", action="store_true", help="without the load harness")
    parser.add_argument("--rt-priority", type=int, default=CONTROL_PATH_RT_PRIORITY,
                        help=f"hand.launch.py rt_priority (default {CONTROL_PATH_RT_PRIORITY}; 0: none, the nodes "
                             "at its nice)")
    args = parser.parse_args(argv)
    if args.minutes <= 0:
        parser.error(f"--minutes {args.minutes}: must be > 0")
    if not 0 <= args.rt_priority <= 99:
        parser.error(f"--rt-priority {args.rt_priority}: SCHED_FIFO priorities are 1-99 (0: none)")
    from prisma_testing.goal_soak import node_pids, run_soak
    from prisma_testing.load_harness import machine_load
    from prisma_testing.node_process import ros2_launch, stop_process
    from prisma_testing.ros_harness import ROS_AVAILABLE, ROS_IMPORT_ERROR, RosHarness

    if not ROS_AVAILABLE:
        print(f"skipped: {ROS_IMPORT_ERROR}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    os.environ.setdefault("ROS_DOMAIN_ID", str(101 + os.getpid() % 130))  # this soak's graph only
    ros = RosHarness()
    ros.capture_logs()
    hand = ros2_launch("prisma_bringup", "hand.launch.py", "sim:=true", f"rt_priority:={args.rt_priority}")
    try:
        pids = node_pids(hand.proc.pid, NODES)
        if set(pids) != set(NODES):
            print(f"the graph did not start: {sorted(set(NODES) - set(pids))} missing\n{hand.output[-3000:]}",
                  file=sys.stderr)
            return 1
        started = time.strftime("%Y-%m-%d %H:%M:%S")
        if args.no_load:
            report = run_soak(ros, pids, args.minutes * 60)
        else:
            with machine_load() as hogs:
                print(f"load harness: {len(hogs)} hogs", flush=True)
                report = run_soak(ros, pids, args.minutes * 60)
    finally:
        stop_process(hand)
        ros.shutdown()
    summary = {"started": started, "load": not args.no_load, "rt_priority": args.rt_priority,
               "loadavg_end": os.getloadavg(), **report.summary(),
               "median_s_first_and_last_minute": minute_medians(report)}
    tmp = args.out / "soak.json.partial"
    goals = [[g.name, *g.outcome, round(g.seconds, 4), round(g.started_s, 2)] for g in report.goals]
    tmp.write_text(json.dumps({**summary, "rss_timeline": report.rss_timeline, "goal_records": goals}, indent=1))
    tmp.replace(args.out / "soak.json")  # whole or not at all
    print(json.dumps(summary, indent=1))
    if args.plot:
        plot(report, args.plot, beside_load=not args.no_load)
        print(f"wrote {args.plot}")
    grew = {n: g for n, g in report.rss_growth_mb.items() if g >= MAX_RSS_GROWTH_MB}
    return 1 if report.failures or report.refused_replacements or report.dead or grew else 0


if __name__ == "__main__":
    sys.exit(main())
