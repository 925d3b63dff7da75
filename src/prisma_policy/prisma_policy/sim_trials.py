"""The policy tried in the ROS-free closed-loop sim, beside the scripted Grasp on the same balls.

Policy trial: the sim hand (`ClosedLoop`: the motor driver, tactile driver, force estimator and
manipulation cores, as prisma-sim's teleop session runs them) with a Teleoperate goal sent at the
first scan, with the manipulation node's teleop defaults (touch limit 2 N, 40 rpm, input timeout
0.15 s). The policy takes the teleop node's place as the source of prisma/teleop/motor_targets: at
the dataset's fps (every other 100 Hz scan at 50 fps) it reads the scan's taxel voltages, the newest
wrench per finger and the motors' positions and velocities, and its targets reach the manipulation
core at the next scan, stamped with the scan they came from, as a node's subscription hands them.
So the touch limit and the stale-input stop of the manipulation core apply to it as to a glove.

Grasp trial: the same ball, the scripted Grasp pinch goal as prisma-sim's pinch_grasp sends it
(fingers at 60 rpm to 0.8 N on the index pad, then the thumb to 1 N).

Balls (`sim_objects.pinch_ball_variant`): outside every range the demonstrations showed (the model
remembers them), alternately smaller or farther (touched later: contact angles above the range) and
larger or nearer (below it), stiffer or softer, drawn with a seed.

A trial closed on the ball when the thumb and the index pad both pressed it with at least
`CLOSED_N` (the world's true force) for `CLOSED_S` on end; it stayed within the touch limit when no
pad's true force passed the limit by more than `TOUCH_TOLERANCE_N` (the margin the replay check of
issue 41 allows, prisma-sim's force tolerance).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from prisma_common.atomic import atomic_output
from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_force_estimator.inference import ForceEstimator
from prisma_hand_sim.hand_world import HandWorld
from prisma_hand_sim.sim_objects import OBJECTS, ObjectParams, pinch_ball_variant
from prisma_manipulation.closed_loop import ClosedLoop, Scan
from prisma_manipulation.manipulation_core import GraspRequest
from prisma_manipulation.node_config import ManipulationConfig
from prisma_manipulation.teleop_controller import TARGET_STREAM, TeleopTarget
from prisma_manipulation.teleop_goal import TeleopRequest
from prisma_motor_driver.control_table import rpm_to_rad_s

from .bc_policy import BALL_KEYS, Policy

NS = 1_000_000_000
TRIAL_S = 5.0
CLOSED_N = 0.5
CLOSED_S = 0.5
TOUCH_TOLERANCE_N = 0.15
TOUCH_LIMIT_N = ManipulationConfig().teleop_max_pad_force
GRASP = GraspRequest("pinch", 0.8, 1.0, 60.0, 10.0)  # prisma-sim's pinch_grasp (prisma_manipulation.scenarios)
# how far outside the shown range an unseen ball lies: margin + spread x uniform(0, 1)
UNSEEN = {"index_contact_rad": (0.1, 0.15), "thumb_contact_rad": (0.1, 0.15), "stiffness_n_per_mm": (0.05, 0.1)}
THUMB, PARTNER = FINGERS.index("thumb"), FINGERS.index("index")


def unseen_balls(shown: dict[str, list[float]], trials: int, seed: int) -> list[ObjectParams]:
    """`trials` balls outside `shown` (key -> [min, max]; the sim pinch ball's own values where a key
    is missing): even trials above every range, odd ones below."""
    ball = OBJECTS["pinch_ball"]
    own = {"index_contact_rad": ball.finger_contact_rad["index"],
           "thumb_contact_rad": float(ball.thumb_contact_rad or 0.0), "stiffness_n_per_mm": ball.stiffness_n_per_mm}
    rng = np.random.default_rng(seed)
    balls = []
    for trial in range(trials):
        above = trial % 2 == 0
        values = {}
        for key in BALL_KEYS:
            low, high = shown.get(key) or [own[key], own[key]]
            margin, spread = UNSEEN[key]
            offset = margin + spread * float(rng.uniform())
            values[key] = round(high + offset if above else low - offset, 3)
        balls.append(pinch_ball_variant(values["index_contact_rad"], values["thumb_contact_rad"],
                                        values["stiffness_n_per_mm"]))
    return balls


@dataclass
class TrialResult:
    kind: str  # "policy" or "grasp"
    ball: ObjectParams
    stamps_s: np.ndarray
    forces_true: np.ndarray  # [scans, 5]
    positions: np.ndarray  # [scans, 3]
    reason: str  # how the goal ended ("" while it ran on)
    closed: bool = field(init=False)
    peak_force_n: float = field(init=False)
    within_limit: bool = field(init=False)

    def __post_init__(self) -> None:
        pinch = np.minimum(self.forces_true[:, THUMB], self.forces_true[:, PARTNER]) >= CLOSED_N
        needed = int(round(CLOSED_S / float(np.median(np.diff(self.stamps_s)))))
        run = longest = 0
        for pressed in pinch:
            run = run + 1 if pressed else 0
            longest = max(longest, run)
        self.closed = longest >= needed
        self.peak_force_n = float(np.max(self.forces_true))
        self.within_limit = self.peak_force_n <= TOUCH_LIMIT_N + TOUCH_TOLERANCE_N


class Observer:
    """The policy's view of the scans: taxels and joints of the newest scan, the newest wrench per
    finger (the estimator's batches need not carry every finger every scan)."""

    def __init__(self) -> None:
        self.wrench = np.zeros((len(FINGERS), 6))
        self.tactile = np.zeros((len(FINGERS), 3, 3))
        self.state = np.zeros(2 * len(MOTOR_NAMES))

    def update(self, scan: Scan, volts: np.ndarray) -> None:
        self.tactile = np.asarray(volts, dtype=np.float64).reshape(len(FINGERS), 3, 3)
        for finger, sample in scan.wrenches.items():
            self.wrench[FINGERS.index(finger)] = np.asarray(sample.wrench, dtype=np.float64)
        self.state = np.array([scan.states[m].position_rad for m in MOTOR_NAMES]
                              + [rpm_to_rad_s(scan.states[m].velocity_rpm) for m in MOTOR_NAMES])


def policy_trial(policy: Policy, ball: ObjectParams, estimator: ForceEstimator, duration_s: float = TRIAL_S,
                 seed: int = 0) -> TrialResult:
    """The policy drives the sim hand holding `ball` through a Teleoperate goal for `duration_s`."""
    loop = ClosedLoop(HandWorld(obj=ball), estimator, seed=seed)
    every = max(1, int(round(NS / policy.fps / loop.period_ns)))  # scans per policy step
    observer = Observer()
    pending: list = []
    stamps, forces, positions = [], [], []
    for k in range(int(round(duration_s * NS / loop.period_ns)) + 1):
        t = k * loop.period_ns
        scan, volts, _ = loop.scan(t, pending)
        pending = []
        if k == 0:
            loop.start(TeleopRequest(), scan)
        observer.update(scan, volts)
        if k % every == 0:
            targets = policy.act(observer.tactile, observer.wrench, observer.state)
            pending = [(TARGET_STREAM, t, TeleopTarget(t, dict(zip(MOTOR_NAMES, map(float, targets)))))]
        truth = loop.world.forces()
        stamps.append(t / NS)
        forces.append([truth[f] for f in FINGERS])
        positions.append([scan.states[m].position_rad for m in MOTOR_NAMES])
    reason = loop.finished.reason if loop.finished is not None else ""
    return TrialResult("policy", ball, np.asarray(stamps), np.asarray(forces), np.asarray(positions), reason)


def grasp_trial(ball: ObjectParams, estimator: ForceEstimator, duration_s: float = TRIAL_S,
                seed: int = 0) -> TrialResult:
    """The scripted Grasp pinch goal on `ball`, run for `duration_s`."""
    loop = ClosedLoop(HandWorld(obj=ball), estimator, seed=seed)
    trace = loop.run(GRASP, duration_s, settle_s=duration_s)
    reason = loop.finished.reason if loop.finished is not None else ""
    return TrialResult("grasp", ball, trace.array("stamps_ns") / NS, trace.array("forces_true"),
                       trace.array("positions"), reason)


def run_trials(policy: Policy, estimator: ForceEstimator, trials: int, seed: int, duration_s: float = TRIAL_S,
               progress: Callable[[str], None] | None = None) -> list[tuple[TrialResult, TrialResult]]:
    """(policy, grasp) per unseen ball."""
    results = []
    for number, ball in enumerate(unseen_balls(policy.shown, trials, seed)):
        pair = (policy_trial(policy, ball, estimator, duration_s, seed + number),
                grasp_trial(ball, estimator, duration_s, seed + number))
        results.append(pair)
        if progress:
            progress(table_row(number, *pair))
    return results


def ball_text(ball: ObjectParams) -> str:
    return (f"index {ball.finger_contact_rad['index']:.2f} / thumb {ball.thumb_contact_rad:.2f} rad, "
            f"{ball.stiffness_n_per_mm:.2f} N/mm")


def _yes(flag: bool) -> str:
    return "yes" if flag else "NO"


TABLE_HEADER = ("| trial | ball (contact angles, stiffness) | policy: closed | peak pad force (N) | within limit "
                "| Grasp: closed | peak pad force (N) | within limit |\n|---|---|---|---|---|---|---|---|")


def table_row(number: int, policy: TrialResult, grasp: TrialResult) -> str:
    return (f"| {number} | {ball_text(policy.ball)} | {_yes(policy.closed)} | {policy.peak_force_n:.2f} | "
            f"{_yes(policy.within_limit)} | {_yes(grasp.closed)} | {grasp.peak_force_n:.2f} | "
            f"{_yes(grasp.within_limit)} |")


def successes(results: list[tuple[TrialResult, TrialResult]], which: int) -> int:
    """Trials that closed on the ball within the touch limit (which: 0 policy, 1 grasp)."""
    return sum(1 for pair in results if pair[which].closed and pair[which].within_limit)


def table(results: list[tuple[TrialResult, TrialResult]]) -> str:
    lines = [TABLE_HEADER, *(table_row(i, *pair) for i, pair in enumerate(results))]
    lines.append(f"closed on the ball within the touch limit ({TOUCH_LIMIT_N:g} N + {TOUCH_TOLERANCE_N:g} N): "
                 f"policy {successes(results, 0)}/{len(results)}, scripted Grasp "
                 f"{successes(results, 1)}/{len(results)}")
    return "\n".join(lines)


def plot(results: list[tuple[TrialResult, TrialResult]], path: Path) -> Path:
    """Thumb and index pad forces of every trial, the policy's beside the Grasp's, with the touch limit."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), sharey=True)
    for ax, which, title in ((axes[0], 0, "policy (Teleoperate, touch-limited)"), (axes[1], 1, "scripted Grasp pinch")):
        for number, pair in enumerate(results):
            trial = pair[which]
            colour = plt.get_cmap("tab10")(number % 10)
            ax.plot(trial.stamps_s, trial.forces_true[:, THUMB], color=colour, lw=1,
                    label=f"{number}: {'closed' if trial.closed else 'not closed'}")
            ax.plot(trial.stamps_s, trial.forces_true[:, PARTNER], color=colour, lw=1, ls=":")
        ax.axhline(TOUCH_LIMIT_N, color="k", ls="--", lw=1)
        ax.axhline(TOUCH_LIMIT_N + TOUCH_TOLERANCE_N, color="r", ls=":", lw=1)
        ax.set_title(f"{title}: {successes(results, which)}/{len(results)} closed within the limit", fontsize=10)
        ax.set_xlabel("time (s); solid: thumb pad, dotted: index pad (true force)")
        ax.legend(fontsize=7, loc="upper left", ncol=2)
    axes[0].set_ylabel(f"pad normal force (N); dashed: touch limit {TOUCH_LIMIT_N:g} N")
    fig.tight_layout()
    with atomic_output(path) as staged:
        fig.savefig(staged, dpi=100)
    plt.close(fig)
    return Path(path)
