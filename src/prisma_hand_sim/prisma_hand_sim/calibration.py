"""Synthetic calibration sets: pad-model voltages with the ground-truth wrench.

Stands in for the paper's calibration rig (140,000 samples at 100 Hz against an ATI F/T sensor).
Three kinds of trajectory, each starting and ending with the pad unloaded:
- push:  press and release at a random location and speed, normal force with a small shear from
         probe misalignment (a few % of the normal force);
- slide: press, drag the contact across the pad under normal load with kinetic friction
         (coefficient 0.3-0.6, |shear| <= ~1.5 N) along the direction of travel, then release;
- roll:  press, then the contact location rolls along an arc while the load varies, with a small
         rolling-resistance shear, then release.
Wrench rows are (Fx, Fy, Fz) in N and (Tx, Ty, Tz) in N*m about the pad centre: T = r x F with
r = (x, y, 0) the contact location in metres (see pad_model for the frame).
Deterministic: a seed fixes the trajectories and the sensor noise.
"""
from __future__ import annotations

import zipfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from prisma_common.atomic import atomic_output
from prisma_common.hand import counts_to_voltages

from .pad_model import PadModel, PadParams

KINDS = ("push", "slide", "roll")
MAX_SHEAR_N = 1.5
PLACE_MM = 5.5  # contacts are placed within +-PLACE_MM of the centre (pad edge at 7 mm)


@dataclass
class CalibrationSet:
    voltages: np.ndarray  # float32[N, 9]
    wrench: np.ndarray  # float32[N, 6] Fx, Fy, Fz (N), Tx, Ty, Tz (N*m) about the pad centre
    stamp_ns: np.ndarray  # int64[N]
    trajectory: np.ndarray  # int32[N] id of the trajectory each sample belongs to
    kind: np.ndarray  # str[N] "push" | "slide" | "roll"
    contact_mm: np.ndarray | None = None  # float32[N, 2] contact location, NaN when unloaded

    def __post_init__(self) -> None:
        self.voltages = np.asarray(self.voltages, dtype=np.float32)
        self.wrench = np.asarray(self.wrench, dtype=np.float32)
        self.stamp_ns = np.asarray(self.stamp_ns, dtype=np.int64)
        self.trajectory = np.asarray(self.trajectory, dtype=np.int32)
        self.kind = np.asarray(self.kind, dtype=str)
        n = len(self.voltages)
        if self.contact_mm is not None:
            self.contact_mm = np.asarray(self.contact_mm, dtype=np.float32)
        shapes = {"voltages": (self.voltages.shape, (n, 9)), "wrench": (self.wrench.shape, (n, 6)),
                  "stamp_ns": (self.stamp_ns.shape, (n,)), "trajectory": (self.trajectory.shape, (n,)),
                  "kind": (self.kind.shape, (n,))}
        if self.contact_mm is not None:
            shapes["contact_mm"] = (self.contact_mm.shape, (n, 2))
        for name, (got, want) in shapes.items():
            if got != want:
                raise ValueError(f"CalibrationSet.{name} has shape {got}, expected {want}")

    def __len__(self) -> int:
        return len(self.voltages)

    def subset(self, index) -> CalibrationSet:
        return CalibrationSet(self.voltages[index], self.wrench[index], self.stamp_ns[index],
                              self.trajectory[index], self.kind[index],
                              None if self.contact_mm is None else self.contact_mm[index])

    def save(self, path: str | Path) -> None:
        arrays = dict(voltages=self.voltages, wrench=self.wrench, stamp_ns=self.stamp_ns,
                      trajectory=self.trajectory, kind=self.kind)
        if self.contact_mm is not None:
            arrays["contact_mm"] = self.contact_mm
        # written whole or not at all: staged under a temporary name, renamed when complete
        with atomic_output(path) as staged, open(staged, "wb") as f:
            # (mypy matches **arrays against savez_compressed's allow_pickle: bool)
            np.savez_compressed(f, **arrays)  # type: ignore[arg-type]  # a file object: no .npz appended

    @classmethod
    def load(cls, path: str | Path) -> CalibrationSet:
        """A set written by save(); ValueError naming the file if it is anything else."""
        not_a_set = f"{path} is not a calibration set (an .npz written by prisma-tactile-calset)"
        try:
            data = np.load(path, allow_pickle=False)
        except ValueError:
            # numpy tries any file that is neither .npy nor .npz as a pickle, and says so; a
            # pickle is never a calibration set
            raise ValueError(f"{not_a_set}: not a NumPy archive") from None
        except (OSError, EOFError, zipfile.BadZipFile) as exc:
            raise ValueError(f"{not_a_set}: {exc}") from None
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise ValueError(f"{not_a_set}: a single .npy array, not an .npz archive")
        with data:
            missing = {"voltages", "wrench", "stamp_ns", "trajectory", "kind"} - set(data.files)
            if missing:
                raise ValueError(f"{not_a_set}: missing arrays {sorted(missing)}")
            try:
                arrays = {name: data[name] for name in data.files}
            except ValueError:  # object arrays: numpy would need pickle to read them
                raise ValueError(f"{not_a_set}: it holds Python objects, not plain arrays") from None
            except (zipfile.BadZipFile, EOFError, OSError) as exc:  # a truncated or damaged archive
                raise ValueError(f"{not_a_set}: {exc}") from None
        try:
            return cls(arrays["voltages"], arrays["wrench"], arrays["stamp_ns"], arrays["trajectory"],
                       arrays["kind"], arrays.get("contact_mm"))
        except ValueError as exc:
            raise ValueError(f"{not_a_set}: {exc}") from None


@dataclass
class _Track:
    """Per-sample contact of one trajectory (normal 0 = unloaded)."""

    x: np.ndarray
    y: np.ndarray
    fz: np.ndarray
    sx: np.ndarray
    sy: np.ndarray


def _smooth(u: np.ndarray) -> np.ndarray:
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def _ramp_profile(t: np.ndarray, t_on: float, t_up: float, t_hold: float, t_down: float) -> np.ndarray:
    """0 -> 1 over t_up (smooth), hold, 1 -> 0 over t_down; 0 outside."""
    up = _smooth((t - t_on) / t_up)
    down = 1.0 - _smooth((t - t_on - t_up - t_hold) / t_down)
    return np.minimum(up, down)


def _point(rng: np.random.Generator) -> np.ndarray:
    return rng.uniform(-PLACE_MM, PLACE_MM, size=2)


def _push(rng: np.random.Generator, dt: float) -> _Track:
    gap, t_up, t_hold, t_down = (rng.uniform(0.1, 0.5), rng.uniform(0.2, 2.0), rng.uniform(0.0, 1.0),
                                 rng.uniform(0.2, 2.0))
    t = np.arange(0.0, gap + t_up + t_hold + t_down + rng.uniform(0.1, 0.4), dt)
    peak = rng.uniform(0.2, 5.0)
    profile = _ramp_profile(t, gap, t_up, t_hold, t_down)
    # a slow wobble of the press depth, as a hand-driven or compliant probe shows
    wobble = 1.0 + 0.05 * np.sin(2 * np.pi * rng.uniform(0.3, 2.0) * t + rng.uniform(0, 2 * np.pi))
    fz = peak * profile * wobble
    x, y = _point(rng)
    misalign = rng.normal(0.0, 0.04, size=2)  # shear as a fraction of the normal force
    return _Track(np.full_like(t, x), np.full_like(t, y), fz, misalign[0] * fz, misalign[1] * fz)


def _slide(rng: np.random.Generator, dt: float) -> _Track:
    mu = rng.uniform(0.3, 0.6)
    normal = rng.uniform(0.5, min(4.0, MAX_SHEAR_N / mu))
    start = _point(rng)
    for _ in range(20):  # a travel of at least 3 mm
        end = _point(rng)
        if np.hypot(*(end - start)) >= 3.0:
            break
    distance = float(np.hypot(*(end - start)))
    speed = rng.uniform(5.0, 25.0)  # mm/s
    gap, t_press, t_settle = rng.uniform(0.1, 0.5), rng.uniform(0.3, 1.0), rng.uniform(0.0, 0.4)
    t_move, t_rest, t_release = distance / speed, rng.uniform(0.0, 0.5), rng.uniform(0.3, 1.0)
    t = np.arange(0.0, gap + t_press + t_settle + t_move + t_rest + t_release + 0.2, dt)
    move_start = gap + t_press + t_settle
    u = (t - move_start) / t_move
    progress = _smooth(u)
    x = start[0] + progress * (end[0] - start[0])
    y = start[1] + progress * (end[1] - start[1])
    fz = normal * _ramp_profile(t, gap, t_press, t_settle + t_move + t_rest, t_release)
    fz = fz * (1.0 + 0.08 * np.sin(2 * np.pi * rng.uniform(0.5, 2.0) * t))
    # kinetic friction while moving (builds over ~0.15 s of stick), decaying to a residual
    # static shear after the stop; it always scales with the present normal load
    moving = np.clip(np.minimum((t - move_start) / 0.15, 1.0), 0.0, None) * (t <= move_start + t_move)
    after = t > move_start + t_move
    residual = rng.uniform(0.2, 0.6)
    level = np.where(after, residual * np.exp(-(t - move_start - t_move) / 0.3), moving)
    direction = (end - start) / distance
    shear = np.clip(mu * fz * level, 0.0, MAX_SHEAR_N)
    return _Track(x, y, fz, shear * direction[0], shear * direction[1])


def _roll(rng: np.random.Generator, dt: float) -> _Track:
    normal = rng.uniform(0.5, 4.5)
    centre = rng.uniform(-2.0, 2.0, size=2)
    radius = rng.uniform(2.0, 4.0)
    a0 = rng.uniform(0, 2 * np.pi)
    sweep = rng.choice([-1.0, 1.0]) * rng.uniform(0.5, 1.5) * np.pi
    gap, t_press, t_roll, t_release = (rng.uniform(0.1, 0.5), rng.uniform(0.3, 1.0), rng.uniform(1.0, 3.0),
                                       rng.uniform(0.3, 1.0))
    t = np.arange(0.0, gap + t_press + t_roll + t_release + 0.2, dt)
    progress = _smooth((t - gap - t_press) / t_roll)
    angle = a0 + sweep * progress
    x = np.clip(centre[0] + radius * np.cos(angle), -PLACE_MM - 1, PLACE_MM + 1)
    y = np.clip(centre[1] + radius * np.sin(angle), -PLACE_MM - 1, PLACE_MM + 1)
    load = 1.0 + 0.2 * np.sin(np.pi * progress * rng.uniform(1.0, 3.0))
    fz = normal * _ramp_profile(t, gap, t_press, t_roll, t_release) * load
    rolling = (progress > 0) & (progress < 1)
    tangent = np.sign(sweep) * np.stack([-np.sin(angle), np.cos(angle)])
    resistance = rng.uniform(0.02, 0.08) * fz * rolling
    misalign = rng.normal(0.0, 0.03, size=2)
    return _Track(x, y, fz, resistance * tangent[0] + misalign[0] * fz, resistance * tangent[1] + misalign[1] * fz)


_GENERATORS: dict[str, Callable[[np.random.Generator, float], _Track]] = {
    "push": _push, "slide": _slide, "roll": _roll,
}


def wrench_from_contact(x_mm, y_mm, fx, fy, fz) -> np.ndarray:
    """(N, 6) wrench about the pad centre: T = r x F, r = (x, y, 0) in metres."""
    x, y = np.asarray(x_mm) * 1e-3, np.asarray(y_mm) * 1e-3
    fx, fy, fz = np.asarray(fx), np.asarray(fy), np.asarray(fz)
    return np.stack([fx, fy, fz, y * fz, -x * fz, x * fy - y * fx], axis=1)


def generate_calibration_set(n_samples: int = 140_000, seed: int = 0,
                             kinds: Sequence[str] = KINDS, rate_hz: float = 100.0,
                             params: PadParams | None = None) -> CalibrationSet:
    """Concatenated random trajectories of the given kinds (drawn uniformly) totalling exactly
    n_samples at rate_hz, seen through one pad model (hysteresis carries across samples)."""
    kinds = tuple(kinds)
    unknown = set(kinds) - set(KINDS)
    if not kinds or unknown:
        raise ValueError(f"kinds must be a non-empty subset of {KINDS}, got {kinds}")
    if n_samples < 1:
        raise ValueError(f"n_samples must be >= 1, got {n_samples}")
    if rate_hz <= 0:
        raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate_hz
    tracks, kind_of, total = [], [], 0
    while total < n_samples:
        kind = kinds[rng.integers(len(kinds))]
        track = _GENERATORS[kind](rng, dt)
        tracks.append(track)
        kind_of.append(kind)
        total += len(track.fz)
    lengths = np.array([len(tr.fz) for tr in tracks])
    cat = {name: np.concatenate([getattr(tr, name) for tr in tracks])[:n_samples]
           for name in ("x", "y", "fz", "sx", "sy")}
    trajectory = np.repeat(np.arange(len(tracks), dtype=np.int32), lengths)[:n_samples]
    sample_kind = np.repeat(np.array(kind_of), lengths)[:n_samples]

    pad = PadModel(params, seed=seed + 1)  # noise stream distinct from the trajectory stream
    counts = pad.sample_sequence(cat["x"], cat["y"], cat["fz"], cat["sx"], cat["sy"])
    loaded = cat["fz"] > 0
    fx, fy, fz = (np.where(loaded, cat[k], 0.0) for k in ("sx", "sy", "fz"))
    wrench = wrench_from_contact(cat["x"], cat["y"], fx, fy, fz)
    contact = np.where(loaded[:, None], np.stack([cat["x"], cat["y"]], axis=1), np.nan)
    stamp_ns = np.rint(np.arange(n_samples) * (1e9 / rate_hz)).astype(np.int64)
    return CalibrationSet(counts_to_voltages(counts, pad.params.vref), wrench, stamp_ns,
                          trajectory, sample_kind, contact)


def generate_trajectory(kind: str, n_samples: int, seed: int, rate_hz: float = 100.0,
                        params: PadParams | None = None) -> CalibrationSet:
    """n_samples of trajectories of one kind (held-out push and slide tests)."""
    if kind not in KINDS:
        raise ValueError(f"unknown trajectory kind {kind!r}; expected one of {KINDS}")
    return generate_calibration_set(n_samples, seed, (kind,), rate_hz, params)
