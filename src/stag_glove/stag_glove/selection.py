"""Choosing the N input frames of the N-frame classifier (docs/glove.md).

Random: the anchor frame plus N-1 frames drawn at random from the same recording.
Cluster: the frames of each recording are embedded with PCA (8 dims), scaled to 0..1, and split into
k = N clusters by k-means; the anchor is joined by one random frame from each of the other N-1
clusters, so the N frames cover different ways the object was held.
"""
from __future__ import annotations

import warnings

import numpy as np
from scipy.cluster.vq import kmeans2

SELECTIONS = ("random", "cluster")
EMBED_DIMS = 8


def check_selection(name: str) -> str:
    if name not in SELECTIONS:
        raise ValueError(f"frame selection must be one of {SELECTIONS}, got {name!r}")
    return name


def pca_scores(flat: np.ndarray, dims: int) -> np.ndarray:
    """Principal-component scores of the rows of `flat` [M, D], the same as sklearn's
    PCA(dims).fit_transform up to the sign of each component. With few frames and many cells
    (M << D) the eigendecomposition of the M x M Gram matrix gives them ~10x faster than an SVD,
    which keeps a live decision inside its time budget (bench glove_classify_n8)."""
    centred = flat - flat.mean(axis=0)
    values, vectors = np.linalg.eigh(centred @ centred.T)
    order = np.argsort(values)[::-1][:dims]
    return vectors[:, order] * np.sqrt(np.clip(values[order], 0.0, None))


def embed(frames: np.ndarray, dims: int = EMBED_DIMS) -> np.ndarray:
    """PCA embedding of frames [M, ...] scaled to 0..1 (as the reference code does)."""
    flat = frames.reshape(frames.shape[0], -1).astype(np.float64)
    dims = max(1, min(dims, flat.shape[0] - 1, flat.shape[1]))
    if flat.shape[0] < 2:
        return np.zeros((flat.shape[0], 1))
    emb = pca_scores(flat, dims)
    span = emb.max() - emb.min()
    return (emb - emb.min()) / span if span > 0 else np.zeros_like(emb)


def kmeans(points: np.ndarray, k: int, seed: int = 0, n_init: int = 10) -> np.ndarray:
    """k-means labels (k-means++ seeding, best of n_init runs by inertia). scipy's kmeans2 is used
    rather than sklearn's KMeans because its per-call overhead is ~10x lower, which matters for
    the live node clustering a small buffer at every decision."""
    rng = np.random.default_rng(seed)
    best, best_inertia = None, np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # an empty cluster is allowed; callers handle fewer clusters
        for _ in range(max(1, n_init)):
            centres, labels = kmeans2(points, k, minit="++", seed=rng)
            inertia = float(((points - centres[labels]) ** 2).sum())
            if inertia < best_inertia:
                best, best_inertia = labels, inertia
    if best is None:  # no run had a finite inertia
        raise ValueError("k-means: no run had a finite inertia (NaN in the points?)")
    return best.astype(np.int64)


def cluster_frames(frames: np.ndarray, k: int, seed: int = 0, n_init: int = 10) -> np.ndarray:
    """Cluster label per frame; k is capped at the number of frames."""
    k = min(k, frames.shape[0])
    if k <= 1:
        return np.zeros(frames.shape[0], dtype=np.int64)
    return kmeans(embed(frames), k, seed, n_init)


def cluster_ids(frames: np.ndarray, recording_id: np.ndarray, pool: np.ndarray, k: int,
                seed: int = 0, n_init: int = 10) -> np.ndarray:
    """Cluster label of every pooled frame, clustering each recording separately (-1 outside pool)."""
    labels = np.full(len(recording_id), -1, dtype=np.int64)
    for rec in np.unique(recording_id[pool]):
        idx = np.nonzero(pool & (recording_id == rec))[0]
        labels[idx] = cluster_frames(frames[idx], k, seed, n_init)
    return labels


def random_tuples(anchors: np.ndarray, pool: np.ndarray, recording_id: np.ndarray, n: int,
                  rng: np.random.Generator) -> np.ndarray:
    """[A, n] frame indices: each anchor and n-1 random pooled frames of its recording."""
    out = np.empty((len(anchors), n), dtype=np.int64)
    out[:, 0] = anchors
    if n == 1:
        return out
    members = _members(pool, recording_id)
    for i, a in enumerate(anchors):
        others = members[recording_id[a]]
        others = others[others != a] if others.size > 1 else others
        out[i, 1:] = rng.choice(others, size=n - 1, replace=others.size < n - 1)
    return out


def cluster_tuples(anchors: np.ndarray, pool: np.ndarray, recording_id: np.ndarray, clusters: np.ndarray,
                   n: int, rng: np.random.Generator) -> np.ndarray:
    """[A, n] frame indices: each anchor plus one random frame from each other cluster of its
    recording (falls back to random frames when a recording has fewer than n clusters)."""
    out = np.empty((len(anchors), n), dtype=np.int64)
    out[:, 0] = anchors
    if n == 1:
        return out
    members = _members(pool, recording_id)
    by_cluster: dict[tuple[int, int], np.ndarray] = {}
    for rec, idx in members.items():
        for c in np.unique(clusters[idx]):
            by_cluster[(rec, int(c))] = idx[clusters[idx] == c]
    for i, a in enumerate(anchors):
        rec, own = recording_id[a], clusters[a]
        chosen: list[np.integer] = []
        for c in sorted({c for (r, c) in by_cluster if r == rec} - {own}):
            if len(chosen) == n - 1:
                break
            candidates = by_cluster[(rec, c)]
            chosen.append(candidates[rng.integers(candidates.size)])
        while len(chosen) < n - 1:
            others = members[rec]
            chosen.append(others[rng.integers(others.size)])
        rng.shuffle(chosen)
        out[i, 1:] = chosen
    return out


def _members(pool: np.ndarray, recording_id: np.ndarray) -> dict[int, np.ndarray]:
    idx = np.nonzero(pool)[0]
    order = np.argsort(recording_id[idx], kind="stable")
    idx = idx[order]
    recs, starts = np.unique(recording_id[idx], return_index=True)
    return {int(r): part for r, part in zip(recs, np.split(idx, starts[1:]))}


def select_from_buffer(frames: np.ndarray, n: int, method: str, rng: np.random.Generator,
                       n_init: int = 3) -> np.ndarray:
    """Indices of n frames from a live buffer (oldest first) for one decision. The newest frame
    is the anchor; cluster selection adds the newest frame of each other cluster, random selection
    adds random distinct frames. Needs at least n frames."""
    check_selection(method)
    m = frames.shape[0]
    if m < n:
        raise ValueError(f"need at least {n} buffered frames, have {m}")
    newest = m - 1
    if n == 1:
        return np.array([newest])
    if method == "random":
        others = rng.choice(newest, size=n - 1, replace=False)
        return np.concatenate([[newest], others])
    labels = cluster_frames(frames, n, seed=int(rng.integers(1 << 31)), n_init=n_init)
    chosen = [newest]
    for c in np.unique(labels):
        if c == labels[newest]:
            continue
        chosen.append(int(np.nonzero(labels == c)[0].max()))  # most recent frame of that cluster
    if len(chosen) < n:  # fewer distinct clusters than n (identical frames): pad with recent ones
        rest = [i for i in range(m - 1, -1, -1) if i not in chosen]
        chosen += rest[:n - len(chosen)]
    return np.array(chosen[:n])
