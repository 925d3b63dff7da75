"""prisma-sim's demonstrations: the teleop session run N times with the operator, the ball and the
speed varied, written as one LeRobot v3.0 dataset (`prisma-sim --dataset DIR --episodes N`).

Each demonstration is the teleop scenario (`teleop_session.run_teleop_session`: the synthetic
operator's glove, the teleop core, the Teleoperate goal touch-limited at 2 N, the closed loop) with
- the operator: how fast it closes (`close_s`), how long it holds, how fast it opens, how far it
  closes (`closure` of a fist); a short rest before and after, no thumb sweep (a pinch, not a tour);
- the ball: where the index and the thumb pad first touch it (its size and position) and its
  stiffness (`sim_objects.pinch_ball_variant`);
- the speed: the Teleoperate goal's max_speed_rpm;
- the glove's noise seed.
Every value is drawn uniformly from `RANGES` by one seeded generator, so `--seed` gives the same
dataset again; each episode's values are in meta/prisma_export.json beside why it ended.

Each session is written as a bag (in a temporary directory, deleted afterwards) and exported with
prisma_dataset's own export (`bag_export.export_bags`, one episode per bag: `--whole-bag`), as
`prisma-dataset export --whole-bag` would; the dataset is written whole or not at all
(`lerobot_format.write_dataset`) and checked against the format's invariants after.
"""
from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from prisma_common.bag import BagWriter
from prisma_dataset.bag_export import ExportOptions, export_bags
from prisma_dataset.dataset_check import CheckReport, require_valid
from prisma_dataset.dataset_summary import summary_lines
from prisma_dataset.lerobot_format import write_dataset
from prisma_force_estimator.inference import ForceEstimator
from prisma_hand_sim.sim_objects import ObjectParams, pinch_ball_variant
from prisma_manipulation.teleop_goal import TeleopRequest
from prisma_teleop.synthetic_glove_core import OperatorScript

from .teleop_session import run_teleop_session, summarise

TASK = "pinch the ball between thumb and index, hold it, let go"
REST_S = 0.3  # the open hand before closing and after opening
# What the demonstrations vary, each drawn uniformly from its (low, high). The ball's contact angles
# around the sim hand's pinch ball (index 3.0 rad, thumb 2.5 rad, 0.4 N/mm); the operator around the
# synthetic_glove node's defaults (close 1.5 s, hold 2 s, open 1.5 s, closure 1); the speed cap
# around the manipulation node's teleop_max_speed_rpm (40 rpm).
RANGES: dict[str, tuple[float, float]] = {
    "close_s": (0.8, 1.6),
    "hold_s": (1.0, 2.0),
    "open_s": (0.8, 1.2),
    "closure": (0.75, 1.0),
    "index_contact_rad": (2.8, 3.2),
    "thumb_contact_rad": (2.3, 2.7),
    "stiffness_n_per_mm": (0.3, 0.5),
    "max_speed_rpm": (30.0, 40.0),
}


@dataclass(frozen=True)
class Demonstration:
    """One session's operator, ball and speed."""

    close_s: float
    hold_s: float
    open_s: float
    closure: float
    index_contact_rad: float
    thumb_contact_rad: float
    stiffness_n_per_mm: float
    max_speed_rpm: float
    glove_seed: int

    def script(self) -> OperatorScript:
        return OperatorScript(REST_S, self.close_s, self.hold_s, self.open_s, 0.0, self.closure)

    def ball(self) -> ObjectParams:
        return pinch_ball_variant(self.index_contact_rad, self.thumb_contact_rad, self.stiffness_n_per_mm)

    def request(self) -> TeleopRequest:
        return TeleopRequest(max_speed_rpm=self.max_speed_rpm)

    def describe(self) -> str:
        return (f"operator closes {self.closure:.2f} of a fist in {self.close_s:.2f} s, holds {self.hold_s:.2f} s, "
                f"opens in {self.open_s:.2f} s; ball touched at index {self.index_contact_rad:.2f} rad, thumb "
                f"{self.thumb_contact_rad:.2f} rad, {self.stiffness_n_per_mm:.2f} N/mm; {self.max_speed_rpm:.0f} rpm")


def draw(episodes: int, seed: int) -> list[Demonstration]:
    """`episodes` demonstrations drawn from RANGES by a generator seeded with `seed`."""
    rng = np.random.default_rng(seed)
    drawn = []
    for _ in range(episodes):
        values = {name: round(float(rng.uniform(low, high)), 3) for name, (low, high) in RANGES.items()}
        drawn.append(Demonstration(**values, glove_seed=int(rng.integers(0, 2**31 - 1))))
    return drawn


@dataclass
class DemonstrationRun:
    """What `record_dataset` did: per episode its parameters and session summary, the check of the
    written dataset, and the wall time of the sessions and of the export."""

    demonstrations: list[Demonstration]
    sessions: list[dict[str, Any]]
    report: CheckReport
    sessions_s: float
    export_s: float

    def summary(self) -> list[str]:
        """The dataset's summary as prisma-dataset show prints it."""
        return summary_lines(self.report)


def record_dataset(out: Path, episodes: int, seed: int, estimator: ForceEstimator,
                   progress: Callable[[str], None] = print) -> DemonstrationRun:
    """Run `episodes` demonstrations and write them as one dataset at `out` (whole or not at all)."""
    demonstrations = draw(episodes, seed)
    sessions: list[dict[str, Any]] = []
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="prisma-sim-demonstrations-") as tmp:
        bags = []
        for number, demo in enumerate(demonstrations):
            bag = Path(tmp) / f"demonstration_{number:03d}"
            with BagWriter(bag) as writer:
                trace, _ = run_teleop_session(writer, estimator, script=demo.script(), obj=demo.ball(),
                                              request=demo.request(), seed=demo.glove_seed)
            summary = summarise(trace)
            sessions.append(summary)
            bags.append(bag)
            peak = max(summary["peak_force_n"]["true"].values())
            progress(f"[demonstration {number}] {demo.describe()} -> ended {summary['reason']}, "
                     f"peak pad force {peak:.2f} N")
        sessions_s = time.perf_counter() - started
        dataset = export_bags(bags, ExportOptions(task=TASK, whole_bag=True))
    for episode, demo, summary in zip(dataset.episodes, demonstrations, sessions):
        episode.notes["source"] = "prisma-sim demonstration (bag not kept)"
        episode.notes["demonstration"] = {**asdict(demo), "rest_s": REST_S, "seed": seed,
                                          "session_reason": summary["reason"],
                                          "peak_pad_force_true_n": max(summary["peak_force_n"]["true"].values())}
    dataset.export_notes["demonstrations"] = {"tool": "prisma-sim --dataset", "seed": seed, "episodes": episodes,
                                              "ranges": {k: list(v) for k, v in RANGES.items()},
                                              "rest_s": REST_S}
    write_dataset(out, dataset)
    report = require_valid(out)
    return DemonstrationRun(demonstrations, sessions, report, sessions_s, time.perf_counter() - started - sessions_s)
