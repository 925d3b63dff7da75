"""Synthetic STAG glove: a generative model of what the glove reads while a hand grasps objects.

What it models, and why each part is there (the real data has all of it):
- Hand layout: the 548 sensors with their hand regions (config/glove/layout.yaml).
- Hand pose (proprioception): bending a finger presses the glove onto the joint creases, so every
  frame carries a posture signal even without an object. Posture = flexion of the five fingers.
- Objects share grasp types (`synthetic_objects`): a library of grasp primitives (pinch, tripod,
  lateral, power, hook, spherical, flat...) says which regions touch and how the fingers bend. Each
  object uses a few modes drawn from the primitives that fit its size, perturbed per object, plus an
  object-specific contact texture (shape class: sphere blobs, cylinder bands, box edges, thin tip
  contact, soft irregular). So one frame of object A often looks like a frame of object B held the same way;
  the set of modes seen over several frames is what tells them apart. That is why N=1 is hard and
  more frames help.
- Grasp events: the hand closes (ramp), holds with a fluctuating grip, opens, pauses; each event
  picks a mode, drops some contact regions, shifts the object a little inside the hand and varies
  the posture. Heavier objects are gripped harder.
- Sessions differ by glove placement (sub-cell shift of everything), per-sensor gain and baseline;
  train/test split by session, as in the paper.
- Readout: 10-bit counts, baseline below the 500-count knee, soft saturation, ADC noise; non-sensor
  cells are constant (so the mask is recoverable from data). Optional shorted frames (> 950).
- Weight set (recordings given a load): a lift's grip must keep the load from slipping, load /
  (2 friction) between opposed contacts, and people hold a safety margin above that (grip force
  follows load force: Johansson & Westling). That force, spread over the contact and more toward
  the palm, comes on top of the grasp's own grip; a press harder than the skin takes widens the
  contact patch. So a frame's pressure sum follows the weight, blurred by contact area, the object's
  friction and the lift's margin (on the real glove the sum-based baseline is informative too).
  The target for leave-one-object-out regression. Friction has a random stream of its own and the
  margin is drawn in lifts only: recordings without a load (object and pose sets, the live stream)
  do not depend on either.

Durations are in frames of the glove's ~7.3 frames/s. The generator is deterministic for a seed.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage

from prisma_common.hand import FINGERS

from .dataset import SPLIT_TEST, SPLIT_TRAIN, GloveDataset, balance_mask
from .layout import GloveLayout, load_layout
from .synthetic_objects import ObjectSpec, make_objects, region_vector

EMPTY_HAND = "empty_hand"

# Hand-pose classes (the paper's 7 grasps + empty hand); self-contact where fingers touch.
POSES: dict[str, dict] = {
    "empty": dict(flexion=(0.15, 0.2, 0.2, 0.2, 0.2), contact={}),
    "power": dict(flexion=(0.85, 0.95, 0.95, 0.95, 0.95),
                  contact={"index_distal": 0.3, "middle_distal": 0.3, "palm": 0.15}),
    "pinch": dict(flexion=(0.6, 0.65, 0.3, 0.3, 0.3), contact={"thumb_distal": 0.5, "index_distal": 0.5}),
    "tripod": dict(flexion=(0.6, 0.6, 0.6, 0.35, 0.35),
                   contact={"thumb_distal": 0.4, "index_distal": 0.35, "middle_distal": 0.3}),
    "lateral": dict(flexion=(0.4, 0.85, 0.85, 0.85, 0.85), contact={"thumb_distal": 0.4, "index_middle": 0.4}),
    "hook": dict(flexion=(0.15, 0.8, 0.8, 0.8, 0.8), contact={}),
    "point": dict(flexion=(0.7, 0.1, 0.9, 0.9, 0.9), contact={"thumb_distal": 0.2, "middle_middle": 0.2}),
    "spherical": dict(flexion=(0.5, 0.5, 0.5, 0.5, 0.5), contact={}),
}
REST_FLEXION = np.array([0.2, 0.25, 0.25, 0.25, 0.25])


@dataclass(frozen=True)
class SyntheticConfig:
    n_objects: int = 26
    include_empty_hand: bool = True
    sessions: int = 3
    test_sessions: tuple[int, ...] = (2,)       # held-out sessions (by index)
    frames_per_session: int = 180
    modes_per_object: tuple[int, int] = (3, 5)  # inclusive range
    mode_perturbation: float = 0.35             # log-sd of per-object region strength changes
    hold_frames: tuple[int, int] = (3, 10)
    gap_frames: tuple[int, int] = (1, 4)
    region_dropout: float = 0.2                 # chance a touching region misses in one grasp
    object_jitter_cells: float = 0.5            # object position inside the hand, per grasp
    object_drift_cells: float = 0.15            # object movement inside the hand, per frame
    placement_shift_cells: float = 0.6          # glove placement per session (sd)
    gain_spread: float = 0.12                   # per-sensor log gain sd, per session
    baseline_counts: tuple[float, float] = (480.0, 10.0)
    session_baseline_counts: float = 4.0
    noise_counts: float = 3.0
    grip_spread: float = 0.25                   # log-sd of grip per grasp
    crease_gain: float = 0.35                   # posture signal at full flexion (pressure units)
    weight_range_g: tuple[float, float] = (15.0, 1000.0)
    # Lifts (the weight set): a grip holds a load between opposed contacts once it reaches
    # load / (2 friction); people grip with a safety margin above that (Johansson & Westling 1984)
    lift_safety: float = 1.4                    # median grip over the least grip that holds the load
    lift_safety_spread: float = 0.25            # log-sd of the safety margin, per lift
    friction: tuple[float, float] = (0.8, 0.3)  # skin-object friction coefficient: median, log-sd per object
    # pressure summed over the cells per newton of grip; sets the object set's holding grip of a
    # ~100 g object (0.45 over contacts summing to ~35-65) near the ~1 N people use for one
    pressure_per_newton: float = 25.0
    lift_peak_pressure: float = 0.8             # a lift's contact patch widens above this peak pressure
    lift_spread_cells: tuple[float, float] = (3.0, 1.5)  # widest widening: sd along, across the fingers
    short_probability: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        if not 1 <= self.n_objects <= 100:
            raise ValueError(f"n_objects must be 1..100, got {self.n_objects}")
        if self.sessions < 1 or any(not 0 <= s < self.sessions for s in self.test_sessions):
            raise ValueError(f"test_sessions {self.test_sessions} must index sessions 0..{self.sessions - 1}")



@dataclass
class Session:
    shift: tuple[float, float]
    gain: np.ndarray       # [rows, cols]
    baseline: np.ndarray   # [rows, cols] counts
    flexion_offset: np.ndarray  # [5], how this wearer/placement reads posture


@dataclass
class Recording:
    """One recording with its ground truth split into posture and object parts (pressure units)."""

    raw: np.ndarray          # uint16 [T, rows, cols]
    contact: np.ndarray      # bool [T]: object (or self-) contact present
    pose_field: np.ndarray   # float32 [T, rows, cols]
    object_field: np.ndarray  # float32 [T, rows, cols]
    mode: np.ndarray         # int [T], mode index (-1 none)
    level: np.ndarray        # float [T], grasp envelope: 0 open hand, 1 fully held


class SyntheticGlove:
    """Deterministic generator of glove recordings and datasets."""

    def __init__(self, config: SyntheticConfig = SyntheticConfig(), layout: GloveLayout | None = None) -> None:
        self.config = config
        self.layout = layout or load_layout()
        self.rng = np.random.default_rng(config.seed)
        self.shape = self.layout.shape
        self.mask = self.layout.mask
        self.region_names = self.layout.region_names
        self.region_masks = np.stack([self.layout.region_index == i for i in range(len(self.region_names))])
        self.creases = self._crease_maps()
        self.crease_gain = np.exp(self.rng.normal(0.0, 0.2, self.shape))  # this hand's creases
        self.glove_baseline = self.rng.normal(*config.baseline_counts, self.shape)
        # friction from a stream of its own: drawn from self.rng it would change the objects and every
        # recording after them, among them the object and pose sets the shipped bundles learned from
        lift_rng = np.random.default_rng([config.seed, 1])
        self.objects = [replace(o, friction=float(config.friction[0] * np.exp(lift_rng.normal(0, config.friction[1]))))
                        for o in make_objects(config, self.layout, self.region_masks, self.rng)]
        rows = np.arange(self.shape[0])[:, None] / (self.shape[0] - 1)
        self._load_profile = np.broadcast_to(0.3 + 0.7 * rows, self.shape)  # more load toward the palm

    # ------------------------------------------------------------------------------ building
    def _crease_maps(self) -> np.ndarray:
        """[5, rows, cols]: where bending each finger presses the glove (joint creases)."""
        index = self.layout.region_index
        maps = np.zeros((5,) + self.shape)
        rows, cols = self.shape
        palm = self.layout.region_mask("palm")
        for k, finger in enumerate(FINGERS):
            own = np.isin(index, [i for i, n in enumerate(self.region_names) if n.startswith(finger + "_")])
            for r, c in zip(*np.nonzero(own)):
                for dr in (-1, 1):
                    rr = r + dr
                    if 0 <= rr < rows and index[rr, c] != index[r, c]:
                        maps[k, r, c] = 1.0  # a phalanx edge = a joint crease
            cols_used = np.nonzero(own.any(axis=0))[0]
            if finger == "thumb":  # thumb flexion loads the thenar eminence
                thenar = palm & (np.arange(cols)[None, :] >= cols_used.min() - 4)
                maps[k][thenar] = 0.6
            else:  # metacarpophalangeal crease: top palm rows under the finger
                top = np.nonzero(palm.any(axis=1))[0].min()
                maps[k, top:top + 2, cols_used.min():cols_used.max() + 1] = 0.8
            maps[k] = ndimage.gaussian_filter(maps[k], 0.5) * self.mask
            maps[k] /= maps[k].max()
        return maps

    def class_names(self) -> list[str]:
        names = [o.name for o in self.objects]
        return names + [EMPTY_HAND] if self.config.include_empty_hand else names

    def new_session(self) -> Session:
        cfg, rng = self.config, self.rng
        return Session(
            shift=tuple(rng.normal(0, cfg.placement_shift_cells, 2)),
            gain=np.exp(rng.normal(0, cfg.gain_spread, self.shape)),
            baseline=self.glove_baseline + rng.normal(0, cfg.session_baseline_counts, self.shape),
            flexion_offset=rng.normal(0, 0.05, 5),
        )

    # ------------------------------------------------------------------------------ frames
    def _shifted(self, field_: np.ndarray, shift: tuple[float, float]) -> np.ndarray:
        return ndimage.shift(field_, shift, order=1, mode="constant", cval=0.0)

    def contact_field(self, strength: np.ndarray, texture: np.ndarray) -> np.ndarray:
        field_ = np.tensordot(strength, self.region_masks.astype(np.float32), axes=1) * texture
        return ndimage.gaussian_filter(field_, 0.6)

    def pose_field(self, flexion: np.ndarray, creases: np.ndarray) -> np.ndarray:
        amount = self.config.crease_gain * np.clip(flexion, 0, 1.2) ** 1.5
        return (np.tensordot(amount, creases, axes=1)
                + 0.06 * np.tensordot(np.clip(flexion, 0, 1.2), creases > 0.05, axes=1))

    def to_counts(self, pressure: np.ndarray, session: Session) -> np.ndarray:
        """Pressure field(s) -> 10-bit counts with this session's gain/baseline and ADC noise."""
        cfg = self.config
        swing = 150.0 * session.gain * pressure
        counts = session.baseline + 420.0 * np.tanh(swing / 420.0)
        counts = counts + self.rng.normal(0, cfg.noise_counts, counts.shape)
        counts = np.where(self.mask, counts, 0.0)  # non-sensor cells read a constant
        return np.clip(np.rint(counts), 0, 1023).astype(np.uint16)

    def record(self, obj: ObjectSpec | None, session: Session, n_frames: int,
               pose: str | None = None, load_g: float | None = None) -> Recording:
        """A recording of `n_frames`: repeated grasps of `obj` (None = empty hand moving, or a
        hand `pose` held without object). With `load_g` (grams) every grasp lifts that load, as in
        the weight set."""
        cfg, rng = self.config, self.rng
        creases = np.stack([self._shifted(c, session.shift) for c in self.creases])
        pose_out = np.zeros((n_frames,) + self.shape, np.float32)
        object_out = np.zeros((n_frames,) + self.shape, np.float32)
        contact = np.zeros(n_frames, bool)
        mode_out = np.full(n_frames, -1, np.int64)
        level = np.zeros(n_frames)
        rest = REST_FLEXION + session.flexion_offset
        t = 0
        while t < n_frames:
            hold = int(rng.integers(cfg.hold_frames[0], cfg.hold_frames[1] + 1))
            envelope = np.concatenate([[0.35, 0.7], np.ones(hold), [0.7, 0.35]])
            gap = int(rng.integers(cfg.gap_frames[0], cfg.gap_frames[1] + 1))
            base_field = None   # contact field in hand coordinates, placed per frame
            placement = np.asarray(session.shift, dtype=float)
            grip = 1.0
            mode_index = -1
            if obj is not None:
                mode_index = int(rng.choice(len(obj.modes), p=[m.probability for m in obj.modes]))
                mode = obj.modes[mode_index]
                strength = mode.strength * (rng.random(mode.strength.shape) >= cfg.region_dropout)
                if not strength.any():
                    strength = mode.strength
                placement = placement + rng.normal(0, cfg.object_jitter_cells, 2)
                grip = obj.grip * np.exp(rng.normal(0, cfg.grip_spread))
                base_field = self.contact_field(strength, obj.texture)
                if load_g is not None:
                    base_field = self._lift_field(base_field, grip, obj, load_g)
                    grip = 1.0  # part of the lift's pressure
                target = mode.flexion + session.flexion_offset + rng.normal(0, 0.08, 5)
            elif pose is not None:
                spec = POSES[pose]
                target = np.array(spec["flexion"]) + session.flexion_offset + rng.normal(0, 0.08, 5)
                if spec["contact"]:
                    grip = float(np.exp(rng.normal(0, 0.3)))
                    base_field = self.contact_field(region_vector(self.region_names, spec["contact"]),
                                                    np.ones(self.shape, np.float32))
            else:  # empty hand: moving without an object
                target = rng.uniform(0.0, 0.7, 5) + session.flexion_offset
            if pose is not None or obj is None:
                envelope = np.concatenate([envelope, np.zeros(gap)])
                gap = 0
            wobble = 1.0
            for e in envelope:
                if t >= n_frames:
                    break
                wobble = 0.7 * wobble + 0.3 * np.exp(rng.normal(0, 0.12))
                flexion = (rest + (target - rest) * (e if obj is not None or pose is not None else 1.0)
                           + rng.normal(0, 0.03, 5))
                pose_out[t] = self.pose_field(flexion, creases)
                if base_field is not None and e > 0:
                    placement = placement + rng.normal(0, cfg.object_drift_cells, 2)  # the object rolls a little
                    field_ = self._shifted(base_field, tuple(placement))
                    object_out[t] = field_ * grip * e * wobble
                contact[t] = obj is not None and e > 0
                mode_out[t] = mode_index if contact[t] else -1
                level[t] = e
                t += 1
            for _ in range(gap):  # hand open between grasps
                if t >= n_frames:
                    break
                pose_out[t] = self.pose_field(rest + rng.normal(0, 0.05, 5), creases)
                t += 1
        raw = self.to_counts(pose_out + object_out, session)
        if cfg.short_probability > 0:
            for i in np.nonzero(rng.random(n_frames) < cfg.short_probability)[0]:
                r, c = np.argwhere(self.mask)[rng.integers(self.mask.sum())]
                raw[i, r, c] = rng.integers(960, 1024)
        return Recording(raw, contact, pose_out, object_out, mode_out, level)

    def _lift_field(self, contact: np.ndarray, grip: float, obj: ObjectSpec, load_g: float) -> np.ndarray:
        """Pressure of one lift in hand coordinates: the grasp's own grip on `contact` plus the grip
        force that holds the load, spread over the contact with more of it toward the palm."""
        cfg = self.config
        safety = cfg.lift_safety * np.exp(self.rng.normal(0, cfg.lift_safety_spread))
        force = cfg.pressure_per_newton * safety * load_g * 9.81e-3 / (2.0 * obj.friction)
        share = contact * self._load_profile
        share = share / max(float(share.sum()), 1e-12)
        # Pressing harder than the skin takes at the peak widens the contact patch (soft pads, the
        # finger wrapping further, the fabric): without it a heavy load in a small grasp would only
        # saturate a few sensors. Mostly along the finger, whose neighbours across are other fingers.
        spread, step = share, 0
        while force * float(spread.max()) > cfg.lift_peak_pressure and step < 6:
            step += 1
            sigma = tuple(step / 6 * w for w in cfg.lift_spread_cells)
            spread = ndimage.gaussian_filter(share, sigma) * self.mask
            spread = spread / max(float(spread.sum()), 1e-12)
        return contact * grip + spread * force

    # ------------------------------------------------------------------------------ datasets
    def object_dataset(self) -> GloveDataset:
        """Classification set: every class x session is one recording; split by session."""
        cfg = self.config
        classes = self.class_names()
        sessions = [self.new_session() for _ in range(cfg.sessions)]
        parts = []
        recording = 0
        for s, session in enumerate(sessions):
            for k, name in enumerate(classes):
                obj = None if name == EMPTY_HAND else self.objects[k]
                rec = self.record(obj, session, cfg.frames_per_session)
                valid = rec.contact if obj is not None else np.ones(len(rec.raw), bool)
                parts.append((rec.raw, k, recording, s, valid))
                recording += 1
        return self._assemble(parts, classes,
                              np.array([o.weight_g for o in self.objects] + [0.0] * (len(classes) - len(self.objects))))

    def pose_dataset(self, frames_per_session: int | None = None) -> GloveDataset:
        """Hand-pose set: 7 grasp poses + empty hand, no object; split by session."""
        cfg = self.config
        n = frames_per_session or cfg.frames_per_session // 2
        names = list(POSES)
        sessions = [self.new_session() for _ in range(cfg.sessions)]
        parts = []
        recording = 0
        for s, session in enumerate(sessions):
            for k, pose in enumerate(names):
                rec = self.record(None, session, n, pose=pose)
                # label the frames where the pose is (nearly) formed, not the transitions
                held = np.ones(n, bool) if pose == "empty" else rec.level >= 0.7
                parts.append((rec.raw, k, recording, s, held))
                recording += 1
        return self._assemble(parts, names, None)

    def weight_dataset(self, grasps_per_object: int = 6, frames_per_grasp: int = 10) -> GloveDataset:
        """Weight set: each object lifted in several grasps; one recording per object."""
        session = self.new_session()
        parts = []
        cfg = replace(self.config, gap_frames=(0, 0), hold_frames=(frames_per_grasp, frames_per_grasp))
        saved, self.config = self.config, cfg
        try:
            for k, obj in enumerate(self.objects):
                frames = []
                for _ in range(grasps_per_object):
                    rec = self.record(obj, session, frames_per_grasp + 4, load_g=obj.weight_g)
                    frames.append(rec.raw[2:-2])  # the held part of the lift
                raw = np.concatenate(frames)
                parts.append((raw, k, k, 0, np.ones(len(raw), bool)))
        finally:
            self.config = saved
        return self._assemble(parts, [o.name for o in self.objects], np.array([o.weight_g for o in self.objects]),
                              split_by_session=False)

    def _assemble(self, parts, names, weights, split_by_session: bool = True) -> GloveDataset:
        raw = np.concatenate([p[0] for p in parts])
        object_id = np.concatenate([np.full(len(p[0]), p[1]) for p in parts])
        recording_id = np.concatenate([np.full(len(p[0]), p[2]) for p in parts])
        session = np.concatenate([np.full(len(p[0]), p[3]) for p in parts])
        valid = np.concatenate([p[4] for p in parts])
        split = np.where(np.isin(session, self.config.test_sessions), SPLIT_TEST, SPLIT_TRAIN) if split_by_session \
            else np.full(len(raw), SPLIT_TRAIN)
        balanced = balance_mask(object_id, split, valid, self.rng)
        ds = GloveDataset(raw, object_id, recording_id, split, valid, balanced, names, weights)
        ds.extras["session"] = session
        return ds

    # ------------------------------------------------------------------------------ live stream
    def stream(self, episode_frames: int = 60, empty_first: int = 60,
               release_frames: int = 22) -> Iterator[tuple[np.ndarray, str, bool]]:
        """Endless glove stream for the sim backend: (raw frame, class name, contact truth).
        Starts with ~8 s of the empty hand moving through its range (what the empty-hand capture
        should record), then grasps random objects, putting each down for `release_frames` empty-hand
        frames (~3 s) before the next: perception clears its frame buffer on such a release, so
        without it every decision would mix two objects."""
        session = self.new_session()
        classes = self.class_names()
        rec = self.record(None, session, empty_first)
        for frame in rec.raw:
            yield frame, EMPTY_HAND, False
        while True:
            k = int(self.rng.integers(len(self.objects)))
            rec = self.record(self.objects[k], session, episode_frames)
            for frame, touching in zip(rec.raw, rec.contact):
                yield frame, classes[k], bool(touching)
            for frame in self.record(None, session, release_frames).raw:
                yield frame, EMPTY_HAND, False


def default_dataset(seed: int = 0, **overrides) -> GloveDataset:
    return SyntheticGlove(SyntheticConfig(seed=seed, **overrides)).object_dataset()
