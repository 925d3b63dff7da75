"""A STAG glove session through the glove cores, recorded as glove_driver and glove_perception publish it.

A scripted user session of the synthetic glove (`stag_glove.synthetic.SyntheticGlove`, one
wearer/placement, the configured share of shorted frames): ~8 s of the empty hand moving, then for
each object a grasp recording of 60 frames followed by ~3 s of open, empty hand (the release that
clears perception's buffer, > `release_frames`), paced at the glove's `frame_rate_hz`. The grasps
hold the object without lifting it (the object set's kind of recording): /stag/weight, learned on
lifts, has no load to read here and says so in the plot (docs/glove.md, "Weight"). It is polled
at the driver's `poll_rate_hz` by `GloveDriver` with the node's frame processing. After the
empty-hand phase the session calls `capture_empty_hand()`, as a user calls `~/capture_empty_hand`.
Every processed frame goes to `GlovePerception` with the bundles of
config/glove_perception.yaml, as the perception node's subscription would. Messages come from the
glove converters: /stag/frame + /stag/image for every frame, /stag/hand_pose for every non-shorted
frame, /stag/weight for contact frames, /stag/object once N contact frames are buffered, and the
driver's /diagnostics once per second.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from prisma_common.bag import BagWriter
from prisma_common.diagnostics import diagnostics_to_msg
from prisma_common.typestore import types as typestore_types
from stag_glove.backend import BackendFrame, BackendStatus
from stag_glove.bundle import load_bundle
from stag_glove.glove_driver_core import GloveDriver
from stag_glove.glove_perception_core import GlovePerception, PerceptionConfig, limit_threads
from stag_glove.layout import load_layout
from stag_glove.node_config import GloveDriverConfig, GlovePerceptionConfig
from stag_glove.processing import FrameProcessor, NormalisationConfig
from stag_glove.ros_conversions import estimate_to_msg, glove_frame_to_msg, pressure_image_msg, weight_to_msg
from stag_glove.synthetic import EMPTY_HAND, SyntheticConfig, SyntheticGlove

NS = 1_000_000_000
EMPTY_FIRST_FRAMES = 60  # the sim stream's empty-hand phase (SyntheticGlove.stream)
GRASP_FRAMES = 60  # frames of repeated grasps of one object
RELEASE_FRAMES = 22  # ~3 s of empty hand after each object (perception clears after 15)
EPISODE_FRAMES = GRASP_FRAMES + RELEASE_FRAMES
# what the weight columns and panel read in this session (its grasps hold each object, none lifts it)
NO_LIFT = "no lift in this session: the weight estimates have no load to read (both were fitted on lifts)"
WEIGHT_NOTE = (f"{NO_LIFT}, so /stag/weight reads about 24 g and the linear baseline about 110 g whatever is "
               "held, not its true weight (docs/glove.md, \"Weight\")")

FRAME, IMAGE = "/stag/frame", "/stag/image"
OBJECT, HAND_POSE, WEIGHT = "/stag/object", "/stag/hand_pose", "/stag/weight"
DIAGNOSTICS = "/diagnostics"
GLOVE_TOPICS = {
    FRAME: "prisma_msgs/msg/GloveFrame",
    IMAGE: "sensor_msgs/msg/Image",
    OBJECT: "prisma_msgs/msg/ObjectEstimate",
    HAND_POSE: "prisma_msgs/msg/ObjectEstimate",
    WEIGHT: "prisma_msgs/msg/WeightEstimate",
    DIAGNOSTICS: "diagnostic_msgs/msg/DiagnosticArray",
}


class SessionGloveBackend:
    """A GloveBackend playing a scripted session of the synthetic glove at the glove's frame rate;
    `truth` is (object in hand, object touching) of the frame last returned."""

    def __init__(self, objects: int, rate_hz: float, seed: int, short_probability: float) -> None:
        self.glove = SyntheticGlove(SyntheticConfig(seed=seed, short_probability=short_probability))
        rng = np.random.default_rng(seed)
        picks = rng.choice(len(self.glove.objects), size=min(objects, len(self.glove.objects)), replace=False)
        self.objects = [self.glove.objects[int(i)] for i in picks]
        self.total_frames = EMPTY_FIRST_FRAMES + len(self.objects) * EPISODE_FRAMES
        self._frames = self._script()
        self._period_ns = int(round(NS / rate_hz))
        self._next_ns: int | None = None
        self.frames_sent = 0
        self.truth: tuple[str, bool] = (EMPTY_HAND, False)
        self._truths: list[tuple[str, bool]] = []

    def _script(self):
        session = self.glove.new_session()
        empty = self.glove.record(None, session, EMPTY_FIRST_FRAMES)
        yield from ((raw, EMPTY_HAND, False) for raw in empty.raw)
        for obj in self.objects:
            # no load: handling the object then lifting it in the same contact episode puts lifted
            # frames, unlike anything the object bundle learned, into the buffer of its last
            # decision (19/26 objects instead of 22/26), and lifting throughout costs more (13/26)
            grasp = self.glove.record(obj, session, GRASP_FRAMES)
            yield from ((raw, obj.name, bool(c)) for raw, c in zip(grasp.raw, grasp.contact))
            release = self.glove.record(None, session, RELEASE_FRAMES, pose="empty")
            yield from ((raw, EMPTY_HAND, False) for raw in release.raw)

    def poll(self, now_ns: int) -> list[BackendFrame]:
        if self._next_ns is None:
            self._next_ns = now_ns
        out = []
        while self._next_ns <= now_ns and self.frames_sent < self.total_frames:
            raw, name, touching = next(self._frames)
            self.truth = (name, touching)
            out.append(BackendFrame(self._next_ns, self.frames_sent & 0xFFFF, np.asarray(raw, dtype=np.uint16)))
            self._next_ns += self._period_ns
            self.frames_sent += 1
        return out

    def status(self) -> BackendStatus:
        return BackendStatus(True, "simulated glove session", {"frames": str(self.frames_sent)})

    def take_errors(self) -> list[str]:
        return []  # no link to lose

    def close(self) -> None:
        pass


@dataclass
class GloveFrameRecord:
    """Per glove frame: truth from the synthetic stream and what perception said."""

    stamp_ns: int
    truth: str
    truth_contact: bool
    mean_pressure: float
    shorted: bool
    contact: bool
    object_label: str | None = None
    object_confidence: float = float("nan")
    pose_label: str | None = None
    weight_g: float = float("nan")
    baseline_g: float = float("nan")


@dataclass
class GloveRecording:
    frames: list[GloveFrameRecord] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)
    capture_message: str = ""
    capture_ok: bool = False
    reason: str = ""
    object_weights_g: dict[str, float] = field(default_factory=dict)
    bundles: dict[str, str] = field(default_factory=dict)
    # the weight bundle's linear baseline, grams = a * sum(pressure) + b, least squares over the
    # weight set's lifts: their grip grows with the load, so the sum carries the weight, blurred by
    # contact area and friction (docs/glove.md, "Weight"). This session's grasps carry no load.
    baseline_a_b: tuple[float, float] = (0.0, 0.0)


def run_glove_session(writer: BagWriter, objects: int = 4, seed: int | None = None,
                      progress: Callable[[str], None] | None = None,
                      types: Callable[[str], Any] = typestore_types) -> GloveRecording:
    """Empty hand, then `objects` grasps; returns the per-frame record (messages go to `writer`)."""
    if objects < 1:
        raise ValueError(f"objects must be >= 1, got {objects}")
    driver_cfg = GloveDriverConfig()
    perception_cfg = GlovePerceptionConfig()
    seed = driver_cfg.sim_seed if seed is None else seed
    limit_threads(perception_cfg.threads)
    mask = load_layout(driver_cfg.layout_file).mask if driver_cfg.layout_file else None
    processor = FrameProcessor(NormalisationConfig(driver_cfg.normalisation_low, driver_cfg.normalisation_high,
                                                   driver_cfg.short_threshold, driver_cfg.contact_margin), mask=mask)
    backend = SessionGloveBackend(objects, driver_cfg.frame_rate_hz, seed, driver_cfg.sim_short_probability)
    driver = GloveDriver(backend, processor, driver_cfg.empty_hand_frames, driver_cfg.stale_timeout, None,
                         "glove_driver", f"sim/seed{seed}")
    bundles = {kind: load_bundle(getattr(perception_cfg, f"{kind}_bundle"), kind)
               for kind in ("object", "pose", "weight")}
    perception = GlovePerception(bundles["object"], bundles["pose"], bundles["weight"],
                                 PerceptionConfig(perception_cfg.selection, perception_cfg.buffer_size,
                                                  perception_cfg.release_frames, perception_cfg.kmeans_restarts,
                                                  perception_cfg.seed))
    line = bundles["weight"].metadata.get("linear_baseline") or {}
    rec = GloveRecording(bundles={k: str(b.path) for k, b in bundles.items()},
                         object_weights_g={o.name: float(o.weight_g) for o in backend.glove.objects},
                         baseline_a_b=(float(line.get("a", 0.0)), float(line.get("b", 0.0))))
    frame_id = driver_cfg.frame_id

    def write(topic: str, msg: Any) -> None:
        writer.write(topic, msg)
        rec.counts[topic] = rec.counts.get(topic, 0) + 1

    total = backend.total_frames
    poll_ns = int(round(NS / driver_cfg.poll_rate_hz))
    diagnostics_ns = int(round(driver_cfg.diagnostics_period * NS))
    next_diagnostics = 0
    t = 0
    episode = -1
    while backend.frames_sent < total:
        for frame in driver.poll(t):
            truth, touching = backend.truth
            write(FRAME, glove_frame_to_msg(types, frame, frame_id))
            write(IMAGE, pressure_image_msg(frame, types, frame_id))
            item = GloveFrameRecord(frame.stamp_ns, truth, bool(touching), float(frame.pressure.mean()),
                                    bool(frame.shorted), bool(frame.contact))
            out = perception.update(frame)
            if out.pose is not None:
                write(HAND_POSE, estimate_to_msg(types, out.pose, frame.stamp_ns, frame_id))
                item.pose_label = out.pose.label
            if out.weight is not None:
                write(WEIGHT, weight_to_msg(types, out.weight, frame.stamp_ns, frame_id))
                item.weight_g, item.baseline_g = out.weight.grams, out.weight.baseline_grams
            if out.object is not None:
                write(OBJECT, estimate_to_msg(types, out.object, frame.stamp_ns, frame_id))
                item.object_label, item.object_confidence = out.object.label, out.object.confidence
            rec.frames.append(item)
            n = len(rec.frames)
            if n == EMPTY_FIRST_FRAMES:
                # the user holds the hand empty and calls ~/capture_empty_hand
                result = driver.capture_empty_hand()
                rec.capture_ok, rec.capture_message = result.success, result.message
                if progress:
                    progress(f"t={t / NS:.1f}s empty-hand capture: {result.message}")
            elif n > EMPTY_FIRST_FRAMES and (n - EMPTY_FIRST_FRAMES - 1) // EPISODE_FRAMES != episode:
                episode = (n - EMPTY_FIRST_FRAMES - 1) // EPISODE_FRAMES
                if progress:
                    progress(f"t={t / NS:.1f}s grasp {episode + 1}/{objects}: {truth}")
        if t >= next_diagnostics:
            next_diagnostics = t + diagnostics_ns
            write(DIAGNOSTICS, diagnostics_to_msg(types, t, driver.diagnostics(t)))
        t += poll_ns
    driver.close()
    rec.reason = "session_complete" if rec.capture_ok else "no_empty_hand_capture"
    return rec


# ------------------------------------------------------------------------------------------------
# Summary and plot


def episodes(rec: GloveRecording) -> list[dict]:
    """One row per grasped object: truth, the last object decision while it was held, median weight."""
    rows = []
    grasps = rec.frames[EMPTY_FIRST_FRAMES:]
    for start in range(0, len(grasps), EPISODE_FRAMES):
        part = grasps[start:start + GRASP_FRAMES]
        truth = part[0].truth
        decisions = [f.object_label for f in part if f.object_label is not None]
        weights = [f.weight_g for f in part if np.isfinite(f.weight_g)]
        baselines = [f.baseline_g for f in part if np.isfinite(f.baseline_g)]
        poses = [f.pose_label for f in part if f.pose_label is not None and f.contact]
        rows.append({
            "truth": truth,
            "decision": decisions[-1] if decisions else None,
            "correct": bool(decisions) and decisions[-1] == truth,
            "decisions": len(decisions),
            "contact_frames": sum(f.contact for f in part),
            "shorted_frames": sum(f.shorted for f in part),
            "true_weight_g": rec.object_weights_g.get(truth),
            "weight_g": float(np.median(weights)) if weights else None,
            "baseline_weight_g": float(np.median(baselines)) if baselines else None,
            "pose": max(set(poses), key=poses.count) if poses else None,
        })
    return rows


def summarise(rec: GloveRecording) -> dict:
    rows = episodes(rec)
    frames = rec.frames
    empty = frames[:EMPTY_FIRST_FRAMES]
    return {
        "scenario": "glove",
        "reason": rec.reason,
        "success": rec.capture_ok,
        "frames": len(frames),
        "duration_s": (frames[-1].stamp_ns - frames[0].stamp_ns) / NS if frames else 0.0,
        "shorted_frames": sum(f.shorted for f in frames),
        "contact_frames": sum(f.contact for f in frames),
        "empty_hand_capture": rec.capture_message,
        "empty_hand_contact_frames_before_capture": sum(f.contact for f in empty),
        "grasps": rows,
        "weight_note": WEIGHT_NOTE,
        "object_correct": sum(r["correct"] for r in rows),
        "object_accuracy": sum(r["correct"] for r in rows) / len(rows) if rows else None,
        "bundles": rec.bundles,
    }


def plot(rec: GloveRecording, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    frames = rec.frames
    t = np.array([f.stamp_ns for f in frames]) / NS
    labels = sorted({f.truth for f in frames} | {f.object_label for f in frames if f.object_label})
    # the grasped objects first, in order of appearance, then the other labels decisions used
    order = list(dict.fromkeys([f.truth for f in frames if f.truth != EMPTY_HAND] + labels))
    y_of = {name: i for i, name in enumerate(order)}
    fig, axes = plt.subplots(3, 1, figsize=(10, 8.5), sharex=True, gridspec_kw={"height_ratios": [1, 1.3, 1]},
                             layout="constrained")
    ax = axes[0]
    ax.plot(t, [f.mean_pressure for f in frames], "k", lw=1, label="mean pressure")
    contact = np.array([f.contact for f in frames])
    ax.fill_between(t, 0, 1, where=contact, transform=ax.get_xaxis_transform(), color="tab:green", alpha=0.15,
                    label="contact (vs empty-hand max)")
    shorted = [f.stamp_ns / NS for f in frames if f.shorted]
    if shorted:
        ax.plot(shorted, np.zeros(len(shorted)), "rx", label="shorted frame (dropped)")
    capture_t = frames[EMPTY_FIRST_FRAMES - 1].stamp_ns / NS if len(frames) >= EMPTY_FIRST_FRAMES else None
    if capture_t is not None:
        for a in axes:
            a.axvline(capture_t, color="0.3", ls=":", lw=1)
        ax.annotate("empty-hand capture", (capture_t, ax.get_ylim()[1]), fontsize=8, rotation=90, va="top",
                    ha="right")
    ax.set_ylabel("pressure (0..1)")
    ax.legend(loc="upper left", fontsize=8)
    ax = axes[1]
    truth_y = [y_of[f.truth] if f.truth in y_of else np.nan for f in frames]
    ax.step(t, truth_y, where="post", color="0.5", lw=3, alpha=0.6, label="object in hand (truth)")
    decided = [(f.stamp_ns / NS, y_of[f.object_label], f.object_confidence) for f in frames if f.object_label]
    if decided:
        dt, dy, dc = zip(*decided)
        points = ax.scatter(dt, dy, c=dc, cmap="viridis", vmin=0, vmax=1, s=10, label="/stag/object")
        fig.colorbar(points, ax=list(axes), pad=0.01, fraction=0.02, label="/stag/object confidence")
    ax.set_yticks(range(len(order)))
    ax.set_yticklabels(order, fontsize=7)
    ax.set_ylabel("object")
    ax.legend(loc="upper left", fontsize=8)
    ax = axes[2]
    true_w = [rec.object_weights_g.get(f.truth, np.nan) if f.truth != EMPTY_HAND else np.nan for f in frames]
    ax.plot(t, true_w, color="0.5", lw=3, alpha=0.6, label="true weight")
    ax.plot(t, [f.weight_g for f in frames], ".", ms=3, color="tab:blue", label="/stag/weight grams (CNN)")
    a, b = rec.baseline_a_b
    ax.plot(t, [f.baseline_g for f in frames], ".", ms=3, color="tab:orange",
            label=f"linear baseline {a:.2f} g x sum(pressure) {b:+.0f} g (least squares over the weight set)")
    # both estimates learned lifts, whose grip carries the weight; these grasps carry none
    ax.set_title(NO_LIFT, fontsize=9, loc="left")
    ax.set_ylabel("weight (g)")
    ax.set_xlabel("time (s)")
    shown = [w for f in frames for w in (f.weight_g, f.baseline_g)] + true_w
    top = np.nanmax(shown) if np.isfinite(shown).any() else 1.0
    ax.set_ylim(0, 1.45 * top)  # a band above the points for the legend
    ax.legend(loc="upper left", fontsize=8, ncol=2)
    summary = summarise(rec)
    fig.suptitle(f"glove session: {summary['object_correct']}/{len(summary['grasps'])} objects recognised, "
                 f"{summary['shorted_frames']} shorted frames dropped")
    fig.savefig(path, dpi=100)
    plt.close(fig)
