"""Command lines (ROS-free): stag-make-dataset, stag-train-classifier, stag-train-weight,
stag-train-pose, stag-glove-correlation. Each prints progress per epoch and writes its numbers as
JSON, its figures as PNG, and (optionally) a model bundle for the glove_perception node."""
from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from pathlib import Path

import numpy as np

from .dataset import GloveDataset, load_dataset, save_dataset



def limit_threads(threads: int) -> None:
    from .perception import limit_threads as limit

    limit(threads)


def _command(argv: list[str] | None, prog: str) -> str:
    """The command line as run, less --out-json (where the numbers went is no part of the recipe)."""
    args = list(sys.argv[1:] if argv is None else argv)
    if "--out-json" in args:
        i = args.index("--out-json")
        del args[i:i + 2]
    return " ".join([prog] + [shlex.quote(a) for a in args])


def _add_data_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--dataset", type=Path, help="metadata.mat (MATLAB v5/v7.3) or .h5; default: synthetic")
    parser.add_argument("--synthetic-seed", type=int, default=0, help="seed of the synthetic glove (no --dataset)")
    parser.add_argument("--threads", type=int, default=1, help="torch/BLAS threads (default 1)")
    parser.add_argument("--out-json", type=Path, help="write the numbers here")


def _add_train_args(parser: argparse.ArgumentParser, epochs: int, lr_step: int) -> None:
    parser.add_argument("--width", type=int, default=16, help="trunk width (paper: 64)")
    parser.add_argument("--epochs", type=int, default=epochs)
    parser.add_argument("--lr-step", type=int, default=lr_step, help="x0.1 learning rate every this many epochs (paper: 100)")
    parser.add_argument("--batch-size", type=int, default=32)
    parser.add_argument("--noise", type=float, default=0.015, help="Gaussian noise on training inputs")


def _train_config(args, seed: int = 0):
    from .training import TrainConfig

    return TrainConfig(width=args.width, epochs=args.epochs, lr_step_epochs=args.lr_step, batch_size=args.batch_size,
                       noise_std=args.noise, seed=seed, threads=args.threads)


def _synthetic(kind: str, seed: int) -> tuple[GloveDataset, str]:
    from .synthetic import SyntheticConfig, SyntheticGlove

    glove = SyntheticGlove(SyntheticConfig(seed=seed))
    ds = {"object": glove.object_dataset, "pose": glove.pose_dataset, "weight": glove.weight_dataset}[kind]()
    return ds, f"synthetic glove, seed {seed}, {kind} set ({len(ds)} frames)"


def _data(args, kind: str) -> tuple[GloveDataset, str]:
    if args.dataset is not None:
        return load_dataset(args.dataset), str(args.dataset)
    return _synthetic(kind, args.synthetic_seed)


def _write_json(path: Path | None, data: dict) -> None:
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(data, indent=2) + "\n")
        print(f"wrote {path}")


def _frames_arg(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        if "-" in part:
            lo, hi = part.split("-")
            out += list(range(int(lo), int(hi) + 1))
        else:
            out.append(int(part))
    if not out or min(out) < 1:
        raise argparse.ArgumentTypeError(f"frame counts must be >= 1, got {text!r}")
    return out


# -------------------------------------------------------------------------------- make dataset
def make_dataset_main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="stag-make-dataset", description="Write a synthetic glove dataset "
                                     "(metadata.mat fields) as .mat (MATLAB v5) or .h5.")
    parser.add_argument("out", type=Path)
    parser.add_argument("--kind", choices=("object", "pose", "weight"), default="object")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    ds, text = _synthetic(args.kind, args.seed)
    save_dataset(ds, args.out)
    print(f"wrote {args.out}: {text}, {len(ds.objects)} classes, {ds.has_valid_label.sum()} valid frames")
    return 0


# -------------------------------------------------------------------------------- classifier
def train_classifier_main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="stag-train-classifier", description="Object classifier: accuracy vs "
                                     "number of input frames N (random vs cluster selection) on held-out sessions.")
    _add_data_args(parser)
    _add_train_args(parser, epochs=12, lr_step=8)
    parser.add_argument("--frames", type=_frames_arg, default=list(range(1, 9)), help="N values, e.g. 1-8 or 1,2,4")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--selection", nargs="+", default=["random", "cluster"], choices=("random", "cluster"))
    parser.add_argument("--mode", default="head", choices=("head", "finetune", "scratch"),
                        help="head: N=1 trained end to end, N>1 warm-started from it with fusion+classifier "
                             "trained on the frozen trunk (CPU); scratch: every N end to end (the paper)")
    parser.add_argument("--head-epochs", type=int, default=10)
    parser.add_argument("--finetune-epochs", type=int, default=2)
    parser.add_argument("--confusion-png", type=Path)
    parser.add_argument("--curve-png", type=Path)
    parser.add_argument("--bundle-out", type=Path, help="save the model of the first seed here")
    parser.add_argument("--bundle-frames", type=int, default=8)
    parser.add_argument("--bundle-selection", default="cluster", choices=("random", "cluster"))
    args = parser.parse_args(argv)
    limit_threads(args.threads)
    from .experiments import object_experiment, summarise_curve
    from .plots import accuracy_curve_png, confusion_png

    started = time.perf_counter()
    ds, source = _data(args, "object")
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
        title = f"held-out sessions, trunk width {args.width}, {args.epochs} epochs, mode {args.mode}, seeds {args.seeds}"
        print(f"wrote {accuracy_curve_png(summary, args.curve_png, title)}")
    command = _command(argv, "stag-train-classifier")
    elapsed = time.perf_counter() - started
    _write_json(args.out_json, {"command": command, "dataset": source, "seconds": elapsed, "summary": summary,
                                "rows": results.rows})
    if args.bundle_out:
        key = next(iter(keep))
        if key not in results.models:
            parser.error(f"--bundle-frames {args.bundle_frames} with --bundle-selection {args.bundle_selection} "
                         f"was not trained (frames {args.frames}, selection {args.selection})")
        from .bundle import save_bundle

        ev = results.confusions[key]
        save_bundle(args.bundle_out, "object", results.models[key], {
            "width": args.width, "n_frames": args.bundle_frames, "labels": ds.objects,
            "selection": args.bundle_selection, "normalisation": {"low": 500, "high": 650},
            "trained_on": source, "command": command, "held_out_top1": ev.top1, "held_out_top3": ev.top3})
        print(f"wrote bundle {args.bundle_out}")
    print(f"done in {elapsed:.0f} s")
    return 0


# -------------------------------------------------------------------------------- weight
def train_weight_main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="stag-train-weight", description="Weight regression in log space, "
                                     "leave-one-object-out, against the linear baseline a*sum(frame)+b.")
    _add_data_args(parser)
    _add_train_args(parser, epochs=15, lr_step=10)
    parser.add_argument("--folds", default="all", help="'all' objects, or a count spread over the weight range")
    parser.add_argument("--png", type=Path)
    parser.add_argument("--bundle-out", type=Path, help="train on every object and save the model here")
    args = parser.parse_args(argv)
    limit_threads(args.threads)
    from .experiments import default_folds, frames_tensor, weight_experiment
    from .plots import weight_png
    from .training import LinearBaseline, train_weight

    started = time.perf_counter()
    ds, source = _data(args, "weight")
    folds = default_folds(ds, None if args.folds == "all" else int(args.folds))
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

        from .bundle import save_bundle
        from .models import WeightNet

        frames = frames_tensor(ds)
        grams = ds.weights_g[ds.object_id]
        torch.manual_seed(cfg.seed)
        net = WeightNet(cfg.width, cfg.dropout)
        print("final model on every object:")
        train_weight(net, frames, grams, cfg, print, "[all objects] ")
        base = LinearBaseline.fit(frames.reshape(len(frames), -1).sum(1).numpy(), grams)
        save_bundle(args.bundle_out, "weight", net, {
            "width": cfg.width, "normalisation": {"low": 500, "high": 650}, "target": "log(grams)",
            "linear_baseline": {"a": base.a, "b": base.b}, "trained_on": source, "command": command,
            "loo_cnn_mean_error_g": cnn, "loo_linear_mean_error_g": linear, "loo_folds": len(folds)})
        print(f"wrote bundle {args.bundle_out}")
    print(f"done in {time.perf_counter() - started:.0f} s")
    return 0


# -------------------------------------------------------------------------------- pose
def train_pose_main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="stag-train-pose", description="Hand-pose classifier (7 grasps + empty "
                                     "hand), single frame, held-out session.")
    _add_data_args(parser)
    _add_train_args(parser, epochs=15, lr_step=10)
    parser.add_argument("--confusion-png", type=Path)
    parser.add_argument("--bundle-out", type=Path)
    args = parser.parse_args(argv)
    limit_threads(args.threads)
    from .experiments import pose_experiment
    from .plots import confusion_png

    started = time.perf_counter()
    ds, source = _data(args, "pose")
    print(f"dataset: {source}; poses {ds.objects}")
    net, ev, _ = pose_experiment(ds, _train_config(args))
    print(f"held-out session: top-1 {100 * ev.top1:.1f}%, top-3 {100 * ev.top3:.1f}%")
    if args.confusion_png:
        print(f"wrote {confusion_png([(f'hand pose, top-1 {100 * ev.top1:.1f}%', ev.confusion)], ds.objects, args.confusion_png)}")
    command = _command(argv, "stag-train-pose")
    _write_json(args.out_json, {"command": command, "dataset": source, "top1": ev.top1, "top3": ev.top3,
                                "labels": ds.objects, "confusion": ev.confusion.tolist(),
                                "seconds": time.perf_counter() - started})
    if args.bundle_out:
        from .bundle import save_bundle

        save_bundle(args.bundle_out, "pose", net, {"width": args.width, "n_frames": 1, "labels": ds.objects,
                                                   "normalisation": {"low": 500, "high": 650}, "trained_on": source,
                                                   "command": command, "held_out_top1": ev.top1})
        print(f"wrote bundle {args.bundle_out}")
    print(f"done in {time.perf_counter() - started:.0f} s")
    return 0


# -------------------------------------------------------------------------------- correlation
def correlation_main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="stag-glove-correlation", description="Decompose grasps into hand-pose and "
                                     "object signal; Pearson maps and region CCA of the object signal.")
    _add_data_args(parser)
    parser.add_argument("--png", type=Path)
    args = parser.parse_args(argv)
    limit_threads(args.threads)
    from .decomposition import grasp_segments, object_signal, pearson_map, region_cca
    from .layout import load_layout, mask_from_pressure
    from .plots import correlation_png
    from .processing import normalise

    ds, source = _data(args, "object")
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
    print(f"dataset: {source}; {segments_total} grasps found, {len(signal)} frames of object signal")
    refs = [(name, tuple(int(round(v)) for v in layout.centroid(name)))
            for name in ("thumb_distal", "index_distal", "middle_proximal", "palm")]
    maps = [(name, pearson_map(signal, mask, ref), ref) for name, ref in refs]
    names, cca = region_cca(signal, layout)
    summary = {n: float(np.nanmean(np.delete(cca[i], i))) for i, n in enumerate(names)}
    for name, value in summary.items():
        print(f"  mean CCA of {name:<16} with the other regions: {value:.2f}")
    if args.png:
        print(f"wrote {correlation_png(maps, (names, cca), args.png, f'object signal after removing the hand pose ({source})')}")
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
