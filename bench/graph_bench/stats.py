"""Figures from a probe's Recording (latencies per hop, dropped and handled scans, stale statuses)
and from repeated runs (median and spread)."""
from __future__ import annotations

import math

import numpy as np

from graph_bench.facts import GRASP
from graph_bench.probe import Recording
from prisma_common.hand import FINGERS

EMPTY = np.array([], dtype=np.int64)


def percentiles(ms: np.ndarray) -> dict:
    """n, p50, p90, p99 and max of latencies in ms."""
    if len(ms) == 0:
        return {"n": 0}
    p = np.percentile(ms, [50, 90, 99])
    return {"n": int(len(ms)), "p50_ms": round(float(p[0]), 3), "p90_ms": round(float(p[1]), 3),
            "p99_ms": round(float(p[2]), 3), "max_ms": round(float(ms.max()), 3)}


def median_spread(values: list) -> dict:
    """Median, min, max and count of the values that are numbers (None and nan left out)."""
    v = [x for x in values if x is not None and not (isinstance(x, float) and math.isnan(x))]
    if not v:
        return {"median": None}
    return {"median": round(float(np.median(v)), 3), "min": round(float(min(v)), 3),
            "max": round(float(max(v)), 3), "runs": len(v)}


def _in_windows(stamps: np.ndarray, windows: list[tuple[int, int]]) -> np.ndarray:
    mask = np.zeros(len(stamps), dtype=bool)
    for lo, hi in windows:
        mask |= (stamps >= lo) & (stamps <= hi)
    return mask


def latencies(rec: Recording, windows: list[tuple[int, int]]) -> tuple[dict, dict]:
    """(stats, samples in ms) of the hops, for samples stamped inside `windows`."""
    samples: dict[str, np.ndarray] = {}
    hops = {"contact_received": ("contact", "receive"), "contact_published": ("contact", "publish"),
            "wrench_received": ("wrench", "receive"), "wrench_published": ("wrench", "publish"),
            "taxels_published": ("taxels", "publish")}
    for key, (suffix, when) in hops.items():
        chunks, per_finger = [], {}
        for f in FINGERS:
            topic = f"/prisma/{f}/{suffix}"
            if topic not in rec.stamps:
                continue
            stamps = rec.stamps[topic]
            times = (rec.receive if when == "receive" else rec.publish)[topic]
            mask = _in_windows(stamps, windows)
            ms = (times[mask] - stamps[mask]) / 1e6
            chunks.append(ms)
            per_finger[f] = ms
        samples[key] = np.concatenate(chunks) if chunks else np.array([])
        if key == "contact_received":
            samples.update({f"contact_received/{f}": v for f, v in per_finger.items()})
    return {k: percentiles(v) for k, v in samples.items()}, samples


def move_latency_real(rec: Recording, grasps: list[dict]) -> tuple[np.ndarray, dict]:
    """Per grasp: the index wrench that reached finger_force and the MoveMotors goal it caused (the
    first goal accepted after it whose feedback shows the thumb flexing), acceptance - taxel stamp.
    Also how many grasps had no such wrench (ended before) or no such goal."""
    stamps = rec.stamps.get("/prisma/index/wrench", EMPTY)
    fz = rec.index_fz if rec.index_fz is not None else np.array([])
    # velocities are in the goal's motor order: fingers, thumb_flexion, thumb_rotation
    thumb_goals = sorted(accept for gid, accept in rec.goals.items()
                         if any(len(fb.velocities) > 1 and fb.velocities[1] > 1.0
                                for fb in rec.feedback.get(gid, [])))
    out, counts = [], {"grasps_without_trigger": 0, "triggers_without_goal": 0}
    for g in grasps:
        if not g["accepted"]:
            continue
        hits = np.nonzero((stamps >= g["accept_ns"]) & (stamps <= g["end_ns"]) & (fz >= GRASP["finger_force"]))[0]
        if len(hits) == 0:
            counts["grasps_without_trigger"] += 1
            continue
        trigger = int(stamps[hits].min())
        after = [a for a in thumb_goals if trigger <= a <= g["end_ns"]]
        if not after:
            counts["triggers_without_goal"] += 1
            continue
        out.append((after[0] - trigger) / 1e6)
    return np.array(out), counts


def move_latency_relay(rec: Recording) -> np.ndarray:
    """Per relay goal: its acceptance - the taxel stamp it carries (echoed in its first feedback)."""
    out = []
    for gid, accept in rec.goals.items():
        fbs = rec.feedback.get(gid)
        if fbs and len(fbs[0].positions) >= 2:
            trigger = int(fbs[0].positions[0]) * 1_000_000_000 + int(fbs[0].positions[1])
            out.append((accept - trigger) / 1e6)
    return np.array(out)


def drops(rec: Recording, lo: int, hi: int, rate_hz: float) -> dict:
    """Taxel samples stamped in [lo, hi] against the wrench / contact samples of the same stamps."""
    out: dict[str, float] = {"taxels": 0, "dropped_wrench": 0, "dropped_contact": 0, "scan_gaps": 0}
    received = []
    for f in FINGERS:
        t = rec.stamps.get(f"/prisma/{f}/taxels", EMPTY)
        t = np.unique(t[(t >= lo) & (t <= hi)])
        out["taxels"] += len(t)
        received.append(len(t) / ((hi - lo) / 1e9))
        for kind in ("wrench", "contact"):
            other = rec.stamps.get(f"/prisma/{f}/{kind}", EMPTY)
            out[f"dropped_{kind}"] += int(len(np.setdiff1d(t, other)))
        if f == FINGERS[0] and len(t) > 1:
            out["scan_gaps"] = int(np.sum(np.diff(t) > 1.5e9 / rate_hz))  # scans the driver did not make
    out["received_hz"] = round(float(np.mean(received)), 1)
    return out


def stamps_in_all(rec: Recording, topics: list[str], lo: int, hi: int) -> int:
    """How many header stamps in [lo, hi] every one of `topics` carries: the scans (frames) that went
    through each hop whose outputs these are. One dropped on the way anywhere is not counted."""
    common: np.ndarray | None = None
    for topic in topics:
        s = rec.stamps.get(topic, EMPTY)
        s = np.unique(s[(s >= lo) & (s <= hi)])
        common = s if common is None else np.intersect1d(common, s)
    return 0 if common is None else int(len(common))


def handled_scans(rec: Recording, lo: int, hi: int) -> int:
    """Scans stamped in [lo, hi] with a WrenchStamped and a ContactState for every finger."""
    return stamps_in_all(rec, [f"/prisma/{f}/{kind}" for f in FINGERS for kind in ("wrench", "contact")], lo, hi)


def stale_statuses(rec: Recording, lo: int, hi: int) -> list[str]:
    """/diagnostics statuses at WARN or above that say "stale", stamped in [lo, hi]."""
    return sorted({f"{name}: {message}" for stamp, name, level, message in rec.diagnostics
                   if lo <= stamp <= hi and level >= 1 and "stale" in message.lower()})
