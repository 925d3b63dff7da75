"""The paper's experiments on a glove dataset: accuracy vs number of input frames (random vs
cluster selection), leave-one-object-out weight regression against the linear baseline, and the
hand-pose classifier. Used by the stag-train-* command lines; ROS-free.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import torch

from .dataset import SPLIT_TEST, SPLIT_TRAIN, GloveDataset
from .models import TouchNet, WeightNet, init_combination_from_single
from .processing import normalise
from .selection import check_selection, cluster_ids, cluster_tuples, random_tuples
from .training import (
    ClassifierEval,
    LinearBaseline,
    Progress,
    TrainConfig,
    _eval_from_probs,
    evaluate_classifier,
    head_proba,
    predict_grams,
    train_classifier,
    train_head,
    train_weight,
    trunk_features,
)

MODES = ("head", "finetune", "scratch")


def frames_tensor(ds: GloveDataset) -> torch.Tensor:
    return torch.from_numpy(normalise(ds.pressure))


@dataclass
class Split:
    """Pools (any valid frame may join a tuple) and anchors (valid and balanced) per split."""

    train_pool: np.ndarray
    test_pool: np.ndarray
    train_anchors: np.ndarray
    test_anchors: np.ndarray

    @classmethod
    def of(cls, ds: GloveDataset, balanced: bool = True) -> Split:
        train_pool = ds.has_valid_label & (ds.split_id == SPLIT_TRAIN)
        test_pool = ds.has_valid_label & (ds.split_id == SPLIT_TEST)
        anchor = ds.is_balanced if balanced else np.ones(len(ds), bool)
        split = cls(train_pool, test_pool, np.nonzero(train_pool & anchor)[0], np.nonzero(test_pool & anchor)[0])
        if not len(split.train_anchors) or not len(split.test_anchors):
            raise ValueError(f"dataset needs valid frames in both splits; train anchors {len(split.train_anchors)}, "
                             f"test anchors {len(split.test_anchors)}")
        return split


@dataclass
class ObjectResults:
    rows: list[dict] = field(default_factory=list)      # seed, selection, n, top1, top3
    histories: dict = field(default_factory=dict)
    confusions: dict = field(default_factory=dict)      # (seed, selection, n) -> ClassifierEval
    models: dict = field(default_factory=dict)          # (seed, selection, n) -> TouchNet

    def mean_top1(self, selection: str, n: int) -> float:
        values = [r["top1"] for r in self.rows if r["n"] == n and r["selection"] in (selection, "any")]
        return float(np.mean(values)) if values else float("nan")


class TupleDrawer:
    """Draws N-frame tuples around anchor frames: at random, or one frame per k-means cluster of the
    anchor's recording (the clusters computed once per N over the whole pool, then reused)."""

    def __init__(self, ds: GloveDataset, frames: np.ndarray, pool: np.ndarray, progress: Progress | None) -> None:
        self.ds = ds
        self.frames = frames
        self.pool = pool
        self.progress = progress
        self.clusters: dict[int, np.ndarray] = {}

    def draw(self, selection: str, n: int, anchors: np.ndarray, pool_mask: np.ndarray,
             rng: np.random.Generator) -> np.ndarray:
        recordings = self.ds.recording_id
        if selection == "random" or n == 1:
            return random_tuples(anchors, pool_mask, recordings, n, rng)
        if n not in self.clusters:
            started = time.perf_counter()
            self.clusters[n] = cluster_ids(self.frames, recordings, self.pool, n, seed=n)
            _log(self.progress, f"  k-means with k={n} on {len(np.unique(recordings[self.pool]))} recordings "
                                f"({time.perf_counter() - started:.1f} s)")
        return cluster_tuples(anchors, pool_mask, recordings, self.clusters[n], n, rng)


@dataclass
class ObjectRun:
    """What every network of one object experiment shares: the data, its split and how to train."""

    ds: GloveDataset
    frames: torch.Tensor
    split: Split
    tuples: TupleDrawer
    mode: str
    head_epochs: int
    finetune_epochs: int
    progress: Progress | None

    @property
    def labels(self) -> np.ndarray:
        return self.ds.object_id

    @property
    def n_classes(self) -> int:
        return len(self.ds.objects)


def object_experiment(ds: GloveDataset, n_values=tuple(range(1, 9)), seeds=(0, 1),
                      selections=("random", "cluster"), config: TrainConfig = TrainConfig(),
                      mode: str = "head", head_epochs: int = 15, finetune_epochs: int = 2,
                      keep_models: set | None = None, progress: Progress | None = print) -> ObjectResults:
    """Top-1/top-3 on held-out sessions for every (seed, selection, N).

    mode 'scratch' trains every N end to end from scratch (the paper). 'head' trains the 1-frame
    network end to end, then for N > 1 warm-starts the N-frame network from it (the fusion conv
    starts as the average of the branches) and trains the fusion conv and classifier on the frozen
    trunk; 'finetune' does the same warm start and then trains everything end to end for
    `finetune_epochs`. The last two exist so the whole curve fits a CPU budget."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    for s in selections:
        check_selection(s)
    n_values = sorted(set(int(n) for n in n_values))
    if n_values[0] < 1:
        raise ValueError(f"N must be >= 1, got {n_values}")
    frames = frames_tensor(ds)
    split = Split.of(ds)
    run = ObjectRun(ds, frames, split, TupleDrawer(ds, frames.numpy(), split.train_pool | split.test_pool, progress),
                    mode, head_epochs, finetune_epochs, progress)
    results = ObjectResults()
    keep_models = keep_models or set()
    for seed in seeds:
        cfg = TrainConfig(**{**config.__dict__, "seed": seed})
        single, hist, ev = _train_single_frame(run, cfg)
        results.histories[(seed, "any", 1)] = hist
        _record(results, seed, "any", 1, ev, mode, cfg, keep_models, single)
        features = trunk_features(single, frames) if mode == "head" else None
        for selection in selections:
            for n in n_values:
                if n == 1:
                    continue
                started = time.perf_counter()
                tag = f"[seed {seed} {selection} N={n}] "
                net, hist, ev, warm = _train_n_frames(run, cfg, selection, n, single, features, tag)
                results.histories[(seed, selection, n)] = hist
                _record(results, seed, selection, n, ev, mode, cfg, keep_models, net)
                if warm is not None:
                    results.rows[-1].update(warm_top1=warm.top1, warm_top3=warm.top3)
                _log(progress, f"{tag}held-out top-1 {100 * ev.top1:.1f}% top-3 {100 * ev.top3:.1f}% "
                               f"({time.perf_counter() - started:.1f} s)")
    return results


def _train_single_frame(run: ObjectRun, cfg: TrainConfig) -> tuple[TouchNet, list[dict], ClassifierEval]:
    """The 1-frame network, trained end to end: the N=1 point and the trunk the others start from."""
    split, labels = run.split, run.labels
    torch.manual_seed(cfg.seed)
    single = TouchNet(run.n_classes, 1, cfg.width, cfg.dropout)
    test1 = split.test_anchors[:, None]
    _log(run.progress, f"[seed {cfg.seed}] N=1: training the {cfg.width}-wide trunk end to end "
                       f"on {len(split.train_anchors)} frames, testing on {len(test1)} held-out-session frames")
    hist = train_classifier(single, run.frames, lambda e: (split.train_anchors[:, None], labels[split.train_anchors]),
                            cfg, run.progress,
                            lambda m: evaluate_classifier(m, run.frames, test1, labels[split.test_anchors]),
                            label=f"[seed {cfg.seed} N=1] ")
    return single, hist, evaluate_classifier(single, run.frames, test1, labels[split.test_anchors])


def _train_n_frames(run: ObjectRun, cfg: TrainConfig, selection: str, n: int, single: TouchNet,
                    features: torch.Tensor | None, tag: str
                    ) -> tuple[TouchNet, list[dict], ClassifierEval, ClassifierEval | None]:
    """One N-frame network in the run's mode; returns it, its history, its held-out evaluation and,
    in mode 'head', the warm start's evaluation (branches averaged, before training)."""
    split, labels, frames = run.split, run.labels, run.frames
    test_tuples = run.tuples.draw(selection, n, split.test_anchors, split.test_pool,
                                  np.random.default_rng(10_000 + 97 * cfg.seed + n))
    test_labels = labels[split.test_anchors]
    train_rng = np.random.default_rng(20_000 + 97 * cfg.seed + n)

    def make(epoch: int) -> tuple[np.ndarray, np.ndarray]:
        tuples = run.tuples.draw(selection, n, split.train_anchors, split.train_pool, train_rng)
        return tuples, labels[split.train_anchors]

    def evaluate(m: TouchNet) -> ClassifierEval:
        return evaluate_classifier(m, frames, test_tuples, test_labels)

    net = TouchNet(run.n_classes, n, cfg.width, cfg.dropout)
    if run.mode == "scratch":
        hist = train_classifier(net, frames, make, cfg, run.progress, evaluate, tag)
        return net, hist, evaluate(net), None
    init_combination_from_single(net, single)
    if features is None:  # mode "finetune"
        ft_cfg = TrainConfig(**{**cfg.__dict__, "epochs": run.finetune_epochs})
        hist = train_classifier(net, frames, make, ft_cfg, run.progress, evaluate, tag)
        return net, hist, evaluate(net), None
    warm = _eval_from_probs(head_proba(net, features, test_tuples), test_labels, run.n_classes)
    if run.head_epochs == 0:  # the warm start alone
        return net, [], warm, warm
    head_cfg = TrainConfig(**{**cfg.__dict__, "epochs": run.head_epochs, "noise_std": 0.0})
    hist = train_head(net, features, make, head_cfg, run.progress, None, tag)
    return net, hist, _eval_from_probs(head_proba(net, features, test_tuples), test_labels, run.n_classes), warm


def _record(results: ObjectResults, seed, selection, n, ev: ClassifierEval, mode, cfg, keep, model) -> None:
    results.rows.append({"seed": seed, "selection": selection, "n": n, "top1": ev.top1, "top3": ev.top3,
                         "mode": mode, "width": cfg.width, "epochs": cfg.epochs})
    results.confusions[(seed, selection, n)] = ev
    if (seed, selection, n) in keep:
        results.models[(seed, selection, n)] = model


def summarise_curve(results: ObjectResults, selections=("random", "cluster")) -> list[dict]:
    """Mean and spread over seeds per (selection, N); N=1 is shared by both selections."""
    out = []
    ns = sorted({r["n"] for r in results.rows})
    for selection in selections:
        for n in ns:
            rows = [r for r in results.rows if r["n"] == n and r["selection"] in (selection, "any")]
            if rows:
                top1 = np.array([r["top1"] for r in rows])
                top3 = np.array([r["top3"] for r in rows])
                row = {"selection": selection, "n": n, "top1": float(top1.mean()), "top1_std": float(top1.std()),
                       "top3": float(top3.mean()), "seeds": len(rows)}
                warm = [r.get("warm_top1", r["top1"] if n == 1 else None) for r in rows]
                known = [w for w in warm if w is not None]
                if len(known) == len(warm):
                    row["warm_top1"] = float(np.mean(known))
                out.append(row)
    return out


# ---------------------------------------------------------------------------------------- weight
def default_folds(ds: GloveDataset, count: int | None) -> list[int]:
    """Objects to hold out: all of them, or `count` spread evenly over the weight range."""
    objects = np.unique(ds.object_id)
    if count is None or count >= len(objects):
        return [int(o) for o in objects]
    if ds.weights_g is None:
        raise ValueError("folds spread over the weight range need a dataset with per-object weights")
    by_weight = objects[np.argsort(ds.weights_g[objects])]
    pick = np.round(np.linspace(0, len(by_weight) - 1, count)).astype(int)
    return [int(by_weight[i]) for i in pick]


def weight_experiment(ds: GloveDataset, folds: list[int], config: TrainConfig = TrainConfig(),
                      progress: Progress | None = print) -> list[dict]:
    """Leave-one-object-out: per held-out object, the CNN's and the linear baseline's mean
    absolute error in grams over that object's frames."""
    if ds.weights_g is None:
        raise ValueError("weight experiment needs a dataset with per-object weights")
    frames = frames_tensor(ds)
    sums = frames.reshape(len(frames), -1).sum(1).numpy()
    grams = ds.weights_g[ds.object_id]
    rows = []
    for i, obj in enumerate(folds):
        started = time.perf_counter()
        test = ds.object_id == obj
        train = ~test
        torch.manual_seed(config.seed)
        net = WeightNet(config.width, config.dropout)
        tag = f"[fold {i + 1}/{len(folds)}: {ds.objects[obj]} {ds.weights_g[obj]:.0f} g] "
        train_idx = torch.from_numpy(np.nonzero(train)[0])
        test_idx = torch.from_numpy(np.nonzero(test)[0])
        # (the lambda runs inside train_weight, within this iteration)
        train_weight(net, frames[train_idx], grams[train], config, progress, tag,
                     lambda m: float(np.mean(np.abs(predict_grams(m, frames[test_idx]) - grams[test]))))  # noqa: B023
        cnn = predict_grams(net, frames[test_idx])
        linear = LinearBaseline.fit(sums[train], grams[train]).predict(sums[test])
        row = {"object": ds.objects[obj], "grams": float(ds.weights_g[obj]),
               "cnn_error_g": float(np.mean(np.abs(cnn - grams[test]))),
               "cnn_median_pred_g": float(np.median(cnn)),
               "linear_error_g": float(np.mean(np.abs(linear - grams[test]))),
               "linear_median_pred_g": float(np.median(linear)),
               "frames": int(test.sum())}
        rows.append(row)
        _log(progress, f"{tag}CNN error {row['cnn_error_g']:.1f} g, linear {row['linear_error_g']:.1f} g "
                       f"({time.perf_counter() - started:.1f} s)")
    return rows


# ---------------------------------------------------------------------------------------- pose
def pose_experiment(ds: GloveDataset, config: TrainConfig = TrainConfig(), progress: Progress | None = print
                    ) -> tuple[TouchNet, ClassifierEval, list[dict]]:
    """Single-frame hand-pose classifier, held-out session."""
    frames = frames_tensor(ds)
    split = Split.of(ds, balanced=False)
    torch.manual_seed(config.seed)
    net = TouchNet(len(ds.objects), 1, config.width, config.dropout)
    test = split.test_anchors[:, None]
    hist = train_classifier(net, frames, lambda e: (split.train_anchors[:, None], ds.object_id[split.train_anchors]),
                            config, progress,
                            lambda m: evaluate_classifier(m, frames, test, ds.object_id[split.test_anchors]),
                            label="[pose] ")
    return net, evaluate_classifier(net, frames, test, ds.object_id[split.test_anchors]), hist


def _log(progress: Progress | None, text: str) -> None:
    if progress is not None:
        progress(text)
