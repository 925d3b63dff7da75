"""tendon_stretch on real rclpy over DDS: one full joint state per display tick, not per motor sample,
carrying the newest joint_states message's stamp and the stretch of the newest wrench; and the
DisplayGate that takes the inputs once per tick."""
from __future__ import annotations

import time
from pathlib import Path

import pytest

from prisma_testing.repo_paths import CONFIG
from prisma_testing.ros_harness import require_ros

require_ros()

import xacro  # noqa: E402
from builtin_interfaces.msg import Time  # noqa: E402
from geometry_msgs.msg import Vector3, Wrench, WrenchStamped  # noqa: E402
from prisma_msgs.msg import HandWrench  # noqa: E402
from prisma_visualization.display_gate import DisplayGate  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Header, String  # noqa: E402

from prisma_common.hand import MOTOR_NAMES  # noqa: E402
from prisma_common.messages import ns_from_stamp  # noqa: E402

PARAMS = CONFIG / "tendon_stretch.yaml"
URDF_XACRO = Path(__file__).resolve().parents[2] / "prisma_description" / "urdf" / "prisma_hand.urdf.xacro"
MOTORS = {"fingers": 4.0, "thumb_flexion": 3.0, "thumb_rotation": 0.5}
INDEX_MCP_PER_MOTOR_RAD = 0.0604  # dimensions.xacro finger_flexion_ratios
STRETCH_1N_RAD = 1.0 / 0.08 / 8.0  # 1 N / 0.08 N/mm / 8 mm per rad (test_tendon_stretch.py)


@pytest.fixture
def node_cls():
    from prisma_visualization.tendon_stretch_node import TendonStretchNode
    return TendonStretchNode


def stamp(ns: int) -> Time:
    return Time(sec=ns // 10**9, nanosec=ns % 10**9)


def joint_state(ns: int) -> JointState:
    return JointState(header=Header(stamp=stamp(ns)), name=list(MOTOR_NAMES),
                      position=[MOTORS[m] for m in MOTOR_NAMES])


def index_wrench(ns: int, fz: float) -> HandWrench:
    pad = WrenchStamped(header=Header(stamp=stamp(ns), frame_id="prisma_index_pad"),
                        wrench=Wrench(force=Vector3(z=fz), torque=Vector3()))
    return HandWrench(header=Header(stamp=stamp(ns)), fingers=["index"], wrenches=[pad])


def test_the_gate_lets_each_of_its_entities_run_once_per_open():
    gate, joints, wrench = DisplayGate(), object(), object()
    assert gate.can_execute(joints) and gate.beginning_execution(joints)
    gate.ending_execution(joints)
    assert not gate.can_execute(joints) and not gate.beginning_execution(joints)  # shut until the tick
    assert gate.can_execute(wrench)  # each entity has its own turn
    gate.open()
    assert gate.can_execute(joints) and gate.beginning_execution(joints)


def test_one_joint_state_per_display_tick_from_the_newest_inputs(ros, node_cls):
    node = ros.node(node_cls, params_files=[PARAMS], params={"publish_period": 0.1})
    description = ros.probe.create_publisher(String, "/robot_description",
                                             QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    description.publish(String(data=xacro.process_file(str(URDF_XACRO)).toxml()))
    assert ros.spin_until(lambda: node.stretch is not None, 10.0)
    model = ros.collect(JointState, "/prisma/model_joint_states")
    # motor samples and wrenches at 100 Hz for 2 s, each from a thread of its own (stamped when sent;
    # the wrench's pads by hand: the thread stamps the HandWrench's header only)
    with ros.publishing(HandWrench, "/prisma/hand/wrench", lambda _: index_wrench(time.time_ns(), 1.0), 100.0,
                        wait_for_subscribers=1), \
            ros.publishing(JointState, "/joint_states", lambda _: joint_state(0), 100.0,
                           wait_for_subscribers=1) as sent:
        ros.spin_for(2.0)
    ros.spin_for(0.3)
    assert len(sent) > 150
    assert 15 <= len(model) <= 23  # 10 Hz for 2 s, however many samples came
    stamps = [ns_from_stamp(m.header.stamp) for m in model]
    assert set(stamps) <= set(sent) and stamps == sorted(set(stamps))  # the samples' own stamps, each once
    drawn = dict(zip(model[-1].name, model[-1].position))
    assert {m: drawn[m] for m in MOTOR_NAMES} == MOTORS  # the motors as given
    # the index drawn at its motor less the 1 N stretch
    assert drawn["index_mcp"] == pytest.approx(INDEX_MCP_PER_MOTOR_RAD * (MOTORS["fingers"] - STRETCH_1N_RAD),
                                               abs=1e-3)
    # five samples between two ticks: the one drawn is the newest, the four before are never taken
    count, burst = len(model), [ros.now_ns() + i * 10_000_000 for i in range(5)]
    for ns in burst:
        ros.publish("/joint_states", joint_state(ns))
    assert ros.spin_until(lambda: len(model) > count, 1.0)
    ros.spin_for(0.25)
    assert [ns_from_stamp(m.header.stamp) for m in model[count:]] == [burst[-1]]


def test_a_period_of_zero_is_refused_with_its_name(ros, node_cls):
    from prisma_common.parameters import ParameterError
    with pytest.raises(ParameterError, match="invalid parameter 'publish_period' = 0.0: must be > 0.0"):
        ros.node(node_cls, params_files=[PARAMS], params={"publish_period": 0.0})
