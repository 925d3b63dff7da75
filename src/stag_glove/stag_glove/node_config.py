"""Parameters of the glove nodes: one dataclass each with the defaults (which config/glove_*.yaml
repeat) and their specs (description, unit, bounds, live or read-only), validation that names the
bad parameter and value, and the factories the nodes call.

Live on glove_driver: contact_margin and short_threshold (the frame processing, from the next
frame) and stale_timeout (/diagnostics). The normalisation range is not: the empty-hand
calibration holds pressures normalised with it. Live on glove_perception: release_frames (from
the next frame). The rest builds the backend, the models and the buffer at start.
"""
from __future__ import annotations

from dataclasses import dataclass

from prisma_common.parameters import ParameterError, Params, backoff_initial, backoff_max, check_backoff, parameter

from .backend import BACKENDS, GloveBackend
from .processing import ADC_MAX, NormalisationConfig
from .replay_backend import ReplayGloveBackend
from .selection import SELECTIONS
from .serial_backend import SerialGloveBackend
from .sim_backend import SimGloveBackend

COUNTS = (0.0, float(ADC_MAX))  # the readout's 10-bit counts
SEED = (0, 2**31 - 1)


@dataclass
class GloveDriverConfig(Params):
    backend: str = parameter("sim", "glove source: serial (readout board), sim (synthetic glove: objects held, "
                                    "never lifted, so /stag/weight has no load to read) or replay (dataset file)",
                             choices=BACKENDS)
    frame_id: str = parameter("stag_glove", "header.frame_id of /stag/frame and /stag/image")
    # serial readout board (firmware/stag_readout)
    port: str = parameter("/dev/ttyACM0", "serial port of the readout board (backend serial)",
                          rules="not empty with backend serial")
    baudrate: int = parameter(250000, "serial baud rate of the readout board", unit="baud", bounds=(1, 4_000_000))
    poll_rate_hz: float = parameter(50.0, "how often the port is drained / the sim and replay are stepped",
                                    unit="Hz", bounds=(0.0, 1000.0), open_low=True)
    reconnect_backoff_initial: float = backoff_initial(0.5, "port")
    reconnect_backoff_max: float = backoff_max(8.0)
    rows: int = parameter(32, "readout rows", bounds=(1, 256))
    cols: int = parameter(32, "readout columns", bounds=(1, 256),
                          rules="rows x cols a multiple of 4 (10-bit packing)")
    # sim and replay
    frame_rate_hz: float = parameter(7.3, "frames/s emitted by sim and replay (the real glove: ~7.3)", unit="Hz",
                                     bounds=(0.0, 1000.0), open_low=True)
    sim_seed: int = parameter(0, "seed of the synthetic glove", bounds=SEED)
    sim_short_probability: float = parameter(0.005, "fraction of simulated frames with a shorted electrode",
                                             bounds=(0.0, 1.0))
    replay_file: str = parameter("", "dataset to replay: metadata.mat (MATLAB v5/v7.3) or .h5 (backend replay)",
                                 rules="not empty with backend replay")
    replay_loop: bool = parameter(True, "replay the file again from its start when it ends")
    # processing
    normalisation_low: float = parameter(500.0, "counts mapped to pressure 0", bounds=COUNTS)
    normalisation_high: float = parameter(650.0, "counts mapped to pressure 1 (above: clipped)", bounds=COUNTS,
                                          rules="above normalisation_low")
    short_threshold: int = parameter(950, "a frame with any reading above this is flagged shorted (from the next "
                                          "frame)", bounds=(1, ADC_MAX), live=True)
    contact_margin: float = parameter(0.05, "pressure above a sensor's empty-hand maximum that counts as contact "
                                            "(from the next frame)", bounds=(0.0, 1.0), live=True)
    layout_file: str = parameter("config/glove/layout.yaml", "sensor layout (548-cell mask); '' = every cell is a "
                                                             "sensor")
    empty_hand_frames: int = parameter(30, "~/capture_empty_hand takes the maximum over this many most recent "
                                           "frames", bounds=(1, 10_000))
    calibration_file: str = parameter("", ".npz empty-hand calibration: loaded at start if present, written by "
                                          "~/capture_empty_hand; '' = none")
    stale_timeout: float = parameter(1.0, "/diagnostics warns after this long without a frame", unit="s",
                                     bounds=(0.0, 60.0), open_low=True, live=True)
    diagnostics_period: float = parameter(1.0, "time between /diagnostics messages", unit="s", bounds=(0.0, 60.0),
                                          open_low=True)

    def check_rules(self) -> None:
        if self.backend == "serial" and not self.port:
            raise ParameterError("port", self.port, "the serial backend needs a port")
        if self.backend == "replay" and not self.replay_file:
            raise ParameterError("replay_file", self.replay_file, "the replay backend needs a dataset file")
        check_backoff(self.reconnect_backoff_initial, self.reconnect_backoff_max)
        if (self.rows * self.cols) % 4:
            raise ParameterError("cols", self.cols, "rows*cols must be a multiple of 4 (10-bit packing)")
        if not self.normalisation_high > self.normalisation_low:
            raise ParameterError("normalisation_high", self.normalisation_high,
                                 f"must exceed normalisation_low ({self.normalisation_low})")

    def normalisation(self) -> NormalisationConfig:
        return NormalisationConfig(self.normalisation_low, self.normalisation_high, self.short_threshold,
                                   self.contact_margin)

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
class GlovePerceptionConfig(Params):
    object_bundle: str = parameter("config/models/glove_object", "N-frame object classifier bundle; '' disables "
                                                                 "/stag/object")
    pose_bundle: str = parameter("config/models/glove_pose", "hand-pose classifier bundle; '' disables "
                                                             "/stag/hand_pose")
    weight_bundle: str = parameter("config/models/glove_weight", "weight regressor bundle; '' disables /stag/weight")
    selection: str = parameter("cluster", "how the object model's N frames are chosen from the buffer: cluster "
                                          "(PCA 8 + k-means) or random", choices=SELECTIONS)
    buffer_size: int = parameter(64, "contact frames kept for the object decision", bounds=(1, 10_000))
    release_frames: int = parameter(15, "frames without contact that clear the buffer (object released; from "
                                        "the next frame)", bounds=(1, 1000), live=True)
    kmeans_restarts: int = parameter(3, "k-means restarts of the cluster selection", bounds=(1, 100))
    seed: int = parameter(0, "seed of the frame selection", bounds=SEED)
    threads: int = parameter(1, "torch and BLAS threads (process-wide)", bounds=(1, 64))
    frame_id: str = parameter("stag_glove", "header.frame_id of the estimates")
