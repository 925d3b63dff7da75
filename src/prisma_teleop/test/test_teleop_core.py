"""The teleop node's decisions: the goal it keeps (sent once the glove flows, again after input_stale
once the glove is back, retried after a refusal for now, cancelled for another, given up with the
reason otherwise), the captures that build the calibration, and the STAG grasps."""
from __future__ import annotations

import pytest

from prisma_teleop.calibration import POSES
from prisma_teleop.node_config import TeleopConfig
from prisma_teleop.retargeting import DEFAULT_JOINTS, nominal_calibration
from prisma_teleop.stag_poses import GraspCommand, OpenCommand
from prisma_teleop.synthetic_glove_core import Synergies, hand_pose
from prisma_teleop.teleop_core import (
    RESUME_SAMPLES,
    CancelGoal,
    GoalKeeper,
    HandPoseTeleop,
    Note,
    SendGoal,
    StagTeleop,
    TeleopGoal,
)

NS = 1_000_000_000
PERIOD_NS = NS // 60
CAL = nominal_calibration()
OPEN = Synergies(0.0, 0.0, 0.0)


def sends(actions: list) -> list:
    return [a.command for a in actions if isinstance(a, SendGoal)]


def cancels(actions: list) -> list:
    return [a for a in actions if isinstance(a, CancelGoal)]


def notes(actions: list, level: str) -> list[str]:
    return [a.text for a in actions if isinstance(a, Note) and a.level == level]


class Glove:
    """Feeds a HandPoseTeleop one sample per glove period; now = the sample's receipt."""

    def __init__(self, core: HandPoseTeleop, t_ns: int = NS) -> None:
        self.core, self.t_ns = core, t_ns

    def samples(self, n: int, command: Synergies = OPEN) -> list:
        actions: list = []
        for _ in range(n):
            self.t_ns += PERIOD_NS
            _, out = self.core.on_sample(self.t_ns, hand_pose(command, CAL), self.t_ns)
            actions += out
        return actions


def engaged_core(**params) -> HandPoseTeleop:
    return HandPoseTeleop(TeleopConfig(engage_at_start=True, **params), CAL)


def test_goal_keeper_sends_cancels_and_retries():
    keeper = GoalKeeper(retry_period_ns=NS // 2)
    pinch, power = GraspCommand("pinch", 1.0, 1.2, "pinch"), GraspCommand("power", 1.5, 1.9, "power")
    assert keeper.want(pinch, 0) == [SendGoal(pinch)]
    assert keeper.want(pinch, 1) == []  # on its way
    assert keeper.want(GraspCommand("pinch", 1.1, 1.3, "tripod"), 2) == []  # the same grasp
    assert cancels(keeper.want(power, 3))
    assert keeper.want(power, 4) == []  # until the cancel ended it
    assert keeper.ended("canceled", True, 5) == (pinch, False)
    assert keeper.want(power, 5) == [SendGoal(power)]
    assert keeper.ended("busy: a grasp goal is running", False, NS) == (power, False)
    assert keeper.want(power, NS + NS // 2 - 1) == []  # not before retry_period
    assert keeper.want(power, NS + NS // 2) == [SendGoal(power)]
    assert keeper.ended("force_reached", True, 2 * NS) == (power, True)
    assert keeper.want(power, 3 * NS) == []  # ended for good: not again


def test_a_teleoperate_goal_once_the_glove_flows_and_only_when_engaged():
    idle = HandPoseTeleop(TeleopConfig(), CAL)
    assert sends(Glove(idle).samples(30)) == []  # not engaged
    core = engaged_core(max_pad_force=1.5, input_timeout=0.2)
    glove = Glove(core)
    assert sends(glove.samples(RESUME_SAMPLES - 1)) == []
    assert sends(glove.samples(1)) == [TeleopGoal(1.5, 0.0, 0.2)]
    assert sends(glove.samples(60)) == []  # one goal


def test_targets_follow_the_operator():
    core = engaged_core()
    targets, _ = core.on_sample(NS, hand_pose(Synergies(1.0, 1.0, 1.0), CAL), NS)
    assert targets == {"fingers": 9.0, "thumb_flexion": 7.0, "thumb_rotation": 1.5}
    bad, actions = core.on_sample(NS + PERIOD_NS, {"index_mcp": 0.1}, NS + PERIOD_NS)
    assert bad is None and notes(actions, "warning")[0].startswith("glove sample ignored: hand pose lacks index_pip")


def test_input_stale_resumes_once_the_glove_is_back():
    core = engaged_core()
    glove = Glove(core)
    assert sends(glove.samples(RESUME_SAMPLES))
    glove.t_ns += NS // 2  # the glove falls silent; the manipulation node ends the goal
    actions = core.on_goal_ended("input_stale: prisma/teleop/motor_targets silent for 160 ms", False, glove.t_ns)
    assert sends(actions) == [] and "resumes once the glove is back" in notes(actions, "warning")[0]
    assert sends(core.tick(glove.t_ns + NS)) == []  # still silent
    assert sends(glove.samples(RESUME_SAMPLES - 1)) == []
    assert sends(glove.samples(1)) == [TeleopGoal()]
    assert core.engaged


@pytest.mark.parametrize("reason", ["sensor_stale: taxels/index silent for 110 ms", "motor_fault: overload",
                                    "canceled"])
def test_any_other_end_disengages(reason):
    core = engaged_core()
    glove = Glove(core)
    glove.samples(RESUME_SAMPLES)
    actions = core.on_goal_ended(reason, reason == "canceled", glove.t_ns)
    assert not core.engaged
    level = "warning" if reason == "canceled" else "error"
    assert notes(actions, level) == [f"Teleoperate ended {reason}: disengaged; call ~/engage to resume"]
    assert sends(glove.samples(30)) == []
    _, actions = core.engage(True, glove.t_ns)
    assert sends(actions + glove.samples(1)) == [TeleopGoal()]


def test_a_refusal_for_now_is_sent_again_after_the_retry_period():
    core = engaged_core(retry_period=0.5)
    glove = Glove(core)
    glove.samples(RESUME_SAMPLES)
    actions = core.on_goal_ended("not_ready: joint_states not received yet", False, glove.t_ns)
    assert sends(actions) == [] and core.engaged
    assert sends(glove.samples(29)) == []  # 0.48 s
    assert sends(glove.samples(2)) == [TeleopGoal()]


def test_disengaging_cancels_the_running_goal():
    core = engaged_core()
    glove = Glove(core)
    glove.samples(RESUME_SAMPLES)
    message, actions = core.engage(False, glove.t_ns)
    assert message == "disengaged" and cancels(actions)
    assert sends(core.on_goal_ended("canceled", True, glove.t_ns)) == []
    assert core.engage(False, glove.t_ns)[0] == "already disengaged"


def test_captures_build_the_calibration_in_use_once_complete():
    core = HandPoseTeleop(TeleopConfig(capture_samples=5), CAL)
    assert core.capture("fist") == (False, "no glove sample yet on glove/joint_states: nothing to capture", None)
    operator_fist = {j: 0.8 * CAL.fist[j] for j in DEFAULT_JOINTS.flexion()}  # a stiffer hand than the nominal
    glove = Glove(core)
    glove.samples(5, Synergies(0.8, 0.8, 0.0))  # the operator's fist: 80 % of the nominal one
    ok, message, complete = core.capture("fist")
    assert ok and message == "captured fist (5 samples); calibration in use"
    assert complete is not None
    assert {j: complete.fist[j] for j in operator_fist} == pytest.approx(operator_fist, abs=1e-9)
    targets, _ = core.on_sample(glove.t_ns + NS, hand_pose(Synergies(0.8, 0.8, 0.0), CAL), glove.t_ns + NS)
    assert targets["fingers"] == pytest.approx(9.0) and targets["thumb_flexion"] == pytest.approx(7.0)


def test_an_incomplete_calibration_is_not_used():
    core = HandPoseTeleop(TeleopConfig(capture_samples=3), CAL)
    glove = Glove(core)
    glove.samples(3, Synergies(1.0, 1.0, 0.0))  # a fist, captured as the open hand
    ok, message, complete = core.capture("open_hand")
    assert ok and complete is None
    assert message.startswith("captured open hand (3 samples); the calibration in use is unchanged until the rest is "
                              "captured: index_mcp: fist 1.396 rad and open hand 1.396 rad are less than 0.1 rad apart")
    assert core.calibration == CAL
    glove.samples(3, Synergies(0.0, 0.0, 0.0))
    ok, message, complete = core.capture("fist")  # the open hand as the fist: the range reversed, and complete
    assert complete is not None and core.calibration.open_hand["index_mcp"] == pytest.approx(CAL.fist["index_mcp"])
    assert set(POSES) == {"open_hand", "fist", "thumb_adducted", "thumb_opposed"}


def stag(**params) -> StagTeleop:
    return StagTeleop(TeleopConfig(input="stag", engage_at_start=True, **params))


def poses(core: StagTeleop, labels: list[str], pressure: float = 30.0, start_ns: int = NS) -> list:
    actions: list = []
    for i, label in enumerate(labels):
        t = start_ns + i * NS // 7
        core.on_frame(t, pressure, False)
        actions += core.on_pose(t, label, 0.98, t)
    return actions


def test_stag_poses_start_grasps_and_the_empty_hand_opens():
    core = stag(pose_frames=3)
    first = poses(core, ["pinch"] * 3)
    (pinch,) = sends(first)
    assert (pinch.grasp, pinch.finger_force) == ("pinch", pytest.approx(1.0667, abs=1e-3))
    assert notes(first, "info")[0].startswith("pose pinch held 3 frames (pressure 30.0): Grasp pinch")
    assert sends(core.on_goal_ended("force_reached", True, 2 * NS)) == []  # held: nothing more
    actions = poses(core, ["empty"] * 3, pressure=1.0, start_ns=3 * NS)
    assert sends(actions) == [OpenCommand("empty")]
    assert cancels(poses(core, ["power"] * 3, start_ns=4 * NS))  # the open still runs: cancel it first
    assert sends(core.on_goal_ended("canceled", True, 5 * NS))[0].grasp == "power"


def test_stag_without_its_frame_pressure_says_so():
    core = stag()
    assert notes(core.on_pose(NS, "pinch", 0.9, NS), "warning") == [
        "pose estimate ignored: no glove frame (stag/frame) for its pressure yet"]
