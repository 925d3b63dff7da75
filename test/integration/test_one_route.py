"""One route from taxels to motors: the manipulation node on real rclpy and the off-robot closed loop
(prisma_manipulation.closed_loop, what prisma-sim records) decide alike.

A paper scenario runs off-robot first; every period's inputs (the motor driver's joint states, the
tactile hub's frames, the normal forces) are then published, period by period on a /clock the test
sets, into a ManipulationNode with config/manipulation.yaml, and the goal is sent at the period the
loop sent it. The motor driver is a stand-in action server that keeps each MoveMotors goal open
until the next one preempts it or a cancel ends it, as the motor driver does. Asserted equal, value
for value: every ContactState, every Grasp / Manipulate feedback, every MoveMotors goal (stamp,
velocities, lease timeout) and cancel, and the result with its stop reason and stop time.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import os

import numpy as np
import pytest

from prisma_testing.repo_paths import CONFIG
from prisma_testing.ros_harness import require_ros, stamp_ns

require_ros()

from geometry_msgs.msg import Vector3, Wrench, WrenchStamped  # noqa: E402
from prisma_msgs.action import Grasp, Manipulate, MoveMotors  # noqa: E402
from prisma_msgs.msg import HandContact  # noqa: E402
from rclpy.action import ActionClient, ActionServer, CancelResponse, GoalResponse  # noqa: E402
from rclpy.task import Future  # noqa: E402
from rosidl_runtime_py.utilities import get_message  # noqa: E402

from prisma_common.messages import make_header
from prisma_force_estimator.ros_conversions import hand_wrench_to_msg  # noqa: E402
from prisma_manipulation.contact_monitor import DEFAULT_K  # noqa: E402
from prisma_manipulation.manipulation_core import (  # noqa: E402
    Feedback,
    Finished,
    GraspRequest,
    SendMove,
    StopMotors,
)
from prisma_manipulation.manipulation_node import ManipulationNode  # noqa: E402
from prisma_manipulation.ros_conversions import contact_state_to_msg  # noqa: E402
from prisma_manipulation.scenarios import build  # noqa: E402
from prisma_motor_driver.ros_conversions import joint_state_to_msg
from prisma_tactile_driver.ros_conversions import hand_taxels_to_msg, taxel_frame_to_msg  # noqa: E402

NS = f"/route{os.getpid()}"


class MoveServer:
    """The motor driver's MoveMotors server as the manipulation node sees it: each goal runs until
    the next preempts it or a cancel stops it. Records (stamp, velocities, timeout) per goal and the
    stamp of each cancel."""

    def __init__(self, ros) -> None:
        self.ros = ros
        self.goals: list[tuple[int, dict[str, float], float]] = []
        self.cancels: list[int] = []
        self._open: dict[bytes, Future] = {}  # goal id -> resolved with how the goal ends
        self.server = ActionServer(ros.probe, MoveMotors, f"{NS}/prisma/motors/move", execute_callback=self._execute,
                                   goal_callback=lambda goal: GoalResponse.ACCEPT, cancel_callback=self._cancel)

    async def _execute(self, handle):
        goal = handle.request
        self.goals.append((self.ros.now_ns(), dict(zip(goal.motors, (float(v) for v in goal.targets))),
                           round(float(goal.timeout), 6)))
        for other in list(self._open.values()):
            other.set_result("preempted")
        ended, key = Future(), bytes(handle.goal_id.uuid)
        self._open[key] = ended
        reason = await ended
        del self._open[key]
        if reason == "canceled":
            handle.canceled()
        else:
            handle.abort()
        return MoveMotors.Result(success=False, reason=reason)

    def _cancel(self, handle) -> CancelResponse:
        self.cancels.append(self.ros.now_ns())
        ended = self._open.get(bytes(handle.goal_id.uuid))
        if ended is not None and not ended.done():
            ended.set_result("canceled")
        return CancelResponse.ACCEPT


def wrench_msg(finger: str, stamp: int, force: float) -> WrenchStamped:
    return WrenchStamped(header=make_header(get_message, stamp, f"prisma_{finger}_pad"),
                         wrench=Wrench(force=Vector3(x=0.0, y=0.0, z=float(force)), torque=Vector3()))


def f32(value: float) -> float:
    """As a float32 message field carries it (what the node's messages hold on arrival)."""
    return float(np.float32(value))


def feedback_values(feedback, grasp: bool) -> tuple:
    """What the action's feedback carries: Grasp the forces, Manipulate feasible and v_t."""
    values = getattr(feedback, "status", feedback)  # the core's Feedback: its kind's status; a message: itself
    if grasp:
        return feedback.phase, f32(values.finger_force), f32(values.thumb_force)
    return feedback.phase, bool(values.feasible), f32(values.threshold)


def contact_values(msg) -> tuple:
    return (msg.finger, stamp_ns(msg), tuple(np.asarray(msg.voltages, dtype=np.float32).tolist()),
            f32(msg.mean_voltage), f32(msg.k), f32(msg.threshold), tuple(bool(s) for s in msg.safe),
            tuple(msg.lost_edges), bool(msg.feasible))


@pytest.mark.parametrize("name", ["pinch_grasp", "combined"])
def test_the_node_decides_as_the_off_robot_loop(ros, name):
    # the off-robot run, from the clock the node will see, with the k a Manipulate goal message
    # carries (float32)
    scans = []
    scenario = build(name, k=f32(DEFAULT_K), observer=scans.append)
    scenario.loop.run(scenario.request, scenario.duration_s, start_ns=ros.START_NS, settle_s=scenario.settle_s)
    off_goals = [(s.stamp_ns, a.velocities_rpm, a.timeout_s)
                 for s in scans for a in s.actions if isinstance(a, SendMove)]
    off_cancels = [s.stamp_ns for s in scans for a in s.actions if isinstance(a, StopMotors)]
    grasp = isinstance(scenario.request, GraspRequest)
    off_feedback = [feedback_values(a, grasp) for s in scans for a in s.actions if isinstance(a, Feedback)]
    [finished] = [a for s in scans for a in s.actions if isinstance(a, Finished)]
    off_contacts = [contact_values(contact_state_to_msg(get_message, s.evaluations[f.finger], f"prisma_{f.finger}_pad"))
                    for s in scans for f in s.frames]

    # the node, fed the same inputs period by period
    ros.node(ManipulationNode, params_files=[CONFIG / "manipulation.yaml"], sim_time=True, namespace=NS)
    server = MoveServer(ros)
    contacts = ros.collect(HandContact, f"{NS}/prisma/hand/contact")
    action = f"{NS}/prisma/{'grasp' if grasp else 'manipulate'}"
    client = ActionClient(ros.probe, Grasp if grasp else Manipulate, action)
    assert ros.spin_until(client.server_is_ready, 10.0)
    r = scenario.request
    goal = (Grasp.Goal(grasp=r.grasp, finger_force=r.finger_force, thumb_force=r.thumb_force, speed_rpm=r.speed_rpm,
                       timeout=r.timeout_s) if grasp else
            Manipulate.Goal(motion=r.motion, speed_rpm=r.speed_rpm, k=r.k, use_force=r.use_force, timeout=r.timeout_s))
    feedback, handle = [], None
    for scan in scans:
        ros.set_time(scan.stamp_ns, settle=True)
        ros.publish(f"{NS}/joint_states", joint_state_to_msg(get_message, scan.stamp_ns, scan.states))
        ros.settle()
        samples = [taxel_frame_to_msg(get_message, frame, f"prisma_{frame.finger}_pad") for frame in scan.frames]
        ros.publish(f"{NS}/prisma/hand/taxels", hand_taxels_to_msg(get_message, samples))
        ros.settle()
        stamps = {frame.finger: frame.stamp_ns for frame in scan.frames}
        fingers = list(scan.forces)
        ros.publish(f"{NS}/prisma/hand/wrench", hand_wrench_to_msg(
            get_message, fingers, [wrench_msg(f, stamps[f], scan.forces[f]) for f in fingers]))
        ros.settle()
        if scan.goal_started:
            handle = ros.send_goal(client, goal, feedback=feedback)
            assert handle.accepted
            ros.settle()
    result = ros.result(handle, timeout_sec=10.0)

    assert [(stamp, velocities, timeout) for stamp, velocities, timeout in server.goals] == \
        [(stamp, velocities, round(timeout, 6)) for stamp, velocities, timeout in off_goals]
    assert server.cancels == off_cancels
    assert [feedback_values(f.feedback, grasp) for f in feedback] == off_feedback
    reason = result.result.reason if grasp else result.result.stop_reason
    assert (bool(result.result.success), reason) == (finished.success, finished.reason)
    if not grasp:
        assert result.result.stop_time == pytest.approx(finished.stop_time_s, abs=1e-6)
    node_contacts = [contact_values(c) for msg in contacts for c in msg.contacts]
    assert node_contacts == off_contacts
    print(f"{name}: {len(scans)} periods, {len(off_goals)} MoveMotors goals, {len(off_cancels)} cancels, "
          f"{len(off_feedback)} feedback, {len(off_contacts)} ContactStates alike; {finished.reason}")
