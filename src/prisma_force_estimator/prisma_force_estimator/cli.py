"""Console scripts: prisma-train-force, prisma-eval-force, prisma-estimate-bag."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from prisma_tactile_driver.taxels import FINGERS

from .networks import MODEL_KINDS, MODEL_SPECS, parameter_count


def _is_bag(path: Path) -> bool:
    return path.is_dir() or path.suffix in (".mcap", ".db3")


def load_training_data(args: argparse.Namespace):
    from .dataset import load_calibration_npz, synthetic_dataset

    if args.data == "synthetic":
        return synthetic_dataset(args.samples, args.data_seed)
    path = Path(args.data)
    if not path.exists():
        raise SystemExit(f"--data {args.data}: no such file or directory (expected 'synthetic', a bag or a .npz)")
    if path.suffix == ".npz":
        return load_calibration_npz(path)
    if _is_bag(path):
        from .calibration_bag import load_calibration_bag

        taxel_topic = args.taxel_topic or f"/prisma/{args.finger}/taxels"
        dataset, report = load_calibration_bag(path, taxel_topic, args.wrench_topic,
                                               int(args.tolerance_ms * 1e6))
        print(f"calibration bag: {report.summary()}", flush=True)
        if len(dataset) < 10:
            raise SystemExit(f"--data {args.data}: only {len(dataset)} paired samples; check the topics and tolerance")
        return dataset
    raise SystemExit(f"--data {args.data}: not 'synthetic', a bag directory/.mcap/.db3 or a .npz calibration set")


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


def train_main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="prisma-train-force",
                                     description="Train a taxel-to-wrench network and write a model bundle.")
    parser.add_argument("--model", required=True, choices=MODEL_KINDS)
    parser.add_argument("--data", default="synthetic",
                        help="'synthetic' (the tactile driver's calibration set), a calibration bag, or a .npz set")
    parser.add_argument("--samples", type=int, default=140_000, help="synthetic set size")
    parser.add_argument("--data-seed", type=int, default=0, help="synthetic set seed")
    parser.add_argument("--finger", default="thumb", choices=FINGERS,
                        help="bag: the calibrated finger; its taxel topic is /prisma/<finger>/taxels")
    parser.add_argument("--taxel-topic", help="bag: taxel topic (overrides --finger)")
    parser.add_argument("--reference-topic", "--wrench-topic", dest="wrench_topic", default="/ft_sensor/wrench",
                        help="bag: reference geometry_msgs/WrenchStamped topic of the F/T sensor")
    parser.add_argument("--tolerance-ms", type=float, default=5.0, help="bag: stamp pairing tolerance")
    parser.add_argument("--epochs", type=int, default=300)
    parser.add_argument("--batch", type=int, default=64)
    parser.add_argument("--lr", type=float, default=1e-3)
    parser.add_argument("--lr-schedule", choices=("constant", "cosine"), default="constant")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--patience", type=int, default=0, help="early stopping patience in epochs (0 = off)")
    parser.add_argument("--val-fraction", type=float, default=0.2)
    parser.add_argument("--threads", type=int, default=1, help="torch threads")
    parser.add_argument("--input-noise", type=float, default=0.0,
                        help="V rms Gaussian noise added to training inputs (augmentation; 0 = off)")
    parser.add_argument("--weight-decay", type=float, default=0.0,
                        help="decoupled weight decay; > 0 trains with AdamW instead of Adam (0 = off)")
    parser.add_argument("--ema-decay", type=float, default=0.0,
                        help="per-step decay of an exponential moving average of the weights, e.g. 0.999; "
                             "the averaged network is validated, selected and saved (0 = off)")
    parser.add_argument("--loss-weights", type=parse_loss_weights, default={}, metavar="AXIS=W,...",
                        help="per-axis weights of the normalised MSE, e.g. 'tx=0.5,ty=0.5,tz=0.25'; "
                             "unnamed axes weigh 1; the validation loss that picks the saved epoch "
                             "uses the same weights")
    parser.add_argument("--max-steps-per-epoch", type=int, default=0, help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path, help="bundle directory (default out/force/<model>)")
    args = parser.parse_args(argv)

    from .bundle import save_bundle
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
    dataset = load_training_data(args)
    spec = MODEL_SPECS[args.model]
    print(f"training {args.model} ({spec.description}) on {dataset.source}: {len(dataset)} samples, "
          f"{args.epochs} epochs, batch {args.batch}, seed {args.seed}, {args.threads} torch thread(s)", flush=True)
    result = train(dataset, config, progress=lambda line: print(line, flush=True))
    out = args.out or Path("out") / "force" / args.model
    save_bundle(out, result.model, result.metadata)
    mse = " ".join(f"{a} {v:.4g}" for a, v in result.metadata.validation_mse.items())
    print(f"best epoch {result.best_epoch} of {len(result.history)} ({result.seconds:.0f} s, "
          f"{parameter_count(result.model)} parameters); validation MSE {mse}")
    print(f"wrote bundle {out}")
    return 0


def eval_main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="prisma-eval-force",
                                     description="Held-out push (Fz) and slide (Fx, Fy) tests of model bundles.")
    parser.add_argument("bundles", nargs="+", type=Path, help="bundle directories")
    parser.add_argument("--push-samples", type=int, default=30_000, help="held-out push test length (100 Hz)")
    parser.add_argument("--slide-samples", type=int, default=30_000, help="held-out slide test length (100 Hz)")
    parser.add_argument("--push-seed", type=int)
    parser.add_argument("--slide-seed", type=int)
    parser.add_argument("--plots", type=Path, help="write PNG plots into this directory")
    parser.add_argument("--prefix", default="force_", help="plot file name prefix")
    parser.add_argument("--plot-seconds", type=float, default=30.0, help="time span shown in the time plots")
    parser.add_argument("--table", type=Path, help="also write the markdown table to this file")
    parser.add_argument("--json", type=Path, help="also write the numbers as JSON")
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args(argv)

    from .bundle import BundleError
    from .evaluation import PUSH_SEED, SLIDE_SEED, TARGETS, evaluate, held_out_tests, plot_tests, results_table
    from .inference import ForceEstimator

    try:
        estimators = [(path, ForceEstimator.from_bundle(path, threads=args.threads)) for path in args.bundles]
    except BundleError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
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
        args.table.write_text(table + "\n")
    if args.json:
        args.json.write_text(json.dumps([{
            "name": r.name, "model_kind": r.model_kind, "push_fz_mse": r.push_fz_mse,
            "slide_fx_mse": r.slide_fx_mse, "slide_fy_mse": r.slide_fy_mse,
            "low_force_mae": r.low_force_mae, "low_force_samples": r.low_force_samples,
            "validation_mse": r.validation_mse, "training_seconds": r.training_seconds,
            "epochs_run": r.epochs_run, "meets_targets": r.meets_targets()} for r in results], indent=2))
    if args.plots:
        for path in plot_tests(results, tests, args.plots, args.prefix, args.plot_seconds):
            print(f"wrote {path}")
    return 0


def _parse_overrides(items: list[str]) -> dict[str, str]:
    overrides = {}
    for item in items:
        finger, sep, path = item.partition("=")
        if not sep or finger not in FINGERS or not path:
            raise SystemExit(f"--override {item!r}: expected FINGER=BUNDLE with FINGER in {list(FINGERS)}")
        overrides[finger] = path
    return overrides


def estimate_bag_main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="prisma-estimate-bag",
                                     description="Estimate wrenches for every taxel message of a bag; "
                                                 "write /prisma/<finger>/wrench to a new bag.")
    parser.add_argument("input", type=Path)
    parser.add_argument("output", type=Path)
    parser.add_argument("--bundle", default=None, help="model bundle (default config/models/cnn2)")
    parser.add_argument("--override", action="append", default=[], metavar="FINGER=BUNDLE",
                        help="per-finger bundle (repeatable)")
    parser.add_argument("--fingers", default=",".join(FINGERS))
    parser.add_argument("--frame-id-template", default="", help="e.g. '{finger}_pad'; empty keeps the input's")
    parser.add_argument("--taxel-topic", default="/prisma/{finger}/taxels")
    parser.add_argument("--wrench-topic", default="/prisma/{finger}/wrench")
    parser.add_argument("--batch-window-ms", type=float, default=5.0)
    parser.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args(argv)

    from prisma_bringup.typestore import types

    from .bundle import DEFAULT_BUNDLE, BundleError, resolve_bundle_path
    from .estimate_bag import estimate_bag
    from .pipeline import WrenchPipeline, build_estimators

    fingers = [f.strip() for f in args.fingers.split(",") if f.strip()]
    unknown = [f for f in fingers if f not in FINGERS]
    if unknown or not fingers:
        parser.error(f"--fingers {args.fingers!r}: unknown finger(s) {unknown}; expected some of {list(FINGERS)}")
    if not args.input.exists():
        parser.error(f"input bag {args.input} does not exist")
    if args.output.exists():
        parser.error(f"output bag {args.output} already exists")
    overrides = _parse_overrides(args.override)
    default = args.bundle or DEFAULT_BUNDLE
    bundles = {f: str(resolve_bundle_path(overrides.get(f, default))) for f in fingers}
    try:
        estimators = build_estimators(bundles, threads=args.threads)
    except BundleError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
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
