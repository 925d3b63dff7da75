"""What the stag-* command lines share: the dataset options and the loading (a file read and found
fit for the command before torch is imported, or the synthetic glove), the training options, the
outputs (JSON and model bundles, whole or not at all) and the command line a result records.
"""
from __future__ import annotations

import argparse
import json
import shlex
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from prisma_common.atomic import atomic_output
from prisma_common.cli_args import (
    ArgumentParser,
    UserError,
    check_bundle_out,
    existing_file,
    non_negative_float,
    non_negative_int,
    output_file,
    positive_int,
)

if TYPE_CHECKING:
    from .dataset import GloveDataset

DATASET_SUFFIXES = (".mat", ".h5", ".hdf5")


def limit_threads(threads: int) -> None:
    from .glove_perception_core import limit_threads as limit

    limit(threads)


def command_line(argv: list[str] | None, prog: str) -> str:
    """The command line as run, less --out-json (where the numbers went is no part of the recipe)."""
    args = list(sys.argv[1:] if argv is None else argv)
    if "--out-json" in args:
        i = args.index("--out-json")
        del args[i:i + 2]
    return " ".join([prog] + [shlex.quote(a) for a in args])


def add_data_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--dataset", type=existing_file,
                        help="metadata.mat (MATLAB v5/v7.3) or .h5; default: synthetic")
    parser.add_argument("--synthetic-seed", type=non_negative_int, default=0,
                        help="seed of the synthetic glove (no --dataset)")
    parser.add_argument("--threads", type=positive_int, default=1, help="torch/BLAS threads (default 1)")
    parser.add_argument("--out-json", type=output_file(), help="write the numbers here")


def add_train_args(parser: argparse.ArgumentParser, epochs: int, lr_step: int) -> None:
    parser.add_argument("--width", type=positive_int, default=16, help="trunk width (paper: 64)")
    parser.add_argument("--epochs", type=positive_int, default=epochs)
    parser.add_argument("--lr-step", type=positive_int, default=lr_step,
                        help="x0.1 learning rate every this many epochs (paper: 100)")
    parser.add_argument("--batch-size", type=positive_int, default=32)
    parser.add_argument("--noise", type=non_negative_float, default=0.015, help="Gaussian noise on training inputs")


def add_bundle_out(parser: argparse.ArgumentParser, help: str) -> None:
    parser.add_argument("--bundle-out", type=Path,
                        help=help + " (an earlier bundle there is replaced, any other existing path refused)")


def check_outputs(args) -> None:
    """Before the (long) training: --bundle-out must be new, empty or an earlier bundle."""
    if getattr(args, "bundle_out", None) is not None:
        check_bundle_out(args.bundle_out, "--bundle-out")


def training_parser(prog: str, description: str, epochs: int, lr_step: int) -> ArgumentParser:
    """A training command's parser: the data and training arguments, with its epochs and lr step."""
    parser = ArgumentParser(prog=prog, description=description)
    add_data_args(parser)
    add_train_args(parser, epochs=epochs, lr_step=lr_step)
    return parser


def write_bundle(path: Path, kind: str, model, metadata: dict) -> None:
    """The bundle, its metadata with the normalisation the training frames had (normalise's range)."""
    from .bundle import save_bundle
    from .processing import NormalisationConfig

    metadata = {**metadata, "normalisation": {"low": NormalisationConfig.low, "high": NormalisationConfig.high}}
    with atomic_output(path) as staged:  # whole or not at all
        save_bundle(staged, kind, model, metadata)
    print(f"wrote bundle {path}")


def train_config(args, seed: int = 0):
    from .training import TrainConfig

    return TrainConfig(width=args.width, epochs=args.epochs, lr_step_epochs=args.lr_step, batch_size=args.batch_size,
                       noise_std=args.noise, seed=seed, threads=args.threads)


def synthetic_dataset(kind: str, seed: int) -> tuple[GloveDataset, str]:
    from .synthetic import SyntheticConfig, SyntheticGlove

    glove = SyntheticGlove(SyntheticConfig(seed=seed))
    ds = {"object": glove.object_dataset, "pose": glove.pose_dataset, "weight": glove.weight_dataset}[kind]()
    return ds, f"synthetic glove, seed {seed}, {kind} set ({len(ds)} frames)"


def load_data(args, kind: str,
          check: Callable[[GloveDataset, str], None] | None = None) -> tuple[GloveDataset, str]:
    """The dataset, with the thread limit applied before any heavy work (the synthetic glove's
    generation included). A file is read, and `check` finds it fit for the command (UserError
    otherwise), before torch is imported."""
    if args.dataset is not None:
        from .dataset import load_dataset

        try:
            ds = load_dataset(args.dataset)
        except (ValueError, OSError) as exc:  # not a STAG dataset file: the message says why
            raise UserError(f"--dataset {args.dataset}: {exc}; give a metadata.mat (MATLAB v5 or v7.3) "
                            f"or an .h5 written by stag-make-dataset") from None
        if check is not None:
            check(ds, str(args.dataset))
        limit_threads(args.threads)
        return ds, str(args.dataset)
    limit_threads(args.threads)
    return synthetic_dataset(kind, args.synthetic_seed)


def splits_check(balanced: bool) -> Callable[[GloveDataset, str], None]:
    """The held-out-session experiments need valid (and, for anchors, balanced) frames in both splits."""

    def check(ds: GloveDataset, source: str) -> None:
        from .dataset import SPLIT_TEST, SPLIT_TRAIN

        anchor = ds.is_balanced if balanced else np.ones(len(ds), bool)
        counts = [int(np.sum(ds.has_valid_label & anchor & (ds.split_id == split))) for split in (SPLIT_TRAIN,
                                                                                                   SPLIT_TEST)]
        if not all(counts):
            raise UserError(f"--dataset {source}: needs valid{' balanced' if balanced else ''} frames in both "
                            f"splits (splitId 0 = train, 1 = test), has {counts[0]} and {counts[1]}")
    return check


def weights_check(ds: GloveDataset, source: str) -> None:
    if ds.weights_g is None:
        raise UserError(f"--dataset {source}: no per-object weights ('weights' field); give the STAG weights set")
    if len(np.unique(ds.object_id)) < 2:
        raise UserError(f"--dataset {source}: frames of {len(np.unique(ds.object_id))} object(s); "
                        f"leave-one-object-out needs at least 2")


def recording_check(ds: GloveDataset, source: str) -> None:
    if len(ds) < 2:
        raise UserError(f"--dataset {source}: {len(ds)} frame(s); the correlation needs a recording")


def write_json(path: Path | None, data: dict) -> None:
    if path is not None:
        with atomic_output(path) as staged:
            staged.write_text(json.dumps(data, indent=2) + "\n")
        print(f"wrote {path}")


def frames_arg(text: str) -> list[int]:
    """'1-8' or '1,2,4' (or a mix): the frame counts N."""
    out: list[int] = []
    try:
        for part in text.split(","):
            if "-" in part:
                lo, hi = part.split("-")
                out += list(range(int(lo), int(hi) + 1))
            else:
                out.append(int(part))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a list of frame counts; give e.g. 1-8 or 1,2,4") \
            from None
    if not out or min(out) < 1:
        raise argparse.ArgumentTypeError(f"frame counts must be >= 1, got {text!r}")
    return out


def folds_arg(text: str) -> int | None:
    """'all' -> None, or a positive count."""
    if text == "all":
        return None
    try:
        return positive_int(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"{text!r} is neither 'all' nor a whole number >= 1 of objects to "
                                         f"hold out") from None

