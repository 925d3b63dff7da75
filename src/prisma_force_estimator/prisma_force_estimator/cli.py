"""Console scripts: prisma-train-force, prisma-eval-force, prisma-estimate-bag.

Every argument and input file is checked before torch is imported or any data is generated (exit
2 with a one-line message); bundles, bags, plots, tables and JSON are written under a temporary
name and renamed when complete.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from prisma_common.atomic import atomic_output
from prisma_common.bag import BagError, MissingTopicsError, require_topics
from prisma_common.cli_args import (
    ArgumentParser,
    UserError,
    check_bundle_dir,
    check_bundle_out,
    command,
    existing_path,
    fraction,
    new_path,
    non_negative_float,
    non_negative_int,
    output_dir,
    output_file,
    positive_float,
    positive_int,
    unit_interval,
)
from prisma_common.hand import FINGERS
from prisma_common.topics import TAXELS, WRENCH
from prisma_common.typestore import types
from prisma_hand_sim.calibration import CalibrationSet

from .bundle import DEFAULT_PRECISION, PRECISIONS  # bundle.py imports torch only to load a network

# networks.MODEL_KINDS, spelled out so that building the parser does not import torch
# (test/integration/test_cli_bad_input.py checks that they agree).
MODEL_CHOICES = ("ann", "cnn", "cnn_t", "cnn2")
BAG_SUFFIXES = (".mcap", ".db3")
# The user errors of the loaders these commands call, counted once their module is loaded.
LOADER_ERRORS = ("prisma_force_estimator.bundle:BundleError", "prisma_common.bag:BagError")


def _is_bag(path: Path) -> bool:
    return path.is_dir() or path.suffix in BAG_SUFFIXES


def training_data(text: str) -> str | Path:
    """'synthetic', an .npz calibration set, or a calibration bag (directory, .mcap or .db3)."""
    if text == "synthetic":
        return text
    path = existing_path(text)
    if path.suffix != ".npz" and not _is_bag(path):
        raise argparse.ArgumentTypeError(f"{text} is not 'synthetic', a bag (directory, .mcap, .db3) or an .npz "
                                         f"calibration set")
    return path


def check_training_data(args: argparse.Namespace):
    """Before torch is imported: an .npz must be a calibration set (returned, so it is read once),
    a bag must hold both topics (MissingTopicsError names them and lists the bag's)."""
    if args.data == "synthetic":
        return None
    path = Path(args.data)
    if path.suffix == ".npz":
        try:
            return CalibrationSet.load(path)
        except ValueError as exc:  # not a calibration set: the message names the file and why
            raise UserError(f"--data {exc}") from None
    taxel_topic = args.taxel_topic or TAXELS.format(finger=args.finger)
    try:
        require_topics(path, [taxel_topic, args.wrench_topic])
    except BagError as exc:
        raise UserError(f"--data {exc}; choose the topics with --finger/--taxel-topic and --reference-topic") \
            from None
    return None


def load_training_data(args: argparse.Namespace, calibration=None):
    from .dataset import ForceDataset, load_calibration_npz, synthetic_dataset

    if args.data == "synthetic":
        return synthetic_dataset(args.samples, args.data_seed)
    path = Path(args.data)
    if path.suffix == ".npz":
        if calibration is not None:
            return ForceDataset.from_calibration_set(calibration, str(path))
        try:
            return load_calibration_npz(path)
        except ValueError as exc:  # not a calibration set: the message names the file and why
            raise UserError(f"--data {exc}") from None
    from .calibration_bag import load_calibration_bag

    taxel_topic = args.taxel_topic or TAXELS.format(finger=args.finger)
    try:
        dataset, report = load_calibration_bag(path, taxel_topic, args.wrench_topic,
                                               int(args.tolerance_ms * 1e6))
    except ValueError as exc:  # not a bag, a missing topic (named, with the bag's topics), no messages
        raise UserError(f"--data {exc}; choose the topics with --finger/--taxel-topic and "
                        f"--reference-topic") from None
    print(f"calibration bag: {report.summary()}", flush=True)
    if len(dataset) < 10:
        raise UserError(f"--data {args.data}: only {len(dataset)} paired samples; check the topics and "
                        f"--tolerance-ms")
    return dataset


def parse_loss_weights(text: str) -> dict[str, float]:
    """'tz=0.25,tx=0.5' -> {'tz': 0.25, 'tx': 0.5} (axis names are checked against the model later)."""
    weights: dict[str, float] = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        axis, sep, value = item.partition("=")
        try:
            weights[axis.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep:
            raise argparse.ArgumentTypeError(f"{item!r} is not AXIS=WEIGHT (e.g. tz=0.25)")
    return weights


@command("prisma-train-force", *LOADER_ERRORS)
def train_main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="prisma-train-force",
                            description="Train a taxel-to-wrench network and write a model bundle.")
    parser.add_argument("--model", required=True, choices=MODEL_CHOICES)
    parser.add_argument("--data", default="synthetic", type=training_data,
                        help="'synthetic' (the tactile driver's calibration set), a calibration bag, or a .npz set")
    parser.add_argument("--samples", type=positive_int, default=140_000, help="synthetic set size")
    parser.add_argument("--data-seed", type=non_negative_int, default=0, help="synthetic set seed")
    parser.add_argument("--finger", default="thumb", choices=FINGERS,
                        help="bag: the calibrated finger; its taxel topic is /prisma/<finger>/taxels")
    parser.add_argument("--taxel-topic", help="bag: taxel topic (overrides --finger)")
    parser.add_argument("--reference-topic", "--wrench-topic", dest="wrench_topic", default="/ft_sensor/wrench",
                        help="bag: reference geometry_msgs/WrenchStamped topic of the F/T sensor")
    parser.add_argument("--tolerance-ms", type=non_negative_float, default=5.0, help="bag: stamp pairing tolerance")
    parser.add_argument("--epochs", type=positive_int, default=300)
    parser.add_argument("--batch", type=positive_int, default=64)
    parser.add_argument("--lr", type=positive_float, default=1e-3)
    parser.add_argument("--lr-schedule", choices=("constant", "cosine"), default="constant")
    parser.add_argument("--seed", type=non_negative_int, default=0)
    parser.add_argument("--patience", type=non_negative_int, default=0,
                        help="early stopping patience in epochs (0 = off)")
    parser.add_argument("--val-fraction", type=fraction, default=0.2, help="validation share, between 0 and 1")
    parser.add_argument("--threads", type=positive_int, default=1, help="torch threads")
    parser.add_argument("--input-noise", type=non_negative_float, default=0.0,
                        help="V rms Gaussian noise added to training inputs (augmentation; 0 = off)")
    parser.add_argument("--weight-decay", type=non_negative_float, default=0.0,
                        help="decoupled weight decay; > 0 trains with AdamW instead of Adam (0 = off)")
    parser.add_argument("--ema-decay", type=unit_interval, default=0.0,
                        help="per-step decay of an exponential moving average of the weights, e.g. 0.999; "
                             "the averaged network is validated, selected and saved (0 = off)")
    parser.add_argument("--loss-weights", type=parse_loss_weights, default={}, metavar="AXIS=W,...",
                        help="per-axis weights of the normalised MSE, e.g. 'tx=0.5,ty=0.5,tz=0.25'; "
                             "unnamed axes weigh 1; the validation loss that picks the saved epoch "
                             "uses the same weights")
    parser.add_argument("--max-steps-per-epoch", type=non_negative_int, default=0, help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path,
                        help="bundle directory (default out/force/<model>); an earlier bundle there is "
                             "replaced, any other existing path is refused")
    args = parser.parse_args(argv)
    # the output is checked before the (long) training, not after it
    out = args.out or Path("out") / "force" / args.model
    check_bundle_out(out, "--out")
    calibration = check_training_data(args)

    from .bundle import save_bundle
    from .dataset import contiguous_block_split
    from .networks import MODEL_SPECS, parameter_count
    from .training import TrainConfig, train

    config = TrainConfig(model_kind=args.model, epochs=args.epochs, batch=args.batch, learning_rate=args.lr,
                         lr_schedule=args.lr_schedule, seed=args.seed, patience=args.patience,
                         val_fraction=args.val_fraction, threads=args.threads, input_noise=args.input_noise,
                         weight_decay=args.weight_decay, ema_decay=args.ema_decay, loss_weights=args.loss_weights,
                         max_steps_per_epoch=args.max_steps_per_epoch)
    try:
        config.validate()
    except ValueError as exc:
        parser.error(str(exc))
    dataset = load_training_data(args, calibration)
    try:
        split = contiguous_block_split(dataset.block, config.val_fraction, seed=config.seed)
    except ValueError as exc:  # too few samples to split
        raise UserError(f"--data {args.data}: {exc}") from None
    if len(split.train) == 0 or len(split.validation) == 0:
        raise UserError(f"--val-fraction {args.val_fraction} on {len(dataset)} samples leaves "
                        f"{len(split.train)} for training and {len(split.validation)} for validation; "
                        f"use more samples or another fraction")
    spec = MODEL_SPECS[args.model]
    print(f"training {args.model} ({spec.description}) on {dataset.source}: {len(dataset)} samples, "
          f"{args.epochs} epochs, batch {args.batch}, seed {args.seed}, {args.threads} torch thread(s)", flush=True)
    result = train(dataset, config, progress=lambda line: print(line, flush=True), split=split)
    save_bundle(out, result.model, result.metadata)
    mse = " ".join(f"{a} {v:.4g}" for a, v in result.metadata.validation_mse.items())
    print(f"best epoch {result.best_epoch} of {len(result.history)} ({result.seconds:.0f} s, "
          f"{parameter_count(result.model)} parameters); validation MSE {mse}")
    print(f"wrote bundle {out}")
    return 0


def plot_prefix(text: str) -> str:
    if "/" in text or "\\" in text or text in (".", ".."):
        raise argparse.ArgumentTypeError(f"{text!r} is a path; give a file name prefix (the folder is --plots)")
    return text


def _write_text(path: Path, text: str) -> None:
    with atomic_output(path) as staged:
        staged.write_text(text)


@command("prisma-eval-force", *LOADER_ERRORS)
def eval_main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="prisma-eval-force",
                            description="Held-out push (Fz) and slide (Fx, Fy) tests of model bundles.")
    parser.add_argument("bundles", nargs="+", type=Path, help="bundle directories")
    parser.add_argument("--push-samples", type=positive_int, default=30_000, help="held-out push test length (100 Hz)")
    parser.add_argument("--slide-samples", type=positive_int, default=30_000,
                        help="held-out slide test length (100 Hz)")
    parser.add_argument("--push-seed", type=non_negative_int)
    parser.add_argument("--slide-seed", type=non_negative_int)
    parser.add_argument("--plots", type=output_dir, help="write PNG plots into this directory")
    parser.add_argument("--prefix", type=plot_prefix, default="force_", help="plot file name prefix")
    parser.add_argument("--plot-seconds", type=positive_float, default=30.0,
                        help="time span shown in the time plots")
    parser.add_argument("--table", type=output_file(), help="also write the markdown table to this file")
    parser.add_argument("--json", type=output_file(), help="also write the numbers as JSON")
    parser.add_argument("--threads", type=positive_int, default=1)
    parser.add_argument("--precision", choices=PRECISIONS, default=DEFAULT_PRECISION,
                        help="network weights: float16 on the dense form (CNN2) or the float32 network")
    args = parser.parse_args(argv)
    for path in args.bundles:
        check_bundle_dir(path)

    from .evaluation import PUSH_SEED, SLIDE_SEED, TARGETS, evaluate, held_out_tests, plot_tests, results_table
    from .inference import ForceEstimator

    estimators = [(path, ForceEstimator.from_bundle(path, threads=args.threads, precision=args.precision))
                  for path in args.bundles]
    tests = held_out_tests(args.push_samples, args.slide_samples,
                           args.push_seed if args.push_seed is not None else PUSH_SEED,
                           args.slide_seed if args.slide_seed is not None else SLIDE_SEED)
    names = [path.name or str(path) for path in args.bundles]
    if len(set(names)) != len(names):
        names = [str(path) for path in args.bundles]
    results = [evaluate(est, tests, name) for (path, est), name in zip(estimators, names)]
    table = results_table(results)
    print(f"held-out tests: {tests.push.source}, {tests.slide.source}")
    print(table)
    for r in results:
        checks = ", ".join(f"{k} {'ok' if ok else 'MISSED'}" for k, ok in r.meets_targets().items())
        mae = " ".join(f"{a} {v:.3f}" for a, v in r.low_force_mae.items())
        print(f"{r.name}: MAE under 1.2 N [{mae}] N over {r.low_force_samples} samples; "
              f"CNN2 targets {TARGETS}: {checks}")
    if args.table:
        _write_text(args.table, table + "\n")
    if args.json:
        _write_text(args.json, json.dumps([{
            "name": r.name, "model_kind": r.model_kind, "push_fz_mse": r.push_fz_mse,
            "slide_fx_mse": r.slide_fx_mse, "slide_fy_mse": r.slide_fy_mse,
            "low_force_mae": r.low_force_mae, "low_force_samples": r.low_force_samples,
            "validation_mse": r.validation_mse, "training_seconds": r.training_seconds,
            "epochs_run": r.epochs_run, "meets_targets": r.meets_targets()} for r in results], indent=2))
    if args.plots:
        for path in plot_tests(results, tests, args.plots, args.prefix, args.plot_seconds):
            print(f"wrote {path}")
    return 0


def finger_override(text: str) -> tuple[str, Path]:
    """FINGER=BUNDLE."""
    finger, sep, path = text.partition("=")
    if not sep or finger not in FINGERS or not path:
        raise argparse.ArgumentTypeError(f"{text!r}: expected FINGER=BUNDLE with FINGER in {list(FINGERS)}")
    return finger, Path(path)


def finger_list(text: str) -> list[str]:
    fingers = [f.strip() for f in text.split(",") if f.strip()]
    unknown = [f for f in fingers if f not in FINGERS]
    if unknown or not fingers:
        raise argparse.ArgumentTypeError(f"{text!r}: unknown finger(s) {unknown}; give a comma-separated "
                                         f"list of {','.join(FINGERS)}")
    return list(dict.fromkeys(fingers))


def finger_template(text: str) -> str:
    """A str.format template whose only field is {finger}."""
    try:
        text.format(finger="thumb")
    except (KeyError, IndexError, ValueError) as exc:
        raise argparse.ArgumentTypeError(f"{text!r} is not a template with only {{finger}} in braces "
                                         f"(e.g. '/prisma/{{finger}}/taxels'): {exc!r}") from None
    return text


def bag_input(text: str) -> Path:
    path = existing_path(text)
    if not _is_bag(path):
        raise argparse.ArgumentTypeError(f"{text} is not a bag: give a bag directory or an .mcap/.db3 file")
    return path


@command("prisma-estimate-bag", *LOADER_ERRORS)
def estimate_bag_main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="prisma-estimate-bag",
                            description="Estimate wrenches for every taxel message of a bag; "
                                        "write /prisma/<finger>/wrench to a new bag.")
    parser.add_argument("input", type=bag_input, help="bag directory, .mcap or .db3")
    parser.add_argument("output", type=new_path, help="new bag directory (an existing one is refused)")
    parser.add_argument("--bundle", type=Path, default=None, help="model bundle (default config/models/cnn2)")
    parser.add_argument("--override", type=finger_override, action="append", default=[], metavar="FINGER=BUNDLE",
                        help="per-finger bundle (repeatable)")
    parser.add_argument("--fingers", type=finger_list, default=list(FINGERS),
                        help="comma-separated fingers (default all five)")
    parser.add_argument("--frame-id-template", type=finger_template, default="",
                        help="e.g. '{finger}_pad'; empty keeps the input's")
    parser.add_argument("--taxel-topic", type=finger_template, default=TAXELS)
    parser.add_argument("--wrench-topic", type=finger_template, default=WRENCH)
    parser.add_argument("--batch-window-ms", type=non_negative_float, default=5.0)
    parser.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    parser.add_argument("--threads", type=positive_int, default=1)
    parser.add_argument("--precision", choices=PRECISIONS, default=DEFAULT_PRECISION,
                        help="network weights: float16 on the dense form (CNN2) or the float32 network")
    args = parser.parse_args(argv)
    fingers = args.fingers
    for path in [args.bundle, *(bundle for _, bundle in args.override)]:
        if path is not None:
            check_bundle_dir(path)
    # the input must hold every requested finger's taxel topic: checked (and named) before any
    # bundle is loaded or anything is written
    try:
        require_topics(args.input, [args.taxel_topic.format(finger=f) for f in fingers])
    except MissingTopicsError as exc:
        raise UserError(f"{exc}; pick the fingers it has with --fingers or the topic name with --taxel-topic") \
            from None

    from .bundle import DEFAULT_BUNDLE, resolve_bundle_path
    from .estimate_bag import estimate_bag
    from .force_estimator_core import WrenchPipeline, build_estimators

    overrides = dict(args.override)
    default = args.bundle or DEFAULT_BUNDLE
    bundles = {f: str(resolve_bundle_path(overrides.get(f, default))) for f in fingers}
    estimators = build_estimators(bundles, threads=args.threads, precision=args.precision)
    pipeline = WrenchPipeline(estimators, args.frame_id_template, int(args.batch_window_ms * 1e6))
    report = estimate_bag(args.input, args.output, pipeline, types, args.taxel_topic, args.wrench_topic,
                          args.storage)
    print(report.summary())
    print(f"wrote {args.output}")
    return 0


_COMMANDS = {"train": train_main, "eval": eval_main, "estimate-bag": estimate_bag_main}

if __name__ == "__main__":
    # `python -m prisma_force_estimator.cli train|eval|estimate-bag ...`, for checkouts whose console
    # scripts are not installed yet.
    if len(sys.argv) < 2 or sys.argv[1] not in _COMMANDS:
        sys.exit(f"usage: python -m prisma_force_estimator.cli {{{'|'.join(_COMMANDS)}}} [args]")
    sys.exit(_COMMANDS[sys.argv[1]](sys.argv[2:]))
