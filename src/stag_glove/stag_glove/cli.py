"""Command lines (ROS-free): stag-make-dataset, stag-train-classifier, stag-train-weight,
stag-train-pose, stag-glove-correlation. Each prints progress per epoch and writes its numbers as
JSON, its figures as PNG, and (optionally) a model bundle for the glove_perception node.

Arguments, the dataset file and the output paths are checked before any training (exit 2 with a
one-line message); JSON, figures, datasets and bundles are written under a temporary name and
renamed when complete (an earlier bundle at --bundle-out is replaced, any other directory refused).
What the commands share (options, loading, outputs) is in `cli_common`.
"""
from __future__ import annotations

import sys
import time

import numpy as np

from prisma_common.cli_args import (
    ArgumentParser,
    UserError,
    command,
    image_file,
    non_negative_int,
    output_file,
    positive_int,
)

from .cli_common import (
    DATASET_SUFFIXES,
    add_bundle_out,
    add_data_args,
    check_outputs,
    command_line,
    folds_arg,
    frames_arg,
    load_data,
    recording_check,
    splits_check,
    synthetic_dataset,
    train_config,
    training_parser,
    weights_check,
    write_bundle,
    write_json,
)


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

    ds, text = synthetic_dataset(args.kind, args.seed)
    save_dataset(ds, args.out)
    print(f"wrote {args.out}: {text}, {len(ds.objects)} classes, {ds.has_valid_label.sum()} valid frames")
    return 0


# -------------------------------------------------------------------------------- classifier
@command("stag-train-classifier")
def train_classifier_main(argv: list[str] | None = None) -> int:
    parser = training_parser("stag-train-classifier", "Object classifier: accuracy vs number of input frames N "
                             "(random vs cluster selection) on held-out sessions.", epochs=12, lr_step=8)
    parser.add_argument("--frames", type=frames_arg, default=list(range(1, 9)), help="N values, e.g. 1-8 or 1,2,4")
    parser.add_argument("--seeds", type=non_negative_int, nargs="+", default=[0, 1])
    parser.add_argument("--selection", nargs="+", default=["random", "cluster"], choices=("random", "cluster"))
    parser.add_argument("--mode", default="head", choices=("head", "finetune", "scratch"),
                        help="head: N=1 trained end to end, N>1 warm-started from it with fusion+classifier "
                             "trained on the frozen trunk (CPU); scratch: every N end to end (the paper)")
    parser.add_argument("--head-epochs", type=non_negative_int, default=10)
    parser.add_argument("--finetune-epochs", type=non_negative_int, default=2)
    parser.add_argument("--confusion-png", type=image_file)
    parser.add_argument("--curve-png", type=image_file)
    add_bundle_out(parser, "save the model of the first seed here")
    parser.add_argument("--bundle-frames", type=positive_int, default=8)
    parser.add_argument("--bundle-selection", default="cluster", choices=("random", "cluster"))
    args = parser.parse_args(argv)
    if args.bundle_out and (args.bundle_frames not in args.frames
                            or (args.bundle_frames > 1 and args.bundle_selection not in args.selection)):
        parser.error(f"--bundle-frames {args.bundle_frames} with --bundle-selection {args.bundle_selection} "
                     f"is not trained (--frames {args.frames}, --selection {args.selection}); pick a trained "
                     f"pair")
    check_outputs(args)
    started = time.perf_counter()
    ds, source = load_data(args, "object", splits_check(balanced=True))
    from .experiments import object_experiment, summarise_curve
    from .plots import accuracy_curve_png, confusion_png

    print(f"dataset: {source}; {len(ds.objects)} classes")
    keep = {(args.seeds[0], args.bundle_selection if args.bundle_frames > 1 else "any", args.bundle_frames)}
    results = object_experiment(ds, args.frames, args.seeds, args.selection, train_config(args, args.seeds[0]),
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
    command = command_line(argv, "stag-train-classifier")
    elapsed = time.perf_counter() - started
    write_json(args.out_json, {"command": command, "dataset": source, "seconds": elapsed, "summary": summary,
                                "rows": results.rows})
    if args.bundle_out:
        key = next(iter(keep))
        ev = results.confusions[key]
        write_bundle(args.bundle_out, "object", results.models[key], {
            "width": args.width, "n_frames": args.bundle_frames, "labels": ds.objects,
            "selection": args.bundle_selection, "trained_on": source, "command": command,
            "held_out_top1": ev.top1, "held_out_top3": ev.top3})
    print(f"done in {elapsed:.0f} s")
    return 0


# -------------------------------------------------------------------------------- weight
@command("stag-train-weight")
def train_weight_main(argv: list[str] | None = None) -> int:
    parser = training_parser("stag-train-weight", "Weight regression in log space, leave-one-object-out, "
                             "against the linear baseline a*sum(frame)+b.", epochs=15, lr_step=10)
    parser.add_argument("--folds", type=folds_arg, default=None,
                        help="'all' objects (the default), or a count spread over the weight range")
    parser.add_argument("--png", type=image_file)
    add_bundle_out(parser, "train on every object and save the model here")
    args = parser.parse_args(argv)
    check_outputs(args)
    started = time.perf_counter()
    ds, source = load_data(args, "weight", weights_check)
    from .experiments import default_folds, frames_tensor, weight_experiment
    from .plots import weight_png
    from .training import LinearBaseline, train_weight

    folds = default_folds(ds, args.folds)
    print(f"dataset: {source}; leave-one-object-out over {len(folds)} of {len(ds.objects)} objects")
    cfg = train_config(args)
    rows = weight_experiment(ds, folds, cfg)
    cnn = float(np.mean([r["cnn_error_g"] for r in rows]))
    linear = float(np.mean([r["linear_error_g"] for r in rows]))
    print(f"\n{'object':<12} {'true g':>8} {'CNN err g':>10} {'linear err g':>13}")
    for r in rows:
        print(f"{r['object']:<12} {r['grams']:>8.1f} {r['cnn_error_g']:>10.1f} {r['linear_error_g']:>13.1f}")
    print(f"{'mean':<12} {'':>8} {cnn:>10.1f} {linear:>13.1f}")
    if args.png:
        print(f"wrote {weight_png(rows, args.png)}")
    command = command_line(argv, "stag-train-weight")
    write_json(args.out_json, {"command": command, "dataset": source, "folds": len(folds), "objects": len(ds.objects),
                                "cnn_mean_error_g": cnn, "linear_mean_error_g": linear, "rows": rows,
                                "seconds": time.perf_counter() - started})
    if args.bundle_out:
        import torch

        from .models import WeightNet

        frames = frames_tensor(ds)
        assert ds.weights_g is not None  # weights_check
        grams = ds.weights_g[ds.object_id]
        torch.manual_seed(cfg.seed)
        net = WeightNet(cfg.width, cfg.dropout)
        print("final model on every object:")
        train_weight(net, frames, grams, cfg, print, "[all objects] ")
        base = LinearBaseline.fit(frames.reshape(len(frames), -1).sum(1).numpy(), grams)
        write_bundle(args.bundle_out, "weight", net, {
            "width": cfg.width, "target": "log(grams)",
            "linear_baseline": {"a": base.a, "b": base.b}, "trained_on": source, "command": command,
            "loo_cnn_mean_error_g": cnn, "loo_linear_mean_error_g": linear, "loo_folds": len(folds)})
    print(f"done in {time.perf_counter() - started:.0f} s")
    return 0


# -------------------------------------------------------------------------------- pose
@command("stag-train-pose")
def train_pose_main(argv: list[str] | None = None) -> int:
    parser = training_parser("stag-train-pose", "Hand-pose classifier (7 grasps + empty hand), single frame, "
                             "held-out session.", epochs=15, lr_step=10)
    parser.add_argument("--confusion-png", type=image_file)
    add_bundle_out(parser, "save the model here")
    args = parser.parse_args(argv)
    check_outputs(args)
    started = time.perf_counter()
    ds, source = load_data(args, "pose", splits_check(balanced=False))
    from .experiments import pose_experiment
    from .plots import confusion_png

    print(f"dataset: {source}; poses {ds.objects}")
    net, ev, _ = pose_experiment(ds, train_config(args))
    print(f"held-out session: top-1 {100 * ev.top1:.1f}%, top-3 {100 * ev.top3:.1f}%")
    if args.confusion_png:
        panels = [(f"hand pose, top-1 {100 * ev.top1:.1f}%", ev.confusion)]
        print(f"wrote {confusion_png(panels, ds.objects, args.confusion_png)}")
    command = command_line(argv, "stag-train-pose")
    write_json(args.out_json, {"command": command, "dataset": source, "top1": ev.top1, "top3": ev.top3,
                                "labels": ds.objects, "confusion": ev.confusion.tolist(),
                                "seconds": time.perf_counter() - started})
    if args.bundle_out:
        write_bundle(args.bundle_out, "pose", net, {"width": args.width, "n_frames": 1, "labels": ds.objects,
                                                   "trained_on": source, "command": command,
                                                   "held_out_top1": ev.top1})
    print(f"done in {time.perf_counter() - started:.0f} s")
    return 0


# -------------------------------------------------------------------------------- correlation
@command("stag-glove-correlation")
def correlation_main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="stag-glove-correlation", description="Decompose grasps into hand-pose and "
                            "object signal; Pearson maps and region CCA of the object signal.")
    add_data_args(parser)
    parser.add_argument("--png", type=image_file)
    args = parser.parse_args(argv)
    ds, source = load_data(args, "object", recording_check)
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
    write_json(args.out_json, {"command": command_line(argv, "stag-glove-correlation"), "dataset": source,
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
