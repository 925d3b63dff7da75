"""prisma-sim: the paper's experiments in closed loop, off the robot, recorded as ROS 2 bags.

    prisma-sim                          # every scenario into ./prisma_sim_out
    prisma-sim --scenarios horizontal vertical --out /tmp/sim
    prisma-sim --short                  # the quick configuration the tests use
    prisma-sim --list
    prisma-sim --dataset DIR --episodes 20 [--seed 0]   # teleop demonstrations as a LeRobot v3.0 dataset

Each scenario writes <out>/bags/<scenario>/ (MCAP; `ros2 bag play` it, or open it with rosbags or
mcap_ros2), <out>/<scenario>.png, and a line in <out>/summary.md and summary.json, which also name
the force estimator bundle used. <out> is written whole when the run ends and replaces an earlier
run's output; a directory holding anything else is refused. Exit status 1 when a scenario ends for
another reason than the paper's, or misses one of its force set points (a grasp's finger or thumb
force, the combined hold's thumb force) by more than the force tolerance, 0.15 N by default, in
the estimated or the true force.

With --dataset, the teleop session runs --episodes times with the operator, the ball and the speed
varied (seeded: `prisma_sim.demonstrations`) and is written as one LeRobot v3.0 dataset at DIR
(new or empty), whole or not at all; no bags, plots or summary are kept.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from prisma_common.cli_args import (
    ArgumentParser,
    UserError,
    check_bundle_dir,
    check_replaceable_dir,
    command,
    non_negative_int,
    output_dir,
    positive_float,
    positive_int,
)

from .sim_runner import (
    EXPECTED_REASONS,
    FORCE_TOLERANCE_N,
    GLOVE,
    TELEOP,
    SimOptions,
    check_out,
    failures,
    markdown,
    run,
    scenario_names,
)

DEFAULT_BUNDLE = "config/models/cnn2"
DEFAULT_EPISODES = 20


@command("prisma-sim", "prisma_force_estimator.bundle:BundleError")
def main(argv: list[str] | None = None) -> int:
    names = scenario_names()
    parser = ArgumentParser(prog="prisma-sim", description=__doc__.splitlines()[0],
                            formatter_class=argparse.RawDescriptionHelpFormatter,
                            epilog="scenarios: " + ", ".join(names))
    parser.add_argument("--out", type=output_dir, default=Path("prisma_sim_out"),
                        help="output directory, replaced as a whole by the run (default prisma_sim_out)")
    parser.add_argument("--scenarios", nargs="+", choices=names, metavar="NAME", default=list(names),
                        help="scenarios to run (default: all)")
    parser.add_argument("--short", action="store_true",
                        help="quick configuration (the tests): glove session with 2 objects")
    parser.add_argument("--glove-objects", type=positive_int, default=None,
                        help="objects grasped in the glove session (4)")
    parser.add_argument("--bundle", type=Path, default=Path(DEFAULT_BUNDLE),
                        help=f"force-estimator bundle directory (default {DEFAULT_BUNDLE})")
    parser.add_argument("--force-tolerance", type=positive_float, default=FORCE_TOLERANCE_N, metavar="N",
                        help="largest allowed miss of a force set point in newtons, estimated or true "
                             f"(default {FORCE_TOLERANCE_N:g}: about twice the grasp's measured overshoot); "
                             "a larger miss makes the run exit 1")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    parser.add_argument("--list", action="store_true", help="list the scenarios and exit")
    parser.add_argument("--dataset", type=output_dir, default=None, metavar="DIR",
                        help="run the teleop session --episodes times, varied, into one LeRobot v3.0 dataset at DIR "
                             "(new or empty) instead of the scenarios")
    parser.add_argument("--episodes", type=positive_int, default=None, metavar="N",
                        help=f"demonstrations in the --dataset (default {DEFAULT_EPISODES})")
    parser.add_argument("--seed", type=non_negative_int, default=0,
                        help="seed of the demonstrations' operator, ball and speed (default 0)")
    args = parser.parse_args(argv)
    if args.dataset is not None:
        return dataset_command(args)
    if args.episodes is not None:
        raise UserError(f"--episodes {args.episodes} needs --dataset DIR: the directory the demonstrations go to")
    if args.list:
        from .hand_session import HAND_SCENARIOS
        from .teleop_session import DESCRIPTION

        for name in names:
            text = HAND_SCENARIOS[name].description if name in HAND_SCENARIOS else DESCRIPTION if name == TELEOP else (
                "STAG glove: empty-hand capture, then grasps of synthetic objects through the driver and "
                "perception cores")
            print(f"{name:<14} expects {EXPECTED_REASONS[name]:<16} {text}")
        return 0
    glove_objects = args.glove_objects if args.glove_objects is not None else (2 if args.short else 4)
    scenarios = list(dict.fromkeys(args.scenarios))
    # everything that can be wrong with the command line is found before the first scenario runs
    try:
        check_out(args.out)
    except FileExistsError as exc:
        raise UserError(f"--out {exc}") from None
    estimator = None
    if any(name != GLOVE for name in scenarios):
        from .sim_runner import load_estimator

        check_bundle_dir(args.bundle)
        estimator = load_estimator(args.bundle)  # BundleError names the path and the problem
    options = SimOptions(out=args.out, scenarios=scenarios, bundle=str(args.bundle),
                         glove_objects=glove_objects, plots=not args.no_plots,
                         force_tolerance_n=args.force_tolerance)
    started = time.perf_counter()
    summaries = run(options, progress=lambda line: print(line, flush=True), estimator=estimator)
    print()
    print(markdown(summaries))
    print(f"{len(summaries)} scenario(s) in {time.perf_counter() - started:.1f} s; "
          f"bags, plots and summary.md/json in {options.out}")
    failed = failures(summaries)
    if failed:
        for line in failed:
            print(f"prisma-sim: not as expected: {line}", file=sys.stderr)
        return 1
    return 0


def dataset_command(args: argparse.Namespace) -> int:
    """--dataset: the demonstrations, the dataset's summary and how long it took."""
    out: Path = args.dataset
    if (out / "meta" / "info.json").is_file():
        raise UserError(f"--dataset {out} already holds a dataset; give a new directory (prisma-dataset export "
                        f"--append adds bags to one)")
    check_replaceable_dir(out, (), "a LeRobot dataset", "--dataset")
    check_bundle_dir(args.bundle)
    from .demonstrations import record_dataset
    from .sim_runner import load_estimator

    started = time.perf_counter()
    estimator = load_estimator(args.bundle)
    episodes = args.episodes or DEFAULT_EPISODES
    run = record_dataset(out, episodes, args.seed, estimator, progress=lambda line: print(line, flush=True))
    print()
    print("\n".join(run.summary()))
    print(f"{episodes} demonstration(s) (seed {args.seed}) in {time.perf_counter() - started:.1f} s: sessions "
          f"{run.sessions_s:.1f} s, export {run.export_s:.1f} s; dataset in {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
