"""prisma-policy: learn a behaviour-cloning policy from a LeRobot dataset (train), try it in the sim (eval).

    prisma-policy train DIR --out MODEL.pt [--steps 3000] [--hidden 128] [--seed 0]
    prisma-policy eval MODEL.pt [--trials 10] [--seed 0] [--plot prisma_policy_eval.png]

docs/policy.md: the observation and action, the network, the trials and the numbers.
Exit status: 0; 2 for a mistake in the command or its input (one line, no traceback).
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from prisma_common.cli_args import (
    ArgumentParser,
    UserError,
    check_bundle_dir,
    command,
    existing_dir,
    existing_file,
    non_negative_int,
    output_file,
    positive_float,
    positive_int,
)
from prisma_force_estimator.force_estimator_core import load_estimator

PROG = "prisma-policy"
DEFAULT_BUNDLE = Path("config/models/cnn2")  # the force estimator the sim hand and prisma-sim use
DEFAULT_PLOT = Path("prisma_policy_eval.png")


def parser() -> ArgumentParser:
    top = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    commands = top.add_subparsers(dest="command", required=True, metavar="{train,eval}")
    train = commands.add_parser("train", help="learn a policy from a dataset",
                                description="Learn a behaviour-cloning policy (tactile, wrench, state -> action) "
                                            "from a LeRobot v3.0 dataset; the model file is written whole or not "
                                            "at all.")
    train.add_argument("dataset", type=existing_dir, metavar="DIR", help="a LeRobot v3.0 dataset (prisma-dataset "
                                                                         "export, prisma-sim --dataset)")
    train.add_argument("--out", type=output_file(".pt"), required=True, metavar="MODEL",
                       help="the model file to write (.pt)")
    # defaults: bc_policy.TrainConfig's (not imported here: --help stays light)
    train.add_argument("--steps", type=positive_int, default=None, help="training steps (default 3000)")
    train.add_argument("--hidden", type=positive_int, default=None, help="units per hidden layer (default 128)")
    train.add_argument("--seed", type=non_negative_int, default=None, help="seed (default 0)")
    evaluate = commands.add_parser("eval", help="try a policy in the sim beside the scripted Grasp",
                                   description="Run the policy in the closed-loop sim through the Teleoperate goal "
                                               "on balls it was not shown, and the scripted Grasp on the same balls.")
    evaluate.add_argument("model", type=existing_file, metavar="MODEL", help="a model prisma-policy train wrote")
    evaluate.add_argument("--trials", type=positive_int, default=10, help="trials, one ball each (default 10)")
    evaluate.add_argument("--seed", type=non_negative_int, default=0, help="seed of the balls (default 0)")
    evaluate.add_argument("--duration", type=positive_float, default=None, metavar="S",
                          help="seconds per trial (default 5)")
    evaluate.add_argument("--bundle", type=Path, default=DEFAULT_BUNDLE,
                          help=f"force estimator bundle of the sim hand (default {DEFAULT_BUNDLE})")
    evaluate.add_argument("--plot", type=output_file(".png"), default=DEFAULT_PLOT, metavar="PNG",
                          help=f"the forces of every trial (default {DEFAULT_PLOT})")
    return top


@command(PROG, "prisma_policy.bc_policy:PolicyError", "prisma_dataset.lerobot_format:DatasetFormatError",
         "prisma_force_estimator.bundle:BundleError")
def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    return train_command(args) if args.command == "train" else eval_command(args)


def train_command(args: argparse.Namespace) -> int:
    from .bc_policy import TrainConfig, evaluate_loss, load_training_set, save, train

    root: Path = args.dataset
    if not (root / "meta" / "info.json").is_file():
        raise UserError(f"{root} is not a LeRobot dataset (no meta/info.json); give the directory prisma-dataset "
                        f"export --out or prisma-sim --dataset wrote")
    started = time.perf_counter()
    data = load_training_set(root)
    print(f"dataset {root}: {data.episodes} episodes, {len(data.inputs)} frames at {data.fps} fps "
          f"(closing and holding; {data.idle_frames} more left out: the operator at rest or letting go); "
          f"{data.inputs.shape[1]} inputs -> {data.actions.shape[1]} motor targets", flush=True)
    given = {"hidden": args.hidden, "steps": args.steps, "seed": args.seed}
    config = TrainConfig(**{name: value for name, value in given.items() if value is not None})
    policy = train(data, config, progress=lambda step, loss: print(f"  step {step}/{config.steps}: loss {loss:.4f}",
                                                                   flush=True))
    save(policy, args.out)
    print(f"trained in {time.perf_counter() - started:.1f} s; loss over every frame {evaluate_loss(policy, data):.4f} "
          f"(normalised action, MSE; first 100 steps {policy.losses[0]:.4f}); model {args.out}")
    return 0


def eval_command(args: argparse.Namespace) -> int:
    from .bc_policy import load
    from .sim_trials import TRIAL_S, plot, run_trials, table

    policy = load(args.model)
    check_bundle_dir(args.bundle)
    estimator = load_estimator(args.bundle, threads=1)
    shown = ", ".join(f"{k} {v[0]:g}..{v[1]:g}" for k, v in policy.shown.items()) or "not recorded in the model"
    print(f"policy {args.model}: trained on {policy.episodes} episodes; balls shown: {shown}", flush=True)
    started = time.perf_counter()
    results = run_trials(policy, estimator, args.trials, args.seed, args.duration or TRIAL_S,
                         progress=lambda line: print(line, flush=True))
    print()
    print(table(results))
    path = plot(results, args.plot)
    print(f"{args.trials} trial(s) in {time.perf_counter() - started:.1f} s; plot {path}")
    return 0
