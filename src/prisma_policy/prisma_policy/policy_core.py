"""The policy node's decisions, ROS-free: what the policy observes (the newest taxels and wrench per
finger, the newest motor positions and velocities, each with its stamp) and, per tick, either the three
motor targets to publish or why not (`Act` / `Hold`), plus when to send the Teleoperate goal.

A tick acts only on fresh inputs: every finger's taxels and wrench and the joint states, each stamped
at most `max_input_age` before the tick and not ahead of it. Anything missing or stale holds the
policy: nothing is published, so the manipulation core's stale-input stop (the Teleoperate goal's
input_timeout) stops the hand, as for a glove that falls silent. The targets go out with the tick's
stamp; the goal is sent with the first targets (they flow first, as from the teleop node) and again
`RETRY_S` after a goal ended while the policy still acts.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from prisma_common.diagnostics import ERROR, OK, WARN, DiagnosticStatusData
from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_motor_driver.control_table import rpm_to_rad_s

from .bc_policy import Policy

NS = 1_000_000_000
RETRY_S = 0.5  # the teleop node's retry_period default: a goal the hand ended or refused is sent again after it


@dataclass(frozen=True)
class Act:
    """Publish these targets (motor -> rad) stamped `stamp_ns`; `send_goal`: send the Teleoperate goal too."""

    stamp_ns: int
    targets: dict[str, float]
    send_goal: bool


@dataclass(frozen=True)
class Hold:
    """Nothing published this tick, and why (one line, naming the input and its age)."""

    reason: str


class PolicyCore:
    def __init__(self, policy: Policy | None, max_input_age_s: float, no_model_reason: str = "no model") -> None:
        self.policy = policy
        self.max_age_ns = int(round(max_input_age_s * NS))
        self.no_model_reason = no_model_reason
        self.tactile = np.zeros((len(FINGERS), 3, 3))
        self.wrench = np.zeros((len(FINGERS), 6))
        self.state = np.zeros(2 * len(MOTOR_NAMES))
        self.stamps: dict[str, int] = {}  # input name ("taxels/index", "wrench/thumb", "joint_states") -> stamp
        self.goal_running = False
        self.goal_retry_ns: int | None = None  # no goal before this (one ended or was refused)
        self.holding: str | None = None  # why the last tick published nothing; None while it acts
        self.acts = 0  # ticks that published targets
        self.goals_sent = 0
        self.last_goal_end = "none"

    # ---- inputs --------------------------------------------------------------------------------
    def on_taxels(self, finger: str, stamp_ns: int, voltages: np.ndarray) -> None:
        if finger in FINGERS:
            self.tactile[FINGERS.index(finger)] = np.asarray(voltages, dtype=np.float64).reshape(3, 3)
            self.stamps[f"taxels/{finger}"] = stamp_ns

    def on_wrench(self, finger: str, stamp_ns: int, wrench: np.ndarray) -> None:
        if finger in FINGERS:
            self.wrench[FINGERS.index(finger)] = np.asarray(wrench, dtype=np.float64).reshape(6)
            self.stamps[f"wrench/{finger}"] = stamp_ns

    def on_joints(self, stamp_ns: int, positions: Mapping[str, float], velocities_rpm: Mapping[str, float]) -> bool:
        """False (and nothing taken) for a JointState without every motor's position and velocity."""
        if not all(m in positions and m in velocities_rpm for m in MOTOR_NAMES):
            return False
        self.state = np.array([positions[m] for m in MOTOR_NAMES]
                              + [rpm_to_rad_s(velocities_rpm[m]) for m in MOTOR_NAMES], dtype=np.float64)
        self.stamps["joint_states"] = stamp_ns
        return True

    # ---- decisions -----------------------------------------------------------------------------
    def stale_input(self, now_ns: int) -> str | None:
        """The first input missing, older than max_input_age or stamped ahead of `now_ns`, in words."""
        for name in (*(f"taxels/{f}" for f in FINGERS), *(f"wrench/{f}" for f in FINGERS), "joint_states"):
            stamp = self.stamps.get(name)
            if stamp is None:
                return f"no {name} sample yet"
            age = now_ns - stamp
            if age > self.max_age_ns:
                return f"{name} is {age / NS:.3f} s old (max_input_age {self.max_age_ns / NS:g} s)"
            if age < 0:
                return f"{name} is stamped {-age / NS:.3f} s ahead of this node's clock"
        return None

    def tick(self, now_ns: int) -> Act | Hold:
        reason = self.no_model_reason if self.policy is None else self.stale_input(now_ns)
        self.holding = reason
        if reason is not None:
            return Hold(reason)
        assert self.policy is not None
        targets = self.policy.act(self.tactile, self.wrench, self.state)
        send = not self.goal_running and (self.goal_retry_ns is None or now_ns >= self.goal_retry_ns)
        if send:
            self.goal_running = True
            self.goals_sent += 1
        self.acts += 1
        return Act(now_ns, dict(zip(MOTOR_NAMES, map(float, targets))), send)

    def on_goal_ended(self, now_ns: int, reason: str = "ended") -> None:
        """The goal ended (input_stale, aborted, refused: `reason`): the next one after RETRY_S, if the
        policy acts."""
        self.goal_running = False
        self.goal_retry_ns = now_ns + int(RETRY_S * NS)
        self.last_goal_end = reason

    def diagnostics(self) -> DiagnosticStatusData:
        """The node's status (name `policy`): ERROR without a model, WARN while it holds (with why), OK
        while it acts; the targets published, the goals sent and how the last one ended."""
        model = "none" if self.policy is None else f"{self.policy.episodes} episodes at {self.policy.fps} fps"
        values = {"model": model,
                  "targets_published": str(self.acts), "goals_sent": str(self.goals_sent),
                  "goal_running": str(self.goal_running).lower(), "last_goal_end": self.last_goal_end}
        if self.policy is None:
            level, message = ERROR, self.no_model_reason
        elif self.holding is not None:
            level, message = WARN, f"publishing nothing: {self.holding}"
        else:
            level, message = OK, "acting"
        return DiagnosticStatusData("policy", level, message, values=values)

    def period_s(self, rate_hz: float) -> float:
        """The tick period: `rate_hz`, or the model's fps when 0 (10 Hz without a model, to say why)."""
        if rate_hz > 0:
            return 1.0 / rate_hz
        return 1.0 / self.policy.fps if self.policy is not None else 0.1
