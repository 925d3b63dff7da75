"""motor_driver and manipulation nodes on the rclpy stand-in (test/standin), closed through a sensor
side in the test: the hand/world model fed by /joint_states, PadModel taxels and ground-truth Fz
wrenches published every 10 ms with the test clock's stamps."""
from __future__ import annotations

from dataclasses import replace

import pytest
from action_msgs.msg import GoalStatus
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3, Wrench, WrenchStamped
from prisma_msgs.action import Grasp, Manipulate, MoveMotors
from prisma_msgs.msg import ContactState, TaxelArray
from rclpy.parameter import Parameter
from rosidl_runtime_py.utilities import get_message
from sensor_msgs.msg import JointState

from prisma_manipulation.hand_world import OBJECTS, HandWorld, released
from prisma_manipulation.manipulation_node import ManipulationNode
from prisma_manipulation.motor_driver_node import MotorDriverNode
from prisma_tactile_driver.pad_model import PadModel
from prisma_tactile_driver.ros_conversions import make_header, ns_from_stamp, taxel_frame_to_msg
from prisma_tactile_driver.taxels import FINGERS, TaxelFrame

MS = 1_000_000


class SensorSide:
    """Fingertip hub + force estimator stand-ins driven by the hand/world model."""

    def __init__(self, ros, world: HandWorld) -> None:
        self.ros, self.world = ros, world
        self.pads = {f: PadModel(seed=i) for i, f in enumerate(FINGERS)}
        self.age_ns = 0  # stamps this much older than the clock
        self.silent = False
        self.published = 0
        ros.probe.create_subscription(JointState, "/joint_states", self._on_joints, 10)
        self.taxels = {f: ros.publisher(TaxelArray, f"/prisma/{f}/taxels", 10) for f in FINGERS}
        self.wrenches = {f: ros.publisher(WrenchStamped, f"/prisma/{f}/wrench", 10) for f in FINGERS}
        self.timer = ros.probe.create_timer(0.01, self._tick)

    def _on_joints(self, msg) -> None:
        self.world.update_joints(dict(zip(msg.name, (float(p) for p in msg.position))), ns_from_stamp(msg.header.stamp))

    def _tick(self) -> None:
        if self.silent:
            return
        stamp = self.ros.now_ns() - self.age_ns
        for f in FINGERS:
            frame = TaxelFrame.from_counts(f, stamp, self.pads[f].sample(self.world.contact(f)))
            self.taxels[f].publish(taxel_frame_to_msg(frame, get_message, f"prisma_{f}_pad"))
            force = Vector3(x=0.0, y=0.0, z=float(self.world.forces()[f]))
            self.wrenches[f].publish(WrenchStamped(header=make_header(get_message, stamp, f"prisma_{f}_pad"),
                                                   wrench=Wrench(force=force, torque=Vector3(x=0.0, y=0.0, z=0.0))))
        self.published += 1


def stand_world() -> HandWorld:
    return HandWorld(obj=replace(OBJECTS["pinch_ball"], release_force_n=None, fixture_n_per_mm=5.0))


def pinched_world() -> HandWorld:
    world = HandWorld(obj=released("pinch_ball"))
    world.set_positions(world.grasp_pose(1.0))
    return world


@pytest.fixture
def hand(ros):
    """Motor driver (sim) + manipulation node + sensor side; returns a namespace of handles."""

    def make(world: HandWorld, **manipulation_params):
        positions = [world.positions[m] for m in ("fingers", "thumb_flexion", "thumb_rotation")]
        ros.override(node="motor_driver", sim_initial_positions=positions)
        if manipulation_params:
            ros.override(node="manipulation", **manipulation_params)
        motor = MotorDriverNode()
        goals = []
        original = motor.core.start

        def spy(goal, now_ns):  # record every MoveMotors goal the driver starts
            goals.append(goal)
            return original(goal, now_ns)

        motor.core.start = spy
        manipulation = ManipulationNode()
        sensors = SensorSide(ros, world)
        joints = ros.collect(JointState, "/joint_states")
        ros.advance(0.05)
        return type("Hand", (), dict(motor=motor, manipulation=manipulation, sensors=sensors,
                                      move_goals=goals, joints=joints, world=world))

    return make


def send(ros, name, action, goal, feedback=None):
    client = ros.action_client(action, name)
    future = client.send_goal_async(goal, feedback_callback=feedback)
    assert ros.spin_until(future, timeout_sec=1.0)
    return future.result()


def velocity(joints, motor):
    msg = joints[-1]
    return float(msg.velocity[list(msg.name).index(motor)])


def position(joints, motor):
    msg = joints[-1]
    return float(msg.position[list(msg.name).index(motor)])


def test_grasp_goal_moves_the_motors_streams_feedback_and_returns_the_forces(ros, hand):
    h = hand(stand_world())
    feedback = []
    handle = send(ros, "/prisma/grasp", Grasp, Grasp.Goal(grasp="pinch", finger_force=0.8, thumb_force=1.0,
                                                          speed_rpm=60.0, timeout=5.0), feedback.append)
    assert handle.accepted
    result = handle.get_result_async()
    assert ros.spin_until(result, timeout_sec=5.0)
    assert result.result().status == GoalStatus.STATUS_SUCCEEDED
    r = result.result().result
    assert r.success and r.reason == "force_reached"
    assert 1.0 <= r.thumb_force <= 1.1 and 0.8 <= r.finger_force <= 0.95
    # MoveMotors goals: fingers close at 60 rpm, then the thumb flexes at 60 rpm
    first, second = h.move_goals[0], h.move_goals[1]
    assert first.mode == "velocity" and dict(zip(first.motors, first.targets))["fingers"] == 60.0
    assert dict(zip(second.motors, second.targets)) == {"fingers": 0.0, "thumb_flexion": 60.0, "thumb_rotation": 0.0}
    phases = [f.feedback.phase for f in feedback]
    assert phases[0] == "close_fingers" and "close_thumb" in phases and phases[-1] == "done"
    assert max(f.feedback.finger_force for f in feedback) >= 0.8
    ros.advance(0.1)
    assert abs(velocity(h.joints, "thumb_flexion")) < 0.01 and abs(velocity(h.joints, "fingers")) < 0.01
    assert h.world.forces()["thumb"] == pytest.approx(1.0, abs=0.1)


def test_cancel_stops_the_motors(ros, hand):
    h = hand(stand_world())
    handle = send(ros, "/prisma/grasp", Grasp, Grasp.Goal(grasp="pinch", timeout=5.0))
    result = handle.get_result_async()
    ros.advance(0.3)
    assert velocity(h.joints, "fingers") > 6.0  # rad/s: closing at 60 rpm
    handle.cancel_goal_async()
    assert ros.spin_until(result, timeout_sec=1.0)
    assert result.result().status == GoalStatus.STATUS_CANCELED
    assert result.result().result.reason == "canceled"
    ros.advance(0.1)
    stopped_at = position(h.joints, "fingers")
    ros.advance(0.3)
    assert velocity(h.joints, "fingers") == pytest.approx(0.0, abs=1e-3)
    assert position(h.joints, "fingers") == pytest.approx(stopped_at, abs=1e-4)


@pytest.mark.parametrize("action, name, goal", [
    (Grasp, "/prisma/grasp", Grasp.Goal(grasp="pinch", speed_rpm=90.0)),
    (Grasp, "/prisma/grasp", Grasp.Goal(grasp="pinch", finger_force=5.0)),
    (Grasp, "/prisma/grasp", Grasp.Goal(grasp="hook")),
    (Manipulate, "/prisma/manipulate", Manipulate.Goal(motion="horizontal", speed_rpm=80.0)),
    (Manipulate, "/prisma/manipulate", Manipulate.Goal(motion="hold", k=0.5)),
    (MoveMotors, "/prisma/motors/move", MoveMotors.Goal(motors=["fingers"], mode="velocity", targets=[71.0])),
])
def test_goals_beyond_the_configured_limits_are_rejected(ros, hand, action, name, goal):
    hand(stand_world())
    handle = send(ros, name, action, goal)
    assert not handle.accepted


def test_stale_taxels_abort_with_sensor_stale_and_stop_the_motors(ros, hand):
    h = hand(pinched_world())
    handle = send(ros, "/prisma/manipulate", Manipulate,
                  Manipulate.Goal(motion="vertical", speed_rpm=10.0, timeout=10.0))
    result = handle.get_result_async()
    ros.advance(0.2)
    assert velocity(h.joints, "fingers") > 0.9  # rad/s: 10 rpm down phase
    h.sensors.age_ns = 150 * MS  # the hub now delivers samples 150 ms old
    old_from = ros.now_ns()
    assert ros.spin_until(result, timeout_sec=1.0)
    assert ros.now_ns() - old_from <= 20 * MS  # the first old sample (<= 10 ms) is caught at once
    assert result.result().status == GoalStatus.STATUS_ABORTED
    assert result.result().result.stop_reason == "sensor_stale" and not result.result().result.success
    ros.advance(0.1)
    assert velocity(h.joints, "fingers") == pytest.approx(0.0, abs=1e-3)
    assert velocity(h.joints, "thumb_flexion") == pytest.approx(0.0, abs=1e-3)


def test_silent_sensor_hub_aborts_with_sensor_stale(ros, hand):
    h = hand(pinched_world())
    handle = send(ros, "/prisma/manipulate", Manipulate, Manipulate.Goal(motion="horizontal", timeout=10.0))
    result = handle.get_result_async()
    ros.advance(0.05)
    h.sensors.silent = True
    silent_from = ros.now_ns()
    assert ros.spin_until(result, timeout_sec=1.0)
    assert result.result().result.stop_reason == "sensor_stale"
    assert 100 * MS < ros.now_ns() - silent_from <= 140 * MS  # 100 ms + one watchdog period
    ros.advance(0.1)
    assert velocity(h.joints, "thumb_rotation") == pytest.approx(0.0, abs=1e-3)


def test_horizontal_goal_reports_edge_lost_with_stop_time(ros, hand):
    h = hand(pinched_world())
    feedback = []
    handle = send(ros, "/prisma/manipulate", Manipulate, Manipulate.Goal(motion="horizontal", timeout=10.0),
                  feedback.append)
    result = handle.get_result_async()
    assert ros.spin_until(result, timeout_sec=5.0)
    r = result.result().result
    assert result.result().status == GoalStatus.STATUS_SUCCEEDED and r.stop_reason == "edge_lost"
    assert 0.1 < r.stop_time < 1.0
    assert {"rotate", "return"} <= {f.feedback.phase for f in feedback}
    assert all(f.feedback.threshold > 0 for f in feedback[1:])  # from the first sample on
    ros.advance(0.1)
    assert position(h.joints, "thumb_rotation") == pytest.approx(0.0, abs=0.03)


def test_contact_state_on_every_sample_when_idle_and_k_at_run_time(ros, hand):
    h = hand(pinched_world())
    seen = {f: ros.collect(ContactState, f"/prisma/{f}/contact") for f in FINGERS}
    before = h.sensors.published
    ros.advance(0.1)
    samples = h.sensors.published - before
    assert samples == 10
    assert all(len(seen[f]) == samples for f in FINGERS)
    thumb = seen["thumb"][-1]
    assert thumb.k == pytest.approx(0.8) and thumb.threshold == pytest.approx(0.8 * thumb.mean_voltage, rel=1e-5)
    assert thumb.feasible and list(thumb.lost_edges) == []
    assert not seen["ring"][-1].feasible  # untouched pad: below min_mean_voltage
    assert h.manipulation.set_parameters([Parameter("k", value=0.95)])[0].successful
    ros.advance(0.02)
    assert seen["thumb"][-1].k == pytest.approx(0.95)
    assert seen["thumb"][-1].threshold == pytest.approx(0.95 * seen["thumb"][-1].mean_voltage, rel=1e-5)
    bad = h.manipulation.set_parameters([Parameter("k", value=1.8)])[0]
    assert not bad.successful and "1.8" in bad.reason
    assert not h.manipulation.set_parameters([Parameter("max_force_n", value=9.0)])[0].successful


def test_motor_fault_aborts_move_and_grasp_naming_motor_and_bit(ros, hand):
    h = hand(stand_world())
    handle = send(ros, "/prisma/grasp", Grasp, Grasp.Goal(grasp="pinch", timeout=5.0))
    result = handle.get_result_async()
    ros.advance(0.2)
    h.motor.core.bus.inject_hardware_error("fingers", 5)
    assert ros.spin_until(result, timeout_sec=1.0)
    r = result.result().result
    assert result.result().status == GoalStatus.STATUS_ABORTED
    assert r.reason == "motor_fault"
    ros.advance(0.05)
    assert not h.motor.core.bus.read_state(ros.now_ns())["fingers"].torque_on
    diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
    ros.advance(1.0)
    status = {s.name: s for s in diagnostics[-1].status}
    assert "overload" in status["motor_driver: fingers"].message
    assert "bit 5 overload" in status["motor_driver: bus"].message


def test_joint_states_at_100_hz_in_si_units(ros, hand):
    h = hand(pinched_world())
    start = len(h.joints)
    ros.advance(0.1)
    assert len(h.joints) - start == 10
    msg = h.joints[-1]
    assert list(msg.name) == ["fingers", "thumb_flexion", "thumb_rotation"]
    assert msg.position[0] == pytest.approx(h.world.grasp_pose(1.0)["fingers"])
    assert ns_from_stamp(msg.header.stamp) == ros.now_ns()


def test_invalid_parameters_fail_at_start_naming_them(ros):
    ros.override(node="manipulation", k=2.0)
    with pytest.raises(ValueError, match=r"invalid parameter 'k' = 2.0"):
        ManipulationNode()
    ros.override(node="motor_driver", motor_ids=[1, 1, 3])
    with pytest.raises(ValueError, match=r"motor_ids \[1, 1, 3\] are not unique"):
        MotorDriverNode()


def test_sim_stack_tactile_driver_fed_by_motor_driver_through_hand_world(ros):
    """The ROS sim mode end to end: motor_driver (sim) -> /joint_states -> tactile_driver
    (contact_source hand_world) -> taxels -> manipulation -> MoveMotors -> motor_driver."""
    from prisma_tactile_driver.tactile_driver_node import TactileDriverNode

    pose = HandWorld().grasp_pose(1.0)
    ros.override(node="motor_driver", sim_initial_positions=[pose["fingers"], pose["thumb_flexion"], 0.0])
    ros.override(node="tactile_driver", backend="sim", contact_source="hand_world")
    MotorDriverNode()
    tactile = TactileDriverNode()
    ManipulationNode()
    contacts = ros.collect(ContactState, "/prisma/thumb/contact")
    joints = ros.collect(JointState, "/joint_states")
    ros.advance(0.6)  # the presenting hand lets go of the ball once the pinch holds it
    assert tactile._source.world.forces()["thumb"] == pytest.approx(1.0, abs=0.05)
    assert contacts[-1].feasible and contacts[-1].mean_voltage > 0.9
    goal_sent = ros.now_ns()
    handle = send(ros, "/prisma/manipulate", Manipulate, Manipulate.Goal(motion="horizontal", timeout=10.0))
    result = handle.get_result_async()
    assert ros.spin_until(result, timeout_sec=5.0)
    r = result.result().result
    assert r.success and r.stop_reason == "edge_lost"
    # the stop time is the first published ContactState with the right side lost
    lost_ns = next(ns_from_stamp(c.header.stamp) for c in contacts if "right" in list(c.lost_edges))
    assert (lost_ns - goal_sent) * 1e-9 == pytest.approx(r.stop_time, abs=0.011)
    ros.advance(0.2)
    rotation = float(joints[-1].position[2])
    assert rotation == pytest.approx(0.0, abs=0.03)  # back at the start angle
