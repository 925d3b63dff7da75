"""Glove driver core: backend frames -> processed frames, the empty-hand capture and the driver's
diagnostics. ROS-free; the glove_driver node polls it from a timer and publishes what it returns."""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from prisma_common.diagnostics import ERROR, OK, WARN, DiagnosticStatusData

from .backend import GloveBackend
from .processing import EmptyHandCalibration, FrameProcessor, NormalisationConfig, ProcessedFrame

NS = 1_000_000_000


@dataclass
class CaptureResult:
    success: bool
    message: str


@dataclass
class DriverStats:
    frames: int = 0
    shorted: int = 0
    contact: int = 0


class GloveDriver:
    def __init__(self, backend: GloveBackend, processor: FrameProcessor, empty_hand_frames: int = 30,
                 stale_timeout_s: float = 1.0, calibration_file: str | Path | None = None,
                 name: str = "glove_driver", hardware_id: str = "") -> None:
        self.backend = backend
        self.processor = processor
        self.empty_hand_frames = empty_hand_frames
        self.recent: deque[np.ndarray] = deque(maxlen=empty_hand_frames)
        self.stats = DriverStats()
        self.stale_timeout_ns = int(stale_timeout_s * NS)
        self.calibration_file = Path(calibration_file) if calibration_file else None
        self.name, self.hardware_id = name, hardware_id
        self._last_frame_ns: int | None = None
        self._started_ns: int | None = None
        if self.calibration_file is not None and self.calibration_file.exists():
            self.processor.calibration = load_calibration(self.calibration_file, processor.mask)

    def reconfigure(self, normalisation: NormalisationConfig, stale_timeout_s: float) -> None:
        """Live parameters changed: the frame processing (short threshold, contact margin) from the
        next frame, the stale timeout from the next /diagnostics."""
        self.processor.config = normalisation
        self.stale_timeout_ns = int(stale_timeout_s * NS)

    def poll(self, now_ns: int) -> list[ProcessedFrame]:
        if self._started_ns is None:
            self._started_ns = now_ns
        out = []
        for item in self.backend.poll(now_ns):
            frame = self.processor.process(item.raw, item.stamp_ns, item.sequence)
            self.stats.frames += 1
            self._last_frame_ns = now_ns
            if frame.shorted:
                self.stats.shorted += 1
            else:
                self.recent.append(frame.raw)  # shorted frames never enter the calibration either
            self.stats.contact += frame.contact
            out.append(frame)
        return out

    def capture_empty_hand(self) -> CaptureResult:
        """Calibrate from the most recent `empty_hand_frames` good frames (hold the hand empty and
        still for that long, then call)."""
        if len(self.recent) < self.empty_hand_frames:
            return CaptureResult(False, f"need {self.empty_hand_frames} good frames for the empty-hand capture, "
                                        f"have {len(self.recent)}; keep the hand empty and try again")
        cal = self.processor.calibrate(np.stack(self.recent))
        message = (f"empty-hand calibration from {cal.frames_used} frames; "
                   f"max pressure {float(cal.maximum.max()):.3f}, {int((cal.maximum > 0).sum())} sensors above 0")
        if self.calibration_file is not None:
            save_calibration(self.calibration_file, cal)
            message += f"; saved to {self.calibration_file}"
        return CaptureResult(True, message)

    def diagnostics(self, now_ns: int) -> list[DiagnosticStatusData]:
        status = self.backend.status()
        values = dict(status.values)
        values.update(frames_processed=str(self.stats.frames), shorted_frames=str(self.stats.shorted),
                      contact_frames=str(self.stats.contact),
                      empty_hand_calibrated=str(self.processor.calibration is not None))
        since = self._last_frame_ns if self._last_frame_ns is not None else self._started_ns
        age_ns = None if since is None else now_ns - since
        if age_ns is not None:
            values["seconds_since_last_frame"] = f"{age_ns / NS:.2f}"
        if not status.connected:
            level, message = ERROR, status.message
        elif age_ns is not None and age_ns > self.stale_timeout_ns:
            level, message = WARN, f"no frame for {age_ns / NS:.1f} s ({status.message})"
        elif self.stats.shorted and self.stats.shorted * 10 > self.stats.frames:
            level, message = WARN, f"{self.stats.shorted} of {self.stats.frames} frames shorted (dropped)"
        elif self.processor.calibration is None:
            level, message = OK, f"{status.message}; no empty-hand calibration yet (call ~/capture_empty_hand)"
        else:
            level, message = OK, status.message
        return [DiagnosticStatusData(f"{self.name}: readout", level, message, self.hardware_id, values)]

    def close(self) -> None:
        self.backend.close()


def save_calibration(path: Path, cal: EmptyHandCalibration) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as stream:  # np.savez would append .npz to a name without it
        np.savez(stream, maximum=cal.maximum, frames_used=cal.frames_used)


def load_calibration(path: Path, mask: np.ndarray | None) -> EmptyHandCalibration:
    try:
        with np.load(path) as data:
            cal = EmptyHandCalibration(np.asarray(data["maximum"], dtype=np.float32), int(data["frames_used"]))
    except (OSError, KeyError, ValueError) as exc:
        raise ValueError(f"calibration file {path}: {exc}") from None
    if mask is not None and cal.maximum.shape != mask.shape:
        raise ValueError(f"calibration file {path} holds a {cal.maximum.shape} map, the glove is {mask.shape}")
    return cal
