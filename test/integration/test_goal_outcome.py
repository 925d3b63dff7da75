"""ros_harness's goal outcome helpers: GoalStatus numbers named from action_msgs' own constants,
(status, reason) of each action's result as the tests compare them, and the one refusal a test sends
a goal again for (not_ready)."""
from __future__ import annotations

from prisma_testing.goals import goal_outcome, goal_status_name, goal_status_names, refusal_for_now
from prisma_testing.ros_harness import require_ros

require_ros()

from action_msgs.msg import GoalStatus  # noqa: E402
from control_msgs.action import GripperCommand  # noqa: E402
from prisma_msgs.action import Grasp, Manipulate  # noqa: E402


def test_status_names_are_action_msgs_constants():
    assert goal_status_names() == {0: "UNKNOWN", 1: "ACCEPTED", 2: "EXECUTING", 3: "CANCELING", 4: "SUCCEEDED",
                                   5: "CANCELED", 6: "ABORTED"}
    assert goal_status_name(GoalStatus.STATUS_ABORTED) == "ABORTED" and goal_status_name(42) == "42"


def test_outcome_of_each_action_result():
    grasp = Grasp.Impl.GetResultService.Response(status=GoalStatus.STATUS_SUCCEEDED,
                                                 result=Grasp.Result(reason="force_reached"))
    manipulate = Manipulate.Impl.GetResultService.Response(status=GoalStatus.STATUS_CANCELED,
                                                           result=Manipulate.Result(stop_reason="canceled"))
    assert goal_outcome(grasp) == ("SUCCEEDED", "force_reached")
    assert goal_outcome(manipulate) == ("CANCELED", "canceled")
    for (reached, stalled), reason in {(True, False): "reached_goal", (False, True): "stalled",
                                       (False, False): "neither"}.items():
        gripper = GripperCommand.Impl.GetResultService.Response(
            status=GoalStatus.STATUS_ABORTED, result=GripperCommand.Result(reached_goal=reached, stalled=stalled))
        assert goal_outcome(gripper) == ("ABORTED", reason)


def test_only_not_ready_is_a_refusal_to_send_again():
    not_ready = "not_ready: no wrench/thumb received yet"
    assert refusal_for_now(Grasp.Result(reason=not_ready)) == not_ready
    assert refusal_for_now(Manipulate.Result(stop_reason=not_ready)) == not_ready
    for reason in ("busy: a grasp goal is running", "sensor_stale", "joint_limit", "timeout", "force_reached",
                   "invalid: k 2.0 outside (0.0, 1.5]", "not_homed: fingers", "not_ready"):
        assert refusal_for_now(Grasp.Result(reason=reason)) is None, reason
    assert refusal_for_now(GripperCommand.Result()) is None  # no text: its refusal is the node's log line
