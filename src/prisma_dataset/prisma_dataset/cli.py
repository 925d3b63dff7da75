"""prisma-dataset: bags of demonstrations as a LeRobot v3.0 dataset (export), and a look at one (show).

    prisma-dataset export BAG... --out DIR [--whole-bag] [--fps 50] [--task TEXT] [--action targets|positions]
                          [--namespace NS] [--append]
    prisma-dataset topics [--namespace NS]
    prisma-dataset show DIR [--episode N] [--plots DIR | --no-plots]
    prisma-dataset replay DIR --episode N [--namespace NS] [--speed F] [--plots DIR | --no-plots]

docs/dataset_replay.md: how a replay plays an episode into a running hand and what it compares.

export: one episode per span the teleop node marked (prisma/teleop/episode), its task and outcome
the markers'; --whole-bag: one episode per bag. topics: what a recording for export needs.
docs/datasets.md: the features, the sampling rule, the invariants and the tests that check them.
Exit status: 0; 1 when `show` finds a broken invariant or a replay misses its tolerances; 2 for a
mistake in the command or its input, or a replay with no hand to play into (one line, no traceback).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from prisma_common.cli_args import (
    ArgumentParser,
    UserError,
    check_replaceable_dir,
    command,
    existing_dir,
    existing_path,
    non_negative_int,
    output_dir,
    positive_float,
    positive_int,
    ros_namespace,
)

PROG = "prisma-dataset"
DEFAULT_PLOTS = Path("prisma_dataset_plots")
# what a dataset directory written by export holds: an export may replace only that
DATASET_ENTRIES = ("meta", "data")


def _task(text: str) -> str:
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty task; describe what the demonstrations do, e.g. "
                                         "'pinch the ball'")
    return text


def parser() -> ArgumentParser:
    top = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    commands = top.add_subparsers(dest="command", required=True, metavar="{export,show,topics,replay}")
    export = commands.add_parser("export", help="bags -> one LeRobot v3.0 dataset",
                                 description="Export bags as one LeRobot v3.0 dataset, one episode per marked "
                                             "span (the teleop node's episode markers) or per bag (--whole-bag); "
                                             "the dataset is written whole or not at all.")
    export.add_argument("bags", nargs="+", type=existing_path, metavar="BAG",
                        help="recorded bags (directories or .mcap files)")
    export.add_argument("--out", type=output_dir, required=True, metavar="DIR",
                        help="the dataset directory (new, empty, or with --append an existing dataset)")
    export.add_argument("--fps", type=positive_int, default=50, help="frames per second of the grid (default 50)")
    export.add_argument("--whole-bag", action="store_true",
                        help="one episode per bag, whatever markers it holds (a bag recorded without them)")
    export.add_argument("--task", type=_task, default=None,
                        help="every episode's task text (default: the markers' task; with --whole-bag "
                             "'teleoperate the PRISMA hand')")
    export.add_argument("--namespace", type=ros_namespace, default="", metavar="NS",
                        help="the hand's namespace the bags were recorded in (default: none)")
    export.add_argument("--action", choices=("targets", "positions"), default="targets",
                        help="targets: /prisma/teleop/motor_targets (default); positions: the next frame's "
                             "motor positions, for bags without teleoperation")
    export.add_argument("--append", action="store_true", help="add the episodes to the dataset at --out")
    show = commands.add_parser("show", help="summary, invariant check and plots of a dataset",
                               description="Print a dataset's summary and invariant check; plot each episode.")
    show.add_argument("dataset", type=existing_dir, metavar="DIR", help="a LeRobot v3.0 dataset directory")
    show.add_argument("--episode", type=non_negative_int, default=None, metavar="N", help="only episode N")
    show.add_argument("--plots", type=output_dir, default=DEFAULT_PLOTS, metavar="DIR",
                      help=f"where the episode PNGs go (default {DEFAULT_PLOTS})")
    show.add_argument("--no-plots", action="store_true", help="print the summary only")
    listing = commands.add_parser("topics", help="the topics a recording for export needs, one a line",
                                  description="Print the topics an export reads (record.launch.py records them).")
    listing.add_argument("--namespace", type=ros_namespace, default="", metavar="NS",
                         help="the hand's namespace (default: none)")
    show.add_argument("--touch-limit", type=positive_float, default=None, metavar="N",
                      help="the touch limit drawn with the forces (default: the manipulation node's "
                           "teleop_max_pad_force, 2 N)")
    _replay_parser(commands)
    return top


def _replay_parser(commands) -> None:
    replay = commands.add_parser(
        "replay", help="play an episode's actions into a running hand and compare",
        description="Play an episode's actions into a running hand (sim or emulated) through the Teleoperate goal, "
                    "as the teleop node does, and compare the replay's pad forces and motor positions with the "
                    "recording; exit 1 when a tolerance is missed (docs/dataset_replay.md).")
    replay.add_argument("dataset", type=existing_dir, metavar="DIR", help="a LeRobot v3.0 dataset directory")
    replay.add_argument("--episode", type=non_negative_int, required=True, metavar="N", help="the episode to play")
    replay.add_argument("--namespace", type=ros_namespace, default="", metavar="NS",
                        help="the hand's namespace, as namespace:= of hand.launch.py (default: none)")
    replay.add_argument("--speed", type=positive_float, default=1.0, metavar="F",
                        help="pace against the recording's (default 1; 0.5 = half as fast; 0.05 .. 4)")
    replay.add_argument("--wait", type=positive_float, default=10.0, metavar="S",
                        help="how long to wait for the hand's Teleoperate server and goal (default 10 s)")
    replay.add_argument("--plots", type=output_dir, default=DEFAULT_PLOTS, metavar="DIR",
                        help=f"where the comparison PNG goes (default {DEFAULT_PLOTS})")
    replay.add_argument("--no-plots", action="store_true", help="print the comparison only")
    replay.add_argument("--touch-limit", type=positive_float, default=None, metavar="N",
                        help="the touch limit the pads may not pass (default: the manipulation node's "
                             "teleop_max_pad_force, 2 N)")
    replay.add_argument("--force-tolerance", type=positive_float, default=None, metavar="N",
                        help="largest |replayed - recorded| pad force at a matched frame (default 0.2 N)")
    replay.add_argument("--overshoot", type=positive_float, default=None, metavar="N",
                        help="how far a pad may pass the touch limit (default 0.15 N)")
    replay.add_argument("--position-tolerance", type=positive_float, default=None, metavar="RAD",
                        help="largest position RMS of a motor (default 0.15 rad)")


@command(PROG, "prisma_common.bag:BagError", "prisma_dataset.bag_export:ExportError",
         "prisma_dataset.lerobot_format:DatasetFormatError", "prisma_dataset.replay_plan:ReplayError")
def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    if args.command == "topics":
        from .recorded_topics import record_topics

        print("\n".join(record_topics(args.namespace)))
        return 0
    if args.command == "replay":
        return replay_command(args)
    return export_command(args) if args.command == "export" else show_command(args)


def _check_out(out: Path, append: bool) -> None:
    has_info = (out / "meta" / "info.json").is_file()
    if append:
        if not has_info:
            raise UserError(f"--append --out {out}: no dataset there (no meta/info.json); drop --append to "
                            f"write a new one")
        check_replaceable_dir(out, DATASET_ENTRIES, "a LeRobot dataset", "--out")
        return
    if has_info:
        raise UserError(f"--out {out} already holds a dataset; add --append to add episodes to it, or give a "
                        f"new directory")
    check_replaceable_dir(out, (), "a LeRobot dataset", "--out")


def export_command(args: argparse.Namespace) -> int:
    from .bag_export import ExportOptions, export_bags
    from .dataset_check import require_valid
    from .dataset_summary import summary_lines
    from .lerobot_format import append_episodes, read_dataset, write_dataset

    _check_out(args.out, args.append)
    options = ExportOptions(fps=args.fps, task=args.task, action=args.action, whole_bag=args.whole_bag,
                            namespace=args.namespace)
    existing = read_dataset(args.out) if args.append else None
    if existing is not None and existing.fps != args.fps:
        raise UserError(f"--append: the dataset at {args.out} is at {existing.fps} fps; export with "
                        f"--fps {existing.fps}")
    dataset = export_bags(args.bags, options, progress=print)
    if existing is not None:
        dataset = append_episodes(existing, dataset)
    write_dataset(args.out, dataset)
    report = require_valid(args.out)
    print("\n".join(summary_lines(report)))
    return 0


def show_command(args: argparse.Namespace) -> int:
    from .dataset_check import check_dataset
    from .dataset_summary import DEFAULT_TOUCH_LIMIT_N, episode_numbers, has_plot_features, plot_episode, summary_lines

    root: Path = args.dataset
    if not (root / "meta" / "info.json").is_file():
        raise UserError(f"{root} is not a LeRobot dataset (no meta/info.json); give the directory "
                        f"prisma-dataset export --out wrote")
    report = check_dataset(root)
    numbers = episode_numbers(report, args.episode)
    if args.episode is not None and not numbers:
        raise UserError(f"--episode {args.episode}: the dataset has episodes 0 .. {len(report.episodes) - 1}")
    print("\n".join(summary_lines(report, args.episode)))
    if args.no_plots:
        pass
    elif not report.ok:
        print("  no plots: the dataset breaks the invariants above")
    elif not has_plot_features(report):
        print("  no plots: the dataset lacks observation.state, observation.wrench or action")
    else:
        for number in numbers:
            limit = DEFAULT_TOUCH_LIMIT_N if args.touch_limit is None else args.touch_limit
            path = plot_episode(report, number, args.plots / f"episode_{number:03d}.png", limit)
            print(f"  plot: {path}")
    return 0 if report.ok else 1


def replay_command(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from .dataset_summary import DEFAULT_TOUCH_LIMIT_N
    from .replay_compare import Tolerances, compare, plot_comparison, report_lines
    from .replay_plan import ReplayCore, ReplayOptions, load_episode

    root: Path = args.dataset
    if not (root / "meta" / "info.json").is_file():
        raise UserError(f"{root} is not a LeRobot dataset (no meta/info.json); give the directory "
                        f"prisma-dataset export --out wrote")
    episode = load_episode(root, args.episode)  # ReplayError for a number out of range: before any ROS
    tolerances = Tolerances(touch_limit_n=DEFAULT_TOUCH_LIMIT_N if args.touch_limit is None else args.touch_limit)
    given = {"force_tolerance_n": args.force_tolerance, "overshoot_n": args.overshoot,
             "position_tolerance_rad": args.position_tolerance}
    tolerances = replace(tolerances, **{k: v for k, v in given.items() if v is not None})
    core = ReplayCore(episode, ReplayOptions(speed=args.speed))
    try:
        from .replay_ros import run_replay
    except ImportError as exc:
        raise UserError(f"replay needs ROS 2 (rclpy, prisma_msgs): {exc}; source the ROS setup and the "
                        f"workspace's install/setup.bash") from None
    print(f"replaying episode {episode.number} of {root} ({episode.frames} frames at {episode.fps} fps, speed "
          f"{args.speed:g}, task {episode.task!r}) into the hand{f' /{args.namespace}' if args.namespace else ''}")
    recording = run_replay(core, args.namespace, args.wait)
    comparison = compare(episode, recording, tolerances, core.period_ns)
    print("\n".join(report_lines(comparison, recording)))
    if not args.no_plots:
        path = plot_comparison(episode, comparison, args.plots / f"replay_episode_{episode.number:03d}.png")
        print(f"  plot: {path}")
    return 0 if comparison.ok else 1
