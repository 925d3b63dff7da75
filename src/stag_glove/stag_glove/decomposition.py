"""Separating the object signal from the hand-pose signal, and the correlation maps of the STAG
paper (docs/glove.md).

Grasp detection on one recording (pressure [T, rows, cols], normalised):
1. m_t = mean pressure of frame t, smoothed by a Gaussian of sigma 3 frames; r_t = m_t scaled to
   0..1 over the recording (its dynamic range).
2. Candidate grasp peaks: local maxima of r (the largest value in a 5-frame window, where the
   forward gradient changes sign from + to -) with r above 20%.
3. The grasp's onset is the minimum of r in the 20 frames before the peak; it must lie below 20% of
   the dynamic range (the hand was open), else the peak is not a new grasp.
4. The grasp segment grows from the peak, forward and back, up to 80 frames, while r stays above
   half of the peak's value.
5. The hand-pose (empty-hand) frame of that grasp is the onset frame; object signal = frame - onset
   frame (clipped at 0) over the segment.
Correlations: Pearson correlation between sensors of a signal (one map per reference sensor);
canonical correlation (first pair) between hand regions, each region reduced by PCA first so a
region with hundreds of sensors does not overfit the few hundred frames.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from sklearn.cross_decomposition import CCA
from sklearn.decomposition import PCA

from .layout import GloveLayout


@dataclass(frozen=True)
class GraspSegment:
    onset: int   # frame used as the hand-pose (empty-hand) reference
    start: int   # first frame of the grasp (inclusive)
    peak: int
    end: int     # last frame (inclusive)


@dataclass(frozen=True)
class DecompositionConfig:
    sigma_frames: float = 3.0
    peak_window: int = 5
    lookback_frames: int = 20
    low_fraction: float = 0.2
    high_fraction: float = 0.2
    max_expand_frames: int = 80
    stay_above: float = 0.5


def activity(pressure: np.ndarray, sigma_frames: float = 3.0) -> np.ndarray:
    """Smoothed mean pressure per frame."""
    mean = pressure.reshape(pressure.shape[0], -1).mean(axis=1)
    return ndimage.gaussian_filter1d(mean.astype(np.float64), sigma_frames, mode="nearest")


def grasp_segments(pressure: np.ndarray, config: DecompositionConfig = DecompositionConfig()) -> list[GraspSegment]:
    smooth = activity(pressure, config.sigma_frames)
    span = smooth.max() - smooth.min()
    if span <= 0:
        return []
    r = (smooth - smooth.min()) / span
    gradient = np.diff(r, append=r[-1])  # forward gradient
    local_max = ndimage.maximum_filter1d(r, config.peak_window, mode="nearest") == r
    rising_before = np.concatenate([[False], gradient[:-1] > 0])
    peaks = np.nonzero(local_max & rising_before & (gradient <= 0) & (r > config.high_fraction))[0]
    segments: list[GraspSegment] = []
    for peak in peaks:
        lo = max(0, peak - config.lookback_frames)
        onset = lo + int(np.argmin(r[lo:peak])) if peak > lo else peak
        if r[onset] >= config.low_fraction:
            continue  # the hand never opened since the last grasp
        level = config.stay_above * r[peak]
        start = peak
        while start > 0 and peak - start < config.max_expand_frames and r[start - 1] > level and start - 1 > onset:
            start -= 1
        end = peak
        while end + 1 < len(r) and end - peak < config.max_expand_frames and r[end + 1] > level:
            end += 1
        if segments and start <= segments[-1].end:  # overlapping the previous grasp: keep the higher peak
            if r[peak] > r[segments[-1].peak]:
                segments[-1] = GraspSegment(segments[-1].onset, segments[-1].start, int(peak), int(end))
            continue
        segments.append(GraspSegment(int(onset), int(start), int(peak), int(end)))
    return segments


def object_signal(pressure: np.ndarray, segments: list[GraspSegment]) -> tuple[np.ndarray, np.ndarray]:
    """(object signal [T, ...], in-grasp mask [T]): frame minus its grasp's onset frame, clipped
    at 0, inside grasp segments; zero elsewhere."""
    signal = np.zeros_like(pressure, dtype=np.float32)
    inside = np.zeros(pressure.shape[0], bool)
    for seg in segments:
        part = slice(seg.start, seg.end + 1)
        signal[part] = np.clip(pressure[part] - pressure[seg.onset], 0.0, None)
        inside[part] = True
    return signal, inside


def pearson_matrix(signal: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Correlation between every pair of sensors [S, S] over frames (NaN for constant sensors)."""
    x = signal.reshape(signal.shape[0], -1)[:, mask.reshape(-1)].astype(np.float64)
    x = x - x.mean(axis=0)
    norm = np.sqrt((x ** 2).sum(axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        return (x.T @ x) / np.outer(norm, norm)


def pearson_map(signal: np.ndarray, mask: np.ndarray, reference: tuple[int, int]) -> np.ndarray:
    """Correlation of every sensor with the reference sensor, as a [rows, cols] map (NaN off-mask)."""
    if not mask[reference]:
        raise ValueError(f"reference cell {reference} is not a sensor")
    x = signal.reshape(signal.shape[0], -1).astype(np.float64)
    ref = x[:, reference[0] * signal.shape[2] + reference[1]]
    x = x - x.mean(axis=0)
    ref = ref - ref.mean()
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = (x.T @ ref) / (np.sqrt((x ** 2).sum(axis=0)) * np.sqrt((ref ** 2).sum()))
    out = corr.reshape(signal.shape[1:])
    out[~mask] = np.nan
    return out


def region_cca(signal: np.ndarray, layout: GloveLayout, dims: int = 4, seed: int = 0) -> tuple[list[str], np.ndarray]:
    """First canonical correlation between every pair of hand regions [R, R] (diagonal 1)."""
    names = list(layout.region_names)
    flat = signal.reshape(signal.shape[0], -1)
    reduced = []
    for name in names:
        x = flat[:, layout.region_mask(name).reshape(-1)].astype(np.float64)
        k = max(1, min(dims, x.shape[1], x.shape[0] - 1))
        reduced.append(PCA(k, random_state=seed).fit_transform(x) if x.std() > 0 else np.zeros((len(x), 1)))
    out = np.eye(len(names))
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            a, b = reduced[i], reduced[j]
            if a.std() == 0 or b.std() == 0:
                out[i, j] = out[j, i] = np.nan
                continue
            u, v = CCA(n_components=1, max_iter=1000).fit(a, b).transform(a, b)
            out[i, j] = out[j, i] = abs(np.corrcoef(u[:, 0], v[:, 0])[0, 1])
    return names, out
