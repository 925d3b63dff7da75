"""The teleop node's decisions: the goal it keeps (sent once the glove flows, again after input_stale
once the glove is back, retried after a refusal for now, cancelled for another, given up with the
reason otherwise), the captures that build the calibration, and the STAG grasps."""
from __future__ import annotations

from dataclasses import replace

import pytest

from prisma_common.diagnostics import OK, WARN
from prisma_teleop.calibration import POSES
from prisma_teleop.node_config import TeleopConfig
from prisma_teleop.retargeting import DEFAULT_JOINTS, nominal_calibration
from prisma_teleop.stag_poses import GraspCommand, OpenCommand
from prisma_teleop.synthetic_glove_core import Synergies, hand_pose
from prisma_teleop.teleop_core import (
    MIN_SEND_INTERVAL_NS,
    RESUME_SAMPLES,
    CancelGoal,
    GoalKeeper,
    HandPoseTeleop,
    Note,
    SendGoal,
    StagTeleop,
    TeleopGoal,
    describe,
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
    assert keeper.want(power, 5) == []  # at most one goal per MIN_SEND_INTERVAL_NS
    assert keeper.want(power, MIN_SEND_INTERVAL_NS) == [SendGoal(power)]
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


def capture(core: HandPoseTeleop, glove: Glove, pose: str, command: Synergies) -> tuple:
    glove.samples(core.config.capture_samples, command)
    return core.capture(pose)


OPERATOR_POSES = {"open_hand": OPEN, "fist": Synergies(0.8, 0.8, 0.0), "thumb_adducted": Synergies(0.0, 0.0, -0.9),
                  "thumb_opposed": Synergies(0.0, 0.0, 0.9)}


def test_captures_build_the_calibration_in_use_once_the_operator_captured_all_four_poses():
    core = HandPoseTeleop(TeleopConfig(capture_samples=5), CAL)
    assert core.capture("fist") == (False, "no glove sample yet on glove/joint_states: nothing to capture", None)
    operator_fist = {j: 0.8 * CAL.fist[j] for j in DEFAULT_JOINTS.flexion()}  # a stiffer hand than the nominal
    glove = Glove(core)
    ok, message, complete = capture(core, glove, "fist", OPERATOR_POSES["fist"])
    assert (ok, complete) == (True, None)  # the nominal hand's other three poses are not the operator's
    assert message == ("captured fist (5 samples); the calibration in use (nominal hand) is unchanged until open hand, "
                       "thumb adducted, thumb opposed are captured too")
    for pose in ("open_hand", "thumb_adducted"):
        assert capture(core, glove, pose, OPERATOR_POSES[pose])[2] is None
    assert core.calibration == CAL and core.diagnostics(glove.t_ns).values["calibration_complete"] == \
        "no: thumb opposed to capture"
    ok, message, complete = capture(core, glove, "thumb_opposed", OPERATOR_POSES["thumb_opposed"])
    assert ok and message == "captured thumb opposed (5 samples); calibration in use"
    assert complete is not None and complete.operator == "captured" and core.calibration == complete
    assert {j: complete.fist[j] for j in operator_fist} == pytest.approx(operator_fist, abs=1e-9)
    values = core.diagnostics(glove.t_ns).values
    assert (values["calibration_operator"], values["calibration_complete"]) == ("captured", "yes")
    targets, _ = core.on_sample(glove.t_ns + NS, hand_pose(Synergies(0.8, 0.8, 0.0), CAL), glove.t_ns + NS)
    assert targets["fingers"] == pytest.approx(9.0) and targets["thumb_flexion"] == pytest.approx(7.0)


def test_an_operators_file_recaptured_pose_by_pose_is_in_use_at_once():
    loaded = replace(CAL, operator="alice")
    core = HandPoseTeleop(TeleopConfig(capture_samples=3), loaded, captured=True)
    ok, message, complete = capture(core, Glove(core), "fist", OPERATOR_POSES["fist"])
    assert message == "captured fist (3 samples); calibration in use"
    assert complete is not None and complete.operator == "alice"


def test_an_unusable_calibration_is_not_used():
    core = HandPoseTeleop(TeleopConfig(capture_samples=3), CAL)
    glove = Glove(core)
    for pose in ("open_hand", "fist"):  # a fist captured as the open hand, the open hand as the fist: both the fist
        capture(core, glove, pose, Synergies(1.0, 1.0, 0.0))
    capture(core, glove, "thumb_adducted", OPERATOR_POSES["thumb_adducted"])
    ok, message, complete = capture(core, glove, "thumb_opposed", OPERATOR_POSES["thumb_opposed"])
    assert ok and complete is None and core.calibration == CAL
    assert message.startswith("captured thumb opposed (3 samples); the calibration in use (nominal hand) is unchanged: "
                              "index_mcp: fist 1.396 rad and open hand 1.396 rad are less than 0.1 rad apart")
    assert set(POSES) == {"open_hand", "fist", "thumb_adducted", "thumb_opposed"}


class BadGlove(Glove):
    """A glove whose stamps are `stamp(receipt)`: 0, or seconds old."""

    def stamped(self, n: int, stamp, command: Synergies = OPEN) -> tuple[list, list]:
        actions: list = []
        targets: list = []
        for _ in range(n):
            self.t_ns += PERIOD_NS
            out, more = self.core.on_sample(stamp(self.t_ns), hand_pose(command, CAL), self.t_ns)
            targets += [out] if out is not None else []
            actions += more
        return targets, actions


def test_a_glove_stamped_0_then_5_s_old_moves_nothing_and_is_said_once_each():
    core = engaged_core()
    glove = BadGlove(core, t_ns=1_796_664_778 * NS)
    targets, actions = glove.stamped(600, lambda t: 0, Synergies(1.0, 1.0, 0.0))  # 10 s of a fist at 60 Hz
    assert (targets, sends(actions)) == ([], [])
    assert notes(actions, "warning") == ["glove/joint_states stamped 0: publish header.stamp (ros2 topic pub: "
                                         "header: auto); its samples are refused until then"]
    status = core.diagnostics(glove.t_ns)
    assert status.level == WARN and status.message.startswith("input refused: glove/joint_states stamped 0")
    assert (status.values["input_age_ms"], status.values["goals_sent"]) == ("stamped 0", "0")
    targets, actions = glove.stamped(600, lambda t: t - 5 * NS, Synergies(1.0, 1.0, 0.0))
    assert (targets, sends(actions)) == ([], [])
    (line,) = notes(actions, "warning")
    assert line.startswith("glove/joint_states stamped 5.00 s before it arrived (limit 0.5 s): stamp each sample")
    status = core.diagnostics(glove.t_ns)
    assert status.values["input_rate_hz"] == "60.0" and status.values["input_age_ms"] == "5000"
    assert core.capture("fist")[1].startswith("nothing to capture: glove/joint_states stamped 5.00 s")
    # stamped when taken: accepted again, and the goal follows
    targets, actions = glove.stamped(RESUME_SAMPLES, lambda t: t)
    assert len(targets) == RESUME_SAMPLES and sends(actions) == [TeleopGoal()]
    assert notes(actions, "info") == ["glove/joint_states accepted again (1200 samples refused: stamped 5.00 s "
                                      "before it arrived)"]
    assert core.diagnostics(glove.t_ns).values["input_refused"] == "no"


def test_goals_that_end_at_once_are_sent_at_most_four_a_second():
    core = engaged_core(retry_period=0.01)
    glove = Glove(core)
    sent = 0
    for _ in range(600):  # 10 s; every goal refused for now as soon as it is sent
        actions = glove.samples(1)
        while sends(actions):
            sent += len(sends(actions))
            actions = core.on_goal_ended("not_ready: prisma/teleop/motor_targets not received yet", False, glove.t_ns)
    # one per MIN_SEND_INTERVAL_NS (0.25 s: the 16th sample of 16.7 ms after the last), not one per sample
    assert sent == 38 and MIN_SEND_INTERVAL_NS == NS // 4
    assert core.diagnostics(glove.t_ns).values["last_goal_end"] == "not_ready: prisma/teleop/motor_targets not " \
                                                                    "received yet"


def test_the_status_of_an_engaged_teleop():
    core = engaged_core()
    glove = Glove(core)
    assert core.diagnostics(glove.t_ns).message == "engaged, no input on glove/joint_states"
    glove.samples(RESUME_SAMPLES + 57)
    status = core.diagnostics(glove.t_ns)
    assert (status.name, status.level, status.message) == ("teleop", OK, "engaged: Teleoperate running")
    assert status.values == {
        "engaged": "true", "input": "glove/joint_states", "input_rate_hz": "60.0", "input_age_ms": "0",
        "input_silent_ms": "0", "input_refused": "no", "input_refused_samples": "0", "goals_sent": "1",
        "goal_running": "Teleoperate", "last_goal": "none", "last_goal_end": "none",
        "episode": "none open", "episode_task": "teleoperate the PRISMA hand", "last_episode": "none",
        "calibration_operator": "nominal hand", "calibration_complete": "no: open hand, fist, thumb adducted, "
                                                                        "thumb opposed to capture"}
    core.on_goal_ended("sensor_stale: taxels/index silent for 110 ms", False, glove.t_ns)
    status = core.diagnostics(glove.t_ns + NS)
    assert status.message == "disengaged (~/engage)"
    assert (status.values["last_goal"], status.values["last_goal_end"]) == (
        "Teleoperate", "sensor_stale: taxels/index silent for 110 ms")
    assert status.values["input_rate_hz"] == "0.0"


def stag(**params) -> StagTeleop:
    """A StagTeleop that has seen the empty hand first (a grasp pose's start seen)."""
    core = StagTeleop(TeleopConfig(input="stag", engage_at_start=True, **params))
    core.on_frame(NS // 2, 1.0, False)
    core.on_pose(NS // 2, "empty", 0.98, NS // 2)
    return core


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
    core = StagTeleop(TeleopConfig(input="stag", engage_at_start=True))
    assert notes(core.on_pose(NS, "pinch", 0.9, NS), "warning") == [
        "pose estimate ignored: no glove frame (stag/frame) for its pressure yet"]


def test_stag_a_grasp_the_hand_was_not_ready_for_waits_for_the_pose_formed_anew():
    core = stag(pose_frames=3)
    (pinch,) = sends(poses(core, ["pinch"] * 3))
    actions = core.on_goal_ended("not_ready: no action server prisma/grasp (is the manipulation node running?)",
                                 False, 2 * NS)
    assert notes(actions, "warning") == [
        f"{describe(pinch)} ended not_ready: no action server prisma/grasp (is the manipulation node running?): not "
        "sent again; form the pose anew once the hand is ready"]
    assert sends(poses(core, ["pinch"] * 10, start_ns=3 * NS)) == []  # the pose held on: its end, not a grasp
    assert sends(poses(core, ["empty"] * 3, pressure=1.0, start_ns=5 * NS)) == [OpenCommand("empty")]
    core.on_goal_ended("succeeded", True, 6 * NS)
    assert [c.grasp for c in sends(poses(core, ["pinch"] * 3, start_ns=7 * NS))] == ["pinch"]  # formed anew


def test_stag_a_grasp_at_the_joint_limit_says_the_object_is_gone_and_how_to_put_it_back():
    core = StagTeleop(TeleopConfig(input="stag", engage_at_start=True, pose_frames=3), "/left/stag/hand_pose",
                      "/left/tactile_driver/replace_object")
    poses(core, ["empty"], pressure=1.0, start_ns=0)
    (pinch,) = sends(poses(core, ["pinch"] * 3))
    (line,) = notes(core.on_goal_ended("joint_limit", False, 2 * NS), "warning")
    assert line == (f"{describe(pinch)} ended joint_limit: the fingers closed to their limit without touching "
                    "anything, the object is not between them (an open hand lets it fall). Put it back (the sim "
                    "and emulated hand: ros2 service call /left/tactile_driver/replace_object std_srvs/srv/Trigger), "
                    "then form the pose again")


def test_stag_a_pose_already_held_when_teleoperation_begins_is_not_started_from_its_end():
    core = StagTeleop(TeleopConfig(input="stag", engage_at_start=True, pose_frames=3))
    actions = poses(core, ["pinch"] * 5)  # a replay already mid-pinch when the node starts
    assert sends(actions) == []
    assert notes(actions, "info")[0].endswith("not started: the pose was already held when teleoperation began (a "
                                              "grasp from its end would be cancelled by the next pose at once): form "
                                              "it anew")
    assert sends(poses(core, ["empty"] * 3, pressure=1.0, start_ns=2 * NS)) == [OpenCommand("empty")]
    core.on_goal_ended("succeeded", True, 3 * NS)
    assert [c.grasp for c in sends(poses(core, ["pinch"] * 3, start_ns=4 * NS))] == ["pinch"]  # formed anew
    # engaged again mid-pose: the same
    core.on_goal_ended("force_reached", True, 5 * NS)
    core.engage(False, 5 * NS)
    core.engage(True, 5 * NS)
    assert sends(poses(core, ["power"] * 5, start_ns=6 * NS)) == []
