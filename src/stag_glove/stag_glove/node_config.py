"""Parameters of the glove nodes: one dataclass each with the defaults (which config/glove_*.yaml
repeat), validation that names the bad parameter and value, and the factories the nodes call."""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any, ClassVar

from prisma_common.parameters import ParameterError

from .backend import BACKENDS, GloveBackend
from .replay_backend import ReplayGloveBackend
from .selection import SELECTIONS
from .serial_backend import SerialGloveBackend
from .sim_backend import SimGloveBackend


def _positive(config: Any, *names: str) -> None:
    for name in names:
        if not getattr(config, name) > 0:
            raise ParameterError(name, getattr(config, name), "must be > 0")


class _Parameters:
    """Base of the parameter dataclasses below."""

    __dataclass_fields__: ClassVar[dict[str, Any]]  # (each subclass is a dataclass)

    def validate(self) -> Any:
        """Check the values; raise ParameterError naming the first bad one."""
        raise NotImplementedError

    @classmethod
    def from_parameters(cls, values: dict[str, Any]):
        known = {f.name for f in fields(cls)}
        unknown = set(values) - known
        if unknown:
            raise ParameterError(sorted(unknown)[0], values[sorted(unknown)[0]], "not a parameter of this node")
        return cls(**values).validate()

    def as_parameters(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class GloveDriverConfig(_Parameters):
    backend: str = "sim"               # serial | sim | replay
    frame_id: str = "stag_glove"
    # serial readout board (firmware/stag_readout)
    port: str = "/dev/ttyACM0"
    baudrate: int = 250000
    poll_rate_hz: float = 50.0         # how often the port is drained / the sim and replay are stepped
    reconnect_backoff_initial: float = 0.5   # s, doubled after each failed reopen
    reconnect_backoff_max: float = 8.0       # s
    rows: int = 32
    cols: int = 32
    # sim and replay
    frame_rate_hz: float = 7.3         # frames/s emitted by sim and replay (the real glove: ~7.3)
    sim_seed: int = 0
    sim_short_probability: float = 0.005     # fraction of simulated frames with a shorted electrode
    replay_file: str = ""              # metadata.mat (MATLAB v5/v7.3) or .h5
    replay_loop: bool = True
    # processing
    normalisation_low: float = 500.0   # counts -> pressure 0
    normalisation_high: float = 650.0  # counts -> pressure 1
    short_threshold: int = 950         # any reading above -> frame flagged shorted
    contact_margin: float = 0.05       # pressure above the empty-hand maximum for contact
    layout_file: str = "config/glove/layout.yaml"  # sensor mask; "" = every cell is a sensor
    empty_hand_frames: int = 30        # ~/capture_empty_hand uses this many most recent frames
    calibration_file: str = ""         # .npz: loaded at start if present, written by the capture
    stale_timeout: float = 1.0         # s without a frame -> /diagnostics WARN
    diagnostics_period: float = 1.0    # s

    def validate(self) -> GloveDriverConfig:
        if self.backend not in BACKENDS:
            raise ParameterError("backend", self.backend, f"expected one of {'|'.join(BACKENDS)}")
        if self.backend == "serial" and not self.port:
            raise ParameterError("port", self.port, "the serial backend needs a port")
        if self.backend == "replay" and not self.replay_file:
            raise ParameterError("replay_file", self.replay_file, "the replay backend needs a dataset file")
        _positive(self, "baudrate", "poll_rate_hz", "reconnect_backoff_initial", "frame_rate_hz", "rows", "cols",
                  "empty_hand_frames", "stale_timeout", "diagnostics_period")
        if self.reconnect_backoff_max < self.reconnect_backoff_initial:
            raise ParameterError("reconnect_backoff_max", self.reconnect_backoff_max,
                                 f"must be >= reconnect_backoff_initial ({self.reconnect_backoff_initial})")
        if (self.rows * self.cols) % 4:
            raise ParameterError("cols", self.cols, "rows*cols must be a multiple of 4 (10-bit packing)")
        if not self.normalisation_high > self.normalisation_low:
            raise ParameterError("normalisation_high", self.normalisation_high,
                                 f"must exceed normalisation_low ({self.normalisation_low})")
        if not 0 < self.short_threshold <= 1023:
            raise ParameterError("short_threshold", self.short_threshold, "must be in 1..1023")
        if self.contact_margin < 0:
            raise ParameterError("contact_margin", self.contact_margin, "must be >= 0")
        if not 0 <= self.sim_short_probability <= 1:
            raise ParameterError("sim_short_probability", self.sim_short_probability, "must be in 0..1")
        return self

    def make_backend(self) -> GloveBackend:
        if self.backend == "serial":
            return SerialGloveBackend(self.port, self.baudrate, self.rows, self.cols,
                                      self.reconnect_backoff_initial, self.reconnect_backoff_max)
        if self.backend == "sim":
            return SimGloveBackend(self.frame_rate_hz, self.sim_seed, self.sim_short_probability)
        try:
            return ReplayGloveBackend(self.replay_file, self.frame_rate_hz, self.replay_loop)
        except (OSError, ValueError) as exc:
            raise ParameterError("replay_file", self.replay_file, str(exc)) from None


@dataclass
class GlovePerceptionConfig(_Parameters):
    object_bundle: str = "config/models/glove_object"   # "" disables /stag/object
    pose_bundle: str = "config/models/glove_pose"       # "" disables /stag/hand_pose
    weight_bundle: str = "config/models/glove_weight"   # "" disables /stag/weight
    selection: str = "cluster"         # how the object model's N frames are chosen: cluster | random
    buffer_size: int = 64              # contact frames kept for the object decision
    release_frames: int = 15           # frames without contact that clear the buffer (object released)
    kmeans_restarts: int = 3
    seed: int = 0
    threads: int = 1                   # torch/BLAS threads
    frame_id: str = "stag_glove"

    def validate(self) -> GlovePerceptionConfig:
        if self.selection not in SELECTIONS:
            raise ParameterError("selection", self.selection, f"expected one of {'|'.join(SELECTIONS)}")
        _positive(self, "buffer_size", "release_frames", "kmeans_restarts", "threads")
        return self
