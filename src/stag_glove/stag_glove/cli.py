"""Command lines (ROS-free): stag-make-dataset, stag-train-classifier, stag-train-weight,
stag-train-pose, stag-glove-correlation. Each prints progress per epoch and writes its numbers as
JSON, its figures as PNG, and (optionally) a model bundle for the glove_perception node.

Arguments, the dataset file and the output paths are checked before any training (exit 2 with a
one-line message); JSON, figures, datasets and bundles are written under a temporary name and
renamed when complete (an earlier bundle at --bundle-out is replaced, any other directory refused).
"""
from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from prisma_common.atomic import atomic_output
from prisma_common.cli_args import (
    ArgumentParser,
    UserError,
    check_bundle_out,
    command,
    existing_file,
    image_file,
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


def _command(argv: list[str] | None, prog: str) -> str:
    """The command line as run, less --out-json (where the numbers went is no part of the recipe)."""
    args = list(sys.argv[1:] if argv is None else argv)
    if "--out-json" in args:
        i = args.index("--out-json")
        del args[i:i + 2]
    return " ".join([prog] + [shlex.quote(a) for a in args])


def _add_data_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--dataset", type=existing_file,
                        help="metadata.mat (MATLAB v5/v7.3) or .h5; default: synthetic")
    parser.add_argument("--synthetic-seed", type=non_negative_int, default=0,
                        help="seed of the synthetic glove (no --dataset)")
    parser.add_argument("--threads", type=positive_int, default=1, help="torch/BLAS threads (default 1)")
    parser.add_argument("--out-json", type=output_file(), help="write the numbers here")


def _add_train_args(parser: argparse.ArgumentParser, epochs: int, lr_step: int) -> None:
    parser.add_argument("--width", type=positive_int, default=16, help="trunk width (paper: 64)")
    parser.add_argument("--epochs", type=positive_int, default=epochs)
    parser.add_argument("--lr-step", type=positive_int, default=lr_step,
                        help="x0.1 learning rate every this many epochs (paper: 100)")
    parser.add_argument("--batch-size", type=positive_int, default=32)
    parser.add_argument("--noise", type=non_negative_float, default=0.015, help="Gaussian noise on training inputs")


def _add_bundle_out(parser: argparse.ArgumentParser, help: str) -> None:
    parser.add_argument("--bundle-out", type=Path,
                        help=help + " (an earlier bundle there is replaced, any other existing path refused)")


def _check_outputs(args) -> None:
    """Before the (long) training: --bundle-out must be new, empty or an earlier bundle."""
    if getattr(args, "bundle_out", None) is not None:
        check_bundle_out(args.bundle_out, "--bundle-out")


def _save_bundle(path: Path, kind: str, model, metadata: dict) -> None:
    from .bundle import save_bundle

    with atomic_output(path) as staged:  # whole or not at all
        save_bundle(staged, kind, model, metadata)


def _train_config(args, seed: int = 0):
    from .training import TrainConfig

    return TrainConfig(width=args.width, epochs=args.epochs, lr_step_epochs=args.lr_step, batch_size=args.batch_size,
                       noise_std=args.noise, seed=seed, threads=args.threads)


def _synthetic(kind: str, seed: int) -> tuple[GloveDataset, str]:
    from .synthetic import SyntheticConfig, SyntheticGlove

    glove = SyntheticGlove(SyntheticConfig(seed=seed))
    ds = {"object": glove.object_dataset, "pose": glove.pose_dataset, "weight": glove.weight_dataset}[kind]()
    return ds, f"synthetic glove, seed {seed}, {kind} set ({len(ds)} frames)"


def _data(args, kind: str,
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
    return _synthetic(kind, args.synthetic_seed)


def _splits_check(balanced: bool) -> Callable[[GloveDataset, str], None]:
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


def _weights_check(ds: GloveDataset, source: str) -> None:
    if ds.weights_g is None:
        raise UserError(f"--dataset {source}: no per-object weights ('weights' field); give the STAG weights set")
    if len(np.unique(ds.object_id)) < 2:
        raise UserError(f"--dataset {source}: frames of {len(np.unique(ds.object_id))} object(s); "
                        f"leave-one-object-out needs at least 2")


def _recording_check(ds: GloveDataset, source: str) -> None:
    if len(ds) < 2:
        raise UserError(f"--dataset {source}: {len(ds)} frame(s); the correlation needs a recording")


def _write_json(path: Path | None, data: dict) -> None:
    if path is not None:
        with atomic_output(path) as staged:
            staged.write_text(json.dumps(data, indent=2) + "\n")
        print(f"wrote {path}")


def _frames_arg(text: str) -> list[int]:
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


def _folds_arg(text: str) -> int | None:
    """'all' -> None, or a positive count."""
    if text == "all":
        return None
    try:
        return positive_int(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"{text!r} is neither 'all' nor a whole number >= 1 of objects to "
                                         f"hold out") from None


# -------------------------------------------------------------------------------- make dataset
@command("stag-make-dataset")
def make_dataset_main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="stag-make-dataset", description="Write a synthetic glove dataset "
                            "(metadata.mat fields) as .mat (MATLAB v5) or .h5.")
    parser.add_argument("out", type=output_file(*DATASET_SUFFIXES), help="a .mat, .h5 or .hdf5 file (replaced)")
    parser.add_argument("--kind", choices=("object", "pose", "weight"), default="object")
    parser.add_argument("--seed", type=non_negative_int, default=0)
    args = parser.parse_args(argv)
    from .dataset import save_dataset

    ds, text = _synthetic(args.kind, args.seed)
    save_dataset(ds, args.out)
    print(f"wrote {args.out}: {text}, {len(ds.objects)} classes, {ds.has_valid_label.sum()} valid frames")
    return 0


# -------------------------------------------------------------------------------- classifier
@command("stag-train-classifier")
def train_classifier_main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="stag-train-classifier", description="Object classifier: accuracy vs "
                            "number of input frames N (random vs cluster selection) on held-out sessions.")
    _add_data_args(parser)
    _add_train_args(parser, epochs=12, lr_step=8)
    parser.add_argument("--frames", type=_frames_arg, default=list(range(1, 9)), help="N values, e.g. 1-8 or 1,2,4")
    parser.add_argument("--seeds", type=non_negative_int, nargs="+", default=[0, 1])
    parser.add_argument("--selection", nargs="+", default=["random", "cluster"], choices=("random", "cluster"))
    parser.add_argument("--mode", default="head", choices=("head", "finetune", "scratch"),
                        help="head: N=1 trained end to end, N>1 warm-started from it with fusion+classifier "
                             "trained on the frozen trunk (CPU); scratch: every N end to end (the paper)")
    parser.add_argument("--head-epochs", type=non_negative_int, default=10)
    parser.add_argument("--finetune-epochs", type=non_negative_int, default=2)
    parser.add_argument("--confusion-png", type=image_file)
    parser.add_argument("--curve-png", type=image_file)
    _add_bundle_out(parser, "save the model of the first seed here")
    parser.add_argument("--bundle-frames", type=positive_int, default=8)
    parser.add_argument("--bundle-selection", default="cluster", choices=("random", "cluster"))
    args = parser.parse_args(argv)
    if args.bundle_out and (args.bundle_frames not in args.frames
                            or (args.bundle_frames > 1 and args.bundle_selection not in args.selection)):
        parser.error(f"--bundle-frames {args.bundle_frames} with --bundle-selection {args.bundle_selection} "
                     f"is not trained (--frames {args.frames}, --selection {args.selection}); pick a trained "
                     f"pair")
    _check_outputs(args)
    started = time.perf_counter()
    ds, source = _data(args, "object", _splits_check(balanced=True))
    from .experiments import object_experiment, summarise_curve
    from .plots import accuracy_curve_png, confusion_png

    print(f"dataset: {source}; {len(ds.objects)} classes")
    keep = {(args.seeds[0], args.bundle_selection if args.bundle_frames > 1 else "any", args.bundle_frames)}
    results = object_experiment(ds, args.frames, args.seeds, args.selection, _train_config(args, args.seeds[0]),
                                args.mode, args.head_epochs, args.finetune_epochs, keep)
    summary = summarise_curve(results, args.selection)
    print(f"\n{'selection':<9} {'N':>2} {'top-1 %':>8} {'+-':>5} {'top-3 %':>8} {'warm-start top-1 %':>19}")
    for r in summary:
        warm = f"{100 * r['warm_top1']:.1f}" if "warm_top1" in r else "-"
        print(f"{r['selection']:<9} {r['n']:>2} {100 * r['top1']:>8.1f} {100 * r['top1_std']:>5.1f} "
              f"{100 * r['top3']:>8.1f} {warm:>19}")
    first = args.seeds[0]
    n_max = max(args.frames)
    panels = [(f"N=1 (seed {first}), top-1 {100 * results.confusions[(first, 'any', 1)].top1:.1f}%",
               results.confusions[(first, "any", 1)].confusion)]
    if n_max > 1:
        sel = args.bundle_selection if args.bundle_selection in args.selection else args.selection[0]
        ev = results.confusions[(first, sel, n_max)]
        panels.append((f"N={n_max}, {sel} (seed {first}), top-1 {100 * ev.top1:.1f}%", ev.confusion))
    if args.confusion_png:
        print(f"wrote {confusion_png(panels, ds.objects, args.confusion_png)}")
    if args.curve_png:
        title = (f"held-out sessions, trunk width {args.width}, {args.epochs} epochs, mode {args.mode}, "
                 f"seeds {args.seeds}")
        print(f"wrote {accuracy_curve_png(summary, args.curve_png, title)}")
    command = _command(argv, "stag-train-classifier")
    elapsed = time.perf_counter() - started
    _write_json(args.out_json, {"command": command, "dataset": source, "seconds": elapsed, "summary": summary,
                                "rows": results.rows})
    if args.bundle_out:
        key = next(iter(keep))
        ev = results.confusions[key]
        _save_bundle(args.bundle_out, "object", results.models[key], {
            "width": args.width, "n_frames": args.bundle_frames, "labels": ds.objects,
            "selection": args.bundle_selection, "normalisation": {"low": 500, "high": 650},
            "trained_on": source, "command": command, "held_out_top1": ev.top1, "held_out_top3": ev.top3})
        print(f"wrote bundle {args.bundle_out}")
    print(f"done in {elapsed:.0f} s")
    return 0


# -------------------------------------------------------------------------------- weight
@command("stag-train-weight")
def train_weight_main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="stag-train-weight", description="Weight regression in log space, "
                            "leave-one-object-out, against the linear baseline a*sum(frame)+b.")
    _add_data_args(parser)
    _add_train_args(parser, epochs=15, lr_step=10)
    parser.add_argument("--folds", type=_folds_arg, default=None,
                        help="'all' objects (the default), or a count spread over the weight range")
    parser.add_argument("--png", type=image_file)
    _add_bundle_out(parser, "train on every object and save the model here")
    args = parser.parse_args(argv)
    _check_outputs(args)
    started = time.perf_counter()
    ds, source = _data(args, "weight", _weights_check)
    from .experiments import default_folds, frames_tensor, weight_experiment
    from .plots import weight_png
    from .training import LinearBaseline, train_weight

    folds = default_folds(ds, args.folds)
    print(f"dataset: {source}; leave-one-object-out over {len(folds)} of {len(ds.objects)} objects")
    cfg = _train_config(args)
    rows = weight_experiment(ds, folds, cfg)
    cnn = float(np.mean([r["cnn_error_g"] for r in rows]))
    linear = float(np.mean([r["linear_error_g"] for r in rows]))
    print(f"\n{'object':<12} {'true g':>8} {'CNN err g':>10} {'linear err g':>13}")
    for r in rows:
        print(f"{r['object']:<12} {r['grams']:>8.1f} {r['cnn_error_g']:>10.1f} {r['linear_error_g']:>13.1f}")
    print(f"{'mean':<12} {'':>8} {cnn:>10.1f} {linear:>13.1f}")
    if args.png:
        print(f"wrote {weight_png(rows, args.png)}")
    command = _command(argv, "stag-train-weight")
    _write_json(args.out_json, {"command": command, "dataset": source, "folds": len(folds), "objects": len(ds.objects),
                                "cnn_mean_error_g": cnn, "linear_mean_error_g": linear, "rows": rows,
                                "seconds": time.perf_counter() - started})
    if args.bundle_out:
        import torch

        from .models import WeightNet

        frames = frames_tensor(ds)
        assert ds.weights_g is not None  # _weights_check
        grams = ds.weights_g[ds.object_id]
        torch.manual_seed(cfg.seed)
        net = WeightNet(cfg.width, cfg.dropout)
        print("final model on every object:")
        train_weight(net, frames, grams, cfg, print, "[all objects] ")
        base = LinearBaseline.fit(frames.reshape(len(frames), -1).sum(1).numpy(), grams)
        _save_bundle(args.bundle_out, "weight", net, {
            "width": cfg.width, "normalisation": {"low": 500, "high": 650}, "target": "log(grams)",
            "linear_baseline": {"a": base.a, "b": base.b}, "trained_on": source, "command": command,
            "loo_cnn_mean_error_g": cnn, "loo_linear_mean_error_g": linear, "loo_folds": len(folds)})
        print(f"wrote bundle {args.bundle_out}")
    print(f"done in {time.perf_counter() - started:.0f} s")
    return 0


# -------------------------------------------------------------------------------- pose
@command("stag-train-pose")
def train_pose_main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="stag-train-pose", description="Hand-pose classifier (7 grasps + empty "
                            "hand), single frame, held-out session.")
    _add_data_args(parser)
    _add_train_args(parser, epochs=15, lr_step=10)
    parser.add_argument("--confusion-png", type=image_file)
    _add_bundle_out(parser, "save the model here")
    args = parser.parse_args(argv)
    _check_outputs(args)
    started = time.perf_counter()
    ds, source = _data(args, "pose", _splits_check(balanced=False))
    from .experiments import pose_experiment
    from .plots import confusion_png

    print(f"dataset: {source}; poses {ds.objects}")
    net, ev, _ = pose_experiment(ds, _train_config(args))
    print(f"held-out session: top-1 {100 * ev.top1:.1f}%, top-3 {100 * ev.top3:.1f}%")
    if args.confusion_png:
        panels = [(f"hand pose, top-1 {100 * ev.top1:.1f}%", ev.confusion)]
        print(f"wrote {confusion_png(panels, ds.objects, args.confusion_png)}")
    command = _command(argv, "stag-train-pose")
    _write_json(args.out_json, {"command": command, "dataset": source, "top1": ev.top1, "top3": ev.top3,
                                "labels": ds.objects, "confusion": ev.confusion.tolist(),
                                "seconds": time.perf_counter() - started})
    if args.bundle_out:
        _save_bundle(args.bundle_out, "pose", net, {"width": args.width, "n_frames": 1, "labels": ds.objects,
                                                   "normalisation": {"low": 500, "high": 650}, "trained_on": source,
                                                   "command": command, "held_out_top1": ev.top1})
        print(f"wrote bundle {args.bundle_out}")
    print(f"done in {time.perf_counter() - started:.0f} s")
    return 0


# -------------------------------------------------------------------------------- correlation
@command("stag-glove-correlation")
def correlation_main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="stag-glove-correlation", description="Decompose grasps into hand-pose and "
                            "object signal; Pearson maps and region CCA of the object signal.")
    _add_data_args(parser)
    parser.add_argument("--png", type=image_file)
    args = parser.parse_args(argv)
    ds, source = _data(args, "object", _recording_check)
    from .decomposition import grasp_segments, object_signal, pearson_map, region_cca
    from .layout import load_layout, mask_from_pressure
    from .plots import correlation_png
    from .processing import normalise

    layout = load_layout()
    mask = mask_from_pressure(ds.pressure)
    if mask.shape != layout.mask.shape or not np.array_equal(mask, layout.mask):
        print("note: the data's sensor mask differs from config/glove/layout.yaml; region labels may not fit")
    signals, segments_total = [], 0
    pressure = normalise(ds.pressure)
    for rec in np.unique(ds.recording_id):
        idx = np.nonzero(ds.recording_id == rec)[0]
        segs = grasp_segments(pressure[idx])
        sig, inside = object_signal(pressure[idx], segs)
        signals.append(sig[inside])
        segments_total += len(segs)
    signal = np.concatenate(signals)
    if len(signal) < 2:
        raise UserError(f"--dataset {source}: {segments_total} grasp(s), {len(signal)} frame(s) of object "
                        f"signal; the correlation needs recordings with grasps")
    print(f"dataset: {source}; {segments_total} grasps found, {len(signal)} frames of object signal")
    refs: list[tuple[str, tuple[int, int]]] = []
    for name in ("thumb_distal", "index_distal", "middle_proximal", "palm"):
        row, col = layout.centroid(name)
        refs.append((name, (int(round(row)), int(round(col)))))
    maps = [(name, pearson_map(signal, mask, ref), ref) for name, ref in refs]
    names, cca = region_cca(signal, layout)
    summary = {n: float(np.nanmean(np.delete(cca[i], i))) for i, n in enumerate(names)}
    for name, value in summary.items():
        print(f"  mean CCA of {name:<16} with the other regions: {value:.2f}")
    if args.png:
        title = f"object signal after removing the hand pose ({source})"
        print(f"wrote {correlation_png(maps, (names, cca), args.png, title)}")
    _write_json(args.out_json, {"command": _command(argv, "stag-glove-correlation"), "dataset": source,
                                "grasps": segments_total, "frames": len(signal), "region_names": names,
                                "cca": cca.tolist(), "mean_cca": summary})
    return 0


COMMANDS = {"make-dataset": make_dataset_main, "train-classifier": train_classifier_main,
            "train-weight": train_weight_main, "train-pose": train_pose_main, "correlation": correlation_main}


def main(argv: list[str] | None = None) -> int:
    """`python -m stag_glove.cli <command> ...`, for a checkout whose console scripts are not installed."""
    argv = sys.argv[1:] if argv is None else argv
    if not argv or argv[0] not in COMMANDS:
        print(f"usage: python -m stag_glove.cli {{{','.join(COMMANDS)}}} [options]", file=sys.stderr)
        return 2
    return COMMANDS[argv[0]](argv[1:])


if __name__ == "__main__":
    sys.exit(main())
