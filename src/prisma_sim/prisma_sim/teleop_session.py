"""prisma-sim's teleop scenario: the synthetic operator's hand-pose glove drives the simulated hand
holding the pinch ball, through the teleop node's core and the manipulation node's Teleoperate goal,
in the closed loop, recorded as the graph would publish it.

One route, in the order the graph delivers messages: every glove sample (the synthetic_glove node's
operator, prisma_teleop.synthetic_glove_core, 60 Hz, its noise) goes through
`prisma_teleop.teleop_core.HandPoseTeleop.on_sample` (the teleop node's retargeting, filter and
deadband, engaged at start: it also decides when to send the Teleoperate goal) to its targets; they
reach the manipulation core at the next scan as the node's subscription hands them
(`ClosedLoop.scan(inputs=...)` -> `ManipulationCore.on_input`), and the goal the teleop core sends
starts at that scan (`ClosedLoop.start`) with the teleop node's default fields (0: the manipulation
node's teleop parameters, 2 N, 40 rpm, 0.15 s). The operator: rest, close to a fist (the hand closes
on the ball until its touch limit holds it), hold, open, rest, sweep the thumb's opposition; then the
glove falls silent and the goal ends input_stale with the motors stopped: the expected end.

Bag: /glove/joint_states and /prisma/teleop/motor_targets per glove sample, every hand topic per
scan and the Teleoperate goal's status and feedback (`HandRecorder`), the MoveMotors goals. Plot:
the operator's command (the three targets), the motor positions, the pads' estimated and true
normal forces with the touch limit.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from prisma_common.bag import BagWriter
from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_common.topics import TELEOP_TARGETS
from prisma_common.typestore import types as typestore_types
from prisma_force_estimator.inference import ForceEstimator
from prisma_hand_sim.hand_world import HandWorld
from prisma_hand_sim.sim_objects import ObjectParams
from prisma_manipulation.closed_loop import ClosedLoop
from prisma_manipulation.node_config import ManipulationConfig
from prisma_manipulation.scenarios import Scenario
from prisma_manipulation.teleop_controller import TARGET_STREAM, TeleopTarget
from prisma_manipulation.teleop_goal import TeleopRequest
from prisma_teleop.node_config import SyntheticGloveConfig, TeleopConfig
from prisma_teleop.retargeting import nominal_calibration
from prisma_teleop.ros_conversions import hand_pose_to_msg, motor_targets_to_msg
from prisma_teleop.synthetic_glove_core import OperatorScript, SyntheticGlove
from prisma_teleop.teleop_core import HandPoseTeleop, SendGoal

from .hand_session import HandRecorder

TELEOP = "teleop"
NS = 1_000_000_000
GLOVE_TOPIC, TARGETS_TOPIC = "/glove/joint_states", TELEOP_TARGETS
STOPPED_RPM = 0.229  # one velocity unit of an X-series Dynamixel: "stopped" as the launch tests read it
SILENT_S = 1.0  # the run goes on this long after the glove fell silent
DESCRIPTION = ("the synthetic operator's hand-pose glove (60 Hz) closes to a fist over the pinch ball, holds, opens "
               "and sweeps the thumb, then falls silent; the teleop core's targets, the Teleoperate goal touch-limited "
               "at 2 N")


@dataclass
class TeleopTrace:
    """Per scan: what the plot and the summary read."""

    stamps_ns: list[int] = field(default_factory=list)
    targets: list[np.ndarray] = field(default_factory=list)  # [3] the latest target per motor (nan: none yet)
    positions: list[np.ndarray] = field(default_factory=list)  # [3]
    velocities_rpm: list[np.ndarray] = field(default_factory=list)  # [3]
    forces_used: list[np.ndarray] = field(default_factory=list)  # [5] what the manipulation core got
    forces_true: list[np.ndarray] = field(default_factory=list)  # [5] the world's
    goal_started_ns: list[int] = field(default_factory=list)
    last_glove_ns: int = 0
    finished: Any = None  # the goal's Finished
    finished_ns: int = 0  # the scan it came at

    def array(self, name: str) -> np.ndarray:
        return np.asarray(getattr(self, name))


def make_loop(estimator: ForceEstimator | None, obj: ObjectParams | str = "pinch_ball") -> ClosedLoop:
    """The sim hand of `hand.launch.py sim:=true`: the pinch ball (or `obj`) between the open fingers."""
    return ClosedLoop(HandWorld(obj=obj), estimator)


def operator_glove(script: OperatorScript | None = None, seed: int | None = None) -> SyntheticGlove:
    """The synthetic_glove node's operator with its default parameters, once through its script."""
    c = SyntheticGloveConfig()
    script = script or OperatorScript(c.rest_s, c.close_s, c.hold_s, c.open_s, c.sweep_s, c.closure)
    return SyntheticGlove(script, noise_rad=c.noise_rad, seed=c.seed if seed is None else seed, loop=False)


def run_teleop_session(writer: BagWriter, estimator: ForceEstimator, progress: Callable[[str], None] | None = None,
                       types: Callable[[str], Any] = typestore_types,
                       script: OperatorScript | None = None, obj: ObjectParams | str = "pinch_ball",
                       request: TeleopRequest | None = None, seed: int | None = None) -> tuple[TeleopTrace, Any]:
    """Run the session into `writer`; (the trace, the HandRecorder's recording). The operator's
    `script`, the object and the goal's fields (`request`: its speed cap) vary a demonstration; `seed`
    the glove's noise (default: the synthetic_glove node's)."""
    loop = make_loop(estimator, obj)
    glove = operator_glove(script, seed)
    teleop = HandPoseTeleop(TeleopConfig(engage_at_start=True), nominal_calibration())
    request = request or TeleopRequest()
    duration_s = glove.script.duration_s + SILENT_S
    scenario = Scenario(TELEOP, loop, request, duration_s)  # type: ignore[arg-type]  # a Teleoperate goal
    recorder = HandRecorder(scenario, writer, "teleoperate", types)
    trace = TeleopTrace()
    glove_config = SyntheticGloveConfig()
    glove_period_ns = int(round(NS / glove_config.rate_hz))
    next_glove_ns, latest = 0, np.full(len(MOTOR_NAMES), np.nan)
    for k in range(int(round(duration_s * NS / loop.period_ns)) + 1):
        t = k * loop.period_ns
        inputs, send = [], False
        while next_glove_ns <= t:  # the glove samples published since the last scan
            angles = glove.sample(next_glove_ns / NS)
            if angles is not None:
                writer.write(GLOVE_TOPIC, hand_pose_to_msg(types, next_glove_ns, angles, glove_config.frame_id))
                targets, actions = teleop.on_sample(next_glove_ns, angles, next_glove_ns)
                if targets is not None:
                    writer.write(TARGETS_TOPIC, motor_targets_to_msg(types, next_glove_ns, targets))
                    inputs.append((TARGET_STREAM, next_glove_ns, TeleopTarget(next_glove_ns, targets)))
                    latest = np.array([targets[m] for m in MOTOR_NAMES])
                    trace.last_glove_ns = next_glove_ns
                send = send or any(isinstance(a, SendGoal) for a in actions)
            next_glove_ns += glove_period_ns
        scan, _, used = loop.scan(t, inputs)
        if send and loop.core.controller is None:
            loop.start(request, scan)
            trace.goal_started_ns.append(t)
            if progress:
                progress(f"t={t / NS:.2f}s Teleoperate goal started")
        recorder.record(scan)
        if loop.finished is not None and trace.finished is None:
            trace.finished, trace.finished_ns = loop.finished, t
            teleop.on_goal_ended(loop.finished.reason, loop.finished.success, t)
            if progress:
                progress(f"t={t / NS:.2f}s goal ended {loop.finished.reason}")
        _record(trace, loop, scan, latest, used)
    return trace, recorder.finish()


def _record(trace: TeleopTrace, loop: ClosedLoop, scan: Any, latest: np.ndarray, used: np.ndarray) -> None:
    trace.stamps_ns.append(scan.stamp_ns)
    trace.targets.append(latest.copy())
    trace.positions.append(np.array([scan.states[m].position_rad for m in MOTOR_NAMES]))
    trace.velocities_rpm.append(np.array([scan.states[m].velocity_rpm for m in MOTOR_NAMES]))
    trace.forces_used.append(np.asarray(used, dtype=float))
    truth = loop.world.forces()
    trace.forces_true.append(np.array([truth[f] for f in FINGERS]))


def summarise(trace: TeleopTrace, limit_n: float = ManipulationConfig().teleop_max_pad_force) -> dict:
    """The end, the stop after the glove fell silent, the touch limit held, where the hand stood."""
    t = trace.array("stamps_ns")
    done = trace.finished
    moving = np.nonzero(np.any(np.abs(trace.array("velocities_rpm")) >= STOPPED_RPM, axis=1))[0]
    last_moving = int(moving[-1]) if moving.size else 0
    stopped_s = (t[min(last_moving + 1, len(t) - 1)] - trace.last_glove_ns) / NS
    peaks = {which: {f: float(np.nanmax(trace.array(f"forces_{which}")[:, i])) for i, f in enumerate(FINGERS)}
             for which in ("used", "true")}
    over = {which: max(0.0, max(p.values()) - limit_n) for which, p in peaks.items()}
    fingers = trace.array("positions")[:, 0]
    held = int(np.argmax(fingers))
    return {
        "scenario": TELEOP, "description": DESCRIPTION, "action": "teleoperate",
        "reason": done.reason if done is not None else "none", "success": bool(done.success) if done else False,
        "end_time_s": trace.finished_ns / NS if done is not None else None,
        "goals_started_s": [g / NS for g in trace.goal_started_ns],
        "glove_silent_s": trace.last_glove_ns / NS,
        "stopped_after_silent_s": stopped_s,
        "touch_limit_n": limit_n,
        "peak_force_n": peaks,
        "held_fingers_rad": float(fingers[held]),
        "held_thumb_flexion_rad": float(trace.array("positions")[held, 1]),
        "thumb_rotation_range_rad": [float(np.min(trace.array("positions")[:, 2])),
                                     float(np.max(trace.array("positions")[:, 2]))],
        # the touch limit as a force set point: how far the pads went above it (never counted below)
        "force_set_points": {"touch_limit": {"set_point_n": limit_n, "used_error_n": over["used"],
                                             "true_error_n": over["true"]}},
        "force_error_n": max(over.values()),
    }


def plot(trace: TeleopTrace, summary: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = trace.array("stamps_ns") / NS
    fig, axes = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
    colours = ("tab:blue", "tab:orange", "tab:green")
    for i, (m, c) in enumerate(zip(MOTOR_NAMES, colours)):
        axes[0].plot(t, trace.array("targets")[:, i], color=c, label=m)
        axes[1].plot(t, trace.array("targets")[:, i], color=c, ls=":", lw=1)
        axes[1].plot(t, trace.array("positions")[:, i], color=c, label=m)
    axes[0].set_ylabel("operator's command:\nmotor target (rad)")
    axes[1].set_ylabel("motor position (rad)\n(dotted: target)")
    for i, f in enumerate(FINGERS[:2]):
        axes[2].plot(t, trace.array("forces_used")[:, i], color=colours[i], label=f"{f} Fz estimated")
        axes[2].plot(t, trace.array("forces_true")[:, i], color=colours[i], ls=":", label=f"{f} Fz true")
    axes[2].axhline(summary["touch_limit_n"], color="k", ls="--", lw=1, label="touch limit (max_pad_force)")
    axes[2].set_ylabel("pad normal force (N)")
    for ax in axes:
        ax.axvline(summary["glove_silent_s"], color="0.5", lw=1)
        ax.legend(loc="upper left", fontsize=8)
    axes[2].set_xlabel(f"time (s); grey line: the glove falls silent ({summary['glove_silent_s']:.2f} s)")
    fig.suptitle(f"teleop: ended {summary['reason']}, every motor stopped {summary['stopped_after_silent_s']:.2f} s "
                 f"after the glove's last sample; peak pad force {max(summary['peak_force_n']['used'].values()):.2f} N "
                 f"(limit {summary['touch_limit_n']:g} N)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
