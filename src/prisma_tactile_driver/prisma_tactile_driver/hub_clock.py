"""Stamps from the hub's clock: sequence numbers -> host-time stamps, without ROS.

The hub scans on its own timer (firmware `HUB_RATE_HZ`, 100 Hz) and numbers its frames (uint16,
+1 per frame, wrapping). The host sees them late and in bursts: a USB-serial adapter holds bytes
up to its latency timer (16 ms by default on FTDI), and the driver drains the port at its own
poll rate, so every frame of one read shares one receive time. Frame k was sent at
t0 + k * period on the hub's clock; it is received at that instant plus a latency that is never
below some minimum. So the lower envelope of `receive - k * period` is the hub's clock expressed
in host time (plus the minimum latency), and stamps taken from that line are evenly spaced,
distinct, and free of USB bursts and poll jitter.

- Anchor: the first batch after a start, a reconnect (`reanchor`), a hub restart (the sequence
  jumps backwards) or a jump that the line cannot explain (a frame more than `reanchor_ns`
  before its predicted stamp, or all frames later than that for `late_confirm_ns`) sets the line
  through the newest frame's receive time.
- Offset: the lowest point of `receive - line` over the current window of `window_frames` frames
  and the `offset_windows` windows before it (one until the period is fitted); a latency that
  grows for good is taken up that many windows later.
- Drift: the hub's oscillator (a Nano's ceramic resonator is good to about +-0.5 %) is not the
  host's. The slope of the window minima over the last `slope_windows` windows (least squares)
  corrects the period; it survives re-anchors, because the oscillator is the same.
- Slew: published stamps continue at the estimated period and are steered toward the line by at
  most `slew` periods per frame, so consecutive stamps differ from the estimated period by at
  most that (0.2 ms at 100 Hz) while the estimate moves; only an anchor steps them.

A stamp cannot be better than the receive times it is built from: with a 500 Hz drain and a hub
whose period is a whole number of drain periods, the lowest latency seen can sit up to one drain
period (2 ms) above the true one; USB bursts at a fixed cadence likewise hide where in the burst
period a frame was sent. `update` is pure: it returns a new `HubClockState` and never reads a
clock.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .protocol import SEQUENCE_MODULO

FIRMWARE_RATE_HZ = 100  # HUB_RATE_HZ in firmware/prisma_fingertip_hub/prisma_fingertip_hub.ino
NOMINAL_PERIOD_NS = 1_000_000_000 // FIRMWARE_RATE_HZ


@dataclass(frozen=True)
class HubClockConfig:
    period_ns: float = NOMINAL_PERIOD_NS  # the firmware's nominal scan period
    sequence_modulo: int = SEQUENCE_MODULO
    window_frames: int = 100  # one minimum per this many frames (1 s at 100 Hz)
    offset_windows: int = 4  # completed windows the offset looks back over (with the current one)
    slope_windows: int = 30  # window minima the period fit uses (30 s at 100 Hz)
    min_fit_windows: int = 3  # fewer minima: keep the previous period estimate
    max_skew: float = 0.02  # |estimated period / nominal - 1| is clamped to this
    slew: float = 0.02  # steering per frame, at most this fraction of a period
    reanchor_ns: int = 100_000_000  # a frame this far off its predicted stamp...
    late_confirm_ns: int = 500_000_000  # ...late for this long (or early once) re-anchors

    def __post_init__(self) -> None:
        if not self.period_ns > 0:
            raise ValueError(f"period_ns must be > 0, got {self.period_ns}")
        if self.sequence_modulo < 4:
            raise ValueError(f"sequence_modulo must be >= 4, got {self.sequence_modulo}")
        for name in ("window_frames", "offset_windows", "slope_windows", "min_fit_windows"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.min_fit_windows > self.slope_windows:
            raise ValueError(f"min_fit_windows ({self.min_fit_windows}) must be <= slope_windows "
                             f"({self.slope_windows})")
        if not 0 <= self.max_skew < 0.5:
            raise ValueError(f"max_skew must be in [0, 0.5), got {self.max_skew}")
        if not 0 < self.slew < 1:
            raise ValueError(f"slew must be in (0, 1), got {self.slew}")
        if self.reanchor_ns <= 0 or self.late_confirm_ns < 0:
            raise ValueError(f"need reanchor_ns > 0 and late_confirm_ns >= 0, got {self.reanchor_ns}, "
                             f"{self.late_confirm_ns}")


@dataclass(frozen=True)
class HubClockState:
    """Everything the estimator remembers. A frame's index counts hub periods since the anchor;
    a point (index, y) is y = receive_ns - anchor_ns - index * nominal period, in ns."""

    skew: float = 0.0  # estimated period / nominal - 1 (kept across anchors: same oscillator)
    last_sequence: int | None = None
    anchor_ns: int | None = None  # None: the next batch anchors
    last_index: int = 0  # index of the last frame stamped
    last_stamp_ns: int = 0  # its stamp
    minima: tuple[tuple[int, float], ...] = ()  # lowest point of each completed window, oldest first
    window_min: tuple[int, float] | None = None  # lowest point of the current window
    late_since_ns: int | None = None  # receive time of the first of a run of late batches
    # counters
    frames: int = 0
    dropped: int = 0  # sequence numbers skipped: frames the hub sent that never arrived intact
    restarts: int = 0  # the sequence went backwards: the hub restarted
    anchors: int = 0  # the first anchor included


@dataclass(frozen=True)
class StampResult:
    state: HubClockState
    stamps_ns: tuple[int, ...]  # one per sequence number given, in order
    dropped: int  # sequence numbers skipped before and between this batch's frames
    anchored: bool  # the batch (re-)anchored the clock


DEFAULT_CONFIG = HubClockConfig()


def estimated_period_ns(state: HubClockState, config: HubClockConfig = DEFAULT_CONFIG) -> float:
    return config.period_ns * (1.0 + state.skew)


def reanchor(state: HubClockState) -> HubClockState:
    """Forget the anchor and the sequence (after a reconnect: opening the port may have reset the
    hub); the period estimate and the counters stay."""
    return replace(state, last_sequence=None, anchor_ns=None, minima=(), window_min=None,
                   late_since_ns=None)


def update(state: HubClockState, sequences: list[int], receive_ns: int,
           config: HubClockConfig = DEFAULT_CONFIG) -> StampResult:
    """Stamp the frames of one read: `sequences` in arrival order, all received by `receive_ns`."""
    if len(sequences) == 0:
        return StampResult(state, (), 0, False)
    modulo = config.sequence_modulo
    w = _Working(**state.__dict__)
    stamps: list[int] = []
    dropped = 0
    anchored = False
    # a hub restart splits the batch: each part is stamped on its own anchor
    segment: list[int] = []  # frame offsets from the part's first frame (gaps included)
    gap_before = 0  # sequence numbers skipped between the previous frame and the part
    restart = False
    last = state.last_sequence
    for seq in sequences:
        seq = int(seq) % modulo
        step = None if last is None else (seq - last) % modulo
        if step is not None and (step == 0 or step >= modulo // 2):  # went backwards (or repeated)
            if segment:
                part, n_dropped, did_anchor = _stamp_part(w, segment, gap_before, restart, receive_ns, config)
                stamps += part
                dropped += n_dropped
                anchored |= did_anchor
                segment = []
            restart, step = True, None
        if not segment:
            segment = [0]
            gap_before = 0 if step is None else step - 1
        else:
            assert step is not None  # only a part's first frame has no step
            segment.append(segment[-1] + step)
        last = seq
    part, n_dropped, did_anchor = _stamp_part(w, segment, gap_before, restart, receive_ns, config)
    stamps += part
    dropped += n_dropped
    anchored |= did_anchor
    w.last_sequence = last
    return StampResult(HubClockState(**w.__dict__), tuple(stamps), dropped, anchored)


@dataclass
class _Working:
    """A mutable copy of HubClockState for the duration of one update."""

    skew: float
    last_sequence: int | None
    anchor_ns: int | None
    last_index: int
    last_stamp_ns: int
    minima: tuple[tuple[int, float], ...]
    window_min: tuple[int, float] | None
    late_since_ns: int | None
    frames: int
    dropped: int
    restarts: int
    anchors: int


def _stamp_part(w: _Working, offsets: list[int], gap_before: int, restart: bool, receive_ns: int,
                config: HubClockConfig) -> tuple[list[int], int, bool]:
    """Stamp consecutive frames (no restart among them) received by receive_ns."""
    period = config.period_ns
    dropped = gap_before + offsets[-1] - (len(offsets) - 1)
    w.dropped += dropped
    w.frames += len(offsets)
    w.restarts += restart
    anchor = w.anchor_ns is None or restart
    if not anchor:
        indices = [w.last_index + gap_before + 1 + o for o in offsets]
        predicted = w.last_stamp_ns + (indices[-1] - w.last_index) * period * (1.0 + w.skew)
        error = receive_ns - predicted
        if error < -config.reanchor_ns:
            anchor = True  # sent before the line says it could have been: the line is wrong
        elif error > config.reanchor_ns:
            # late: a stall of the link passes, a hub that stopped counting stays late
            if w.late_since_ns is None:
                w.late_since_ns = receive_ns
            anchor = receive_ns - w.late_since_ns >= config.late_confirm_ns
        else:
            w.late_since_ns = None
    if anchor:
        # the line through the newest frame's receive time, at the estimated period
        last = offsets[-1]
        step = period * (1.0 + w.skew)
        stamps = [receive_ns - round((last - o) * step) for o in offsets]
        w.anchor_ns = receive_ns - round(last * period)
        w.minima, w.window_min, w.late_since_ns = (), (last, 0.0), None
        w.last_index, w.last_stamp_ns = last, stamps[-1]
        w.anchors += 1
        return stamps, dropped, True

    anchor_ns = w.anchor_ns
    assert anchor_ns is not None  # not anchoring: there is a line
    # the newest frame of a read has waited least: it alone can lower the envelope
    _add_point(w, (indices[-1], float(receive_ns - anchor_ns) - indices[-1] * period), config)
    slope = w.skew * period
    # until the period is fitted, look back one window only: an unknown skew bends older minima
    back = config.offset_windows if len(w.minima) >= config.min_fit_windows else 1
    window_min = w.window_min
    assert window_min is not None  # _add_point has set it
    points = w.minima[-back:] + (window_min,)
    offset = min(y - slope * k for k, y in points)
    stamps = []
    for k in indices:
        n = k - w.last_index
        step = n * (period + slope)
        # the line's stamp for frame k, relative to the last stamp handed out
        target = (anchor_ns - w.last_stamp_ns) + k * (period + slope) + offset
        limit = config.slew * period * n
        w.last_stamp_ns += round(step + min(max(target - step, -limit), limit))
        w.last_index = k
        stamps.append(w.last_stamp_ns)
    return stamps, dropped, False


def _add_point(w: _Working, point: tuple[int, float], config: HubClockConfig) -> None:
    k, y = point
    slope = w.skew * config.period_ns
    if w.window_min is None:
        w.window_min = point
    elif k // config.window_frames != w.window_min[0] // config.window_frames:
        w.minima = (w.minima + (w.window_min,))[-config.slope_windows:]
        w.window_min = point
        if len(w.minima) >= config.min_fit_windows:
            ks = np.array([m[0] for m in w.minima], dtype=float)
            ys = np.array([m[1] for m in w.minima])
            ks -= ks.mean()
            fit = float(np.dot(ks, ys - ys.mean()) / np.dot(ks, ks)) if np.dot(ks, ks) > 0 else slope
            w.skew = min(max(fit / config.period_ns, -config.max_skew), config.max_skew)
    elif y - slope * k < w.window_min[1] - slope * w.window_min[0]:
        w.window_min = point
