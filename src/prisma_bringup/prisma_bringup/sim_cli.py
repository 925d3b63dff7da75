"""prisma-sim: the paper's experiments in closed loop, off the robot, recorded as ROS 2 bags.

    prisma-sim                          # every scenario into ./prisma_sim_out
    prisma-sim --scenarios horizontal vertical --out /tmp/sim
    prisma-sim --short                  # the quick configuration the tests use
    prisma-sim --list

Each scenario writes <out>/bags/<scenario>/ (MCAP; `ros2 bag play` it, or open it with rosbags or
mcap_ros2), <out>/<scenario>.png, and a line in <out>/summary.md and summary.json. Exit status 1
when a scenario ends for another reason than the paper's.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from .sim_runner import EXPECTED_REASONS, SimOptions, markdown, run, scenario_names


def main(argv: list[str] | None = None) -> int:
    names = scenario_names()
    parser = argparse.ArgumentParser(prog="prisma-sim", description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="scenarios: " + ", ".join(names))
    parser.add_argument("--out", type=Path, default=Path("prisma_sim_out"), help="output directory")
    parser.add_argument("--scenarios", nargs="+", choices=names, metavar="NAME", default=list(names),
                        help="scenarios to run (default: all)")
    parser.add_argument("--short", action="store_true",
                        help="quick configuration (the tests): glove session with 2 objects")
    parser.add_argument("--glove-objects", type=int, default=None, help="objects grasped in the glove session (4)")
    parser.add_argument("--bundle", default="config/models/cnn2", help="force-estimator bundle directory")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    parser.add_argument("--list", action="store_true", help="list the scenarios and exit")
    args = parser.parse_args(argv)
    if args.list:
        from .hand_session import HAND_SCENARIOS

        for name in names:
            text = HAND_SCENARIOS[name].description if name in HAND_SCENARIOS else (
                "STAG glove: empty-hand capture, then grasps of synthetic objects through the driver and "
                "perception cores")
            print(f"{name:<14} expects {EXPECTED_REASONS[name]:<16} {text}")
        return 0
    glove_objects = args.glove_objects if args.glove_objects is not None else (2 if args.short else 4)
    if glove_objects < 1:
        parser.error(f"--glove-objects must be >= 1, got {glove_objects}")
    options = SimOptions(out=args.out, scenarios=list(dict.fromkeys(args.scenarios)), bundle=args.bundle,
                         glove_objects=glove_objects, plots=not args.no_plots)
    started = time.perf_counter()
    try:
        summaries = run(options, progress=lambda line: print(line, flush=True))
    except (OSError, ValueError) as exc:  # an output path in the way, a missing or mismatched bundle
        print(f"prisma-sim: error: {exc}", file=sys.stderr)
        return 2
    print()
    print(markdown(summaries))
    print(f"{len(summaries)} scenario(s) in {time.perf_counter() - started:.1f} s; "
          f"bags, plots and summary.md/json in {options.out}")
    failed = [s["scenario"] for s in summaries if not s["as_expected"]]
    if failed:
        print(f"not as expected: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
