"""The rclpy stand-in behaves as rclpy (Jazzy) documents, for every behaviour the nodes rely on."""
from __future__ import annotations

import array

import numpy as np
import pytest

import rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter

pytestmark = pytest.mark.skipif(
    not hasattr(rclpy.get_default_context(), "graph"), reason="tests of the stand-in itself; real rclpy in use")

from action_msgs.msg import GoalStatus  # noqa: E402
from builtin_interfaces.msg import Time as TimeMsg  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue  # noqa: E402
from geometry_msgs.msg import Pose, WrenchStamped  # noqa: E402
from prisma_msgs.action import Grasp, Manipulate, MoveMotors  # noqa: E402
from prisma_msgs.msg import ContactState, GloveFrame, TaxelArray  # noqa: E402
from rcl_interfaces.msg import (  # noqa: E402
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    ParameterValue,
    SetParametersResult,
)
from rclpy.action import ActionClient, ActionServer, CancelResponse, GoalResponse  # noqa: E402
from rclpy.exceptions import (  # noqa: E402
    InvalidNodeNameException,
    InvalidParameterTypeException,
    InvalidParameterValueException,
    InvalidTopicNameException,
    NotInitializedException,
    ParameterAlreadyDeclaredException,
    ParameterNotDeclaredException,
    ParameterUninitializedException,
)
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor  # noqa: E402
from rclpy.qos import (  # noqa: E402
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from rclpy.task import Future  # noqa: E402
from rclpy.time import Duration, Time  # noqa: E402
from sensor_msgs.msg import Image, JointState  # noqa: E402
from std_msgs.msg import Header, String  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402

from prisma_bringup.bag import BagWriter, read_bag  # noqa: E402
from prisma_bringup.typestore import get_typestore, registered_prisma_types  # noqa: E402

# ------------------------------------------------------------------------------------------------
# Parameters


def test_declaring_a_parameter_twice_raises_already_declared(ros):
    node = Node("n")
    node.declare_parameter("rate_hz", 100.0)
    with pytest.raises(ParameterAlreadyDeclaredException):
        node.declare_parameter("rate_hz", 50.0)
    assert node.get_parameter("rate_hz").value == 100.0


def test_undeclared_parameter_get_and_set_raise_not_declared(ros):
    node = Node("n")
    with pytest.raises(ParameterNotDeclaredException):
        node.get_parameter("missing")
    with pytest.raises(ParameterNotDeclaredException):
        node.set_parameters([Parameter("missing", value=1)])
    assert not node.has_parameter("missing")


def test_undeclared_parameters_allowed_give_not_set(ros):
    node = Node("n", allow_undeclared_parameters=True)
    assert node.get_parameter("free").type_ == Parameter.Type.NOT_SET
    node.set_parameters([Parameter("free", value="x")])
    assert node.get_parameter("free").value == "x"


def test_declare_returns_value_and_declare_parameters_prefixes_namespace(ros):
    node = Node("n")
    params = node.declare_parameters("pad", [("pitch_mm", 4.0), ("rows", 3), ("name", "thumb")])
    assert [p.name for p in params] == ["pad.pitch_mm", "pad.rows", "pad.name"]
    assert node.get_parameters(["pad.rows", "pad.name"])[0].value == 3
    assert node.get_parameter("pad.name").type_ == Parameter.Type.STRING
    assert set(node.get_parameters_by_prefix("pad")) == {"pitch_mm", "rows", "name"}


def test_on_set_callback_rejection_keeps_the_old_value(ros):
    node = Node("n")
    node.declare_parameter("gain", 1.0)
    seen = []

    def validate(params):
        seen.extend(p.name for p in params)
        ok = all(p.value > 0 for p in params if p.name == "gain")
        return SetParametersResult(successful=ok, reason="" if ok else "gain must be positive")

    node.add_on_set_parameters_callback(validate)
    (result,) = node.set_parameters([Parameter("gain", value=-2.0)])
    assert not result.successful and result.reason == "gain must be positive"
    assert node.get_parameter("gain").value == 1.0
    (result,) = node.set_parameters([Parameter("gain", value=3.0)])
    assert result.successful and node.get_parameter("gain").value == 3.0
    assert seen == ["gain", "gain"]


def test_on_set_callback_runs_on_declare_and_rejection_raises_invalid_value(ros):
    node = Node("n")
    node.add_on_set_parameters_callback(
        lambda params: SetParametersResult(successful=all(p.value != "bad" for p in params), reason="no"))
    node.declare_parameter("mode", "good")
    with pytest.raises(InvalidParameterValueException, match="bad"):
        node.declare_parameter("other", "bad")
    assert not node.has_parameter("other")


def test_set_with_wrong_type_is_rejected_and_keeps_value(ros):
    node = Node("n")
    node.declare_parameter("rate_hz", 100.0)
    (result,) = node.set_parameters([Parameter("rate_hz", value=50)])
    assert not result.successful and result.reason.startswith("Wrong parameter type")
    assert node.get_parameter("rate_hz").value == 100.0


def test_override_wins_over_default(ros):
    node = Node("n", parameter_overrides=[Parameter("rate_hz", value=25.0)])
    assert node.declare_parameter("rate_hz", 100.0).value == 25.0
    assert node.declare_parameter("port", "/dev/ttyACM0").value == "/dev/ttyACM0"
    ignored = node.declare_parameter("rate2", 1.0, ignore_override=True)
    assert ignored.value == 1.0


def test_ros_args_and_params_file_overrides(ros, tmp_path):
    params = tmp_path / "params.yaml"
    params.write_text("driver:\n  ros__parameters:\n    rate_hz: 40.0\n    fingers: [thumb, index]\n"
                      "other:\n  ros__parameters:\n    rate_hz: 1.0\n")
    rclpy.shutdown()
    rclpy.init(args=["prog", "--ros-args", "-p", "gain:=2.5", "--params-file", str(params)])
    node = Node("driver")
    assert node.declare_parameter("gain", 1.0).value == 2.5
    assert node.declare_parameter("rate_hz", 100.0).value == 40.0
    assert node.declare_parameter("fingers", ["thumb"]).value == ["thumb", "index"]
    assert rclpy.utilities.remove_ros_args(["prog", "--ros-args", "-p", "a:=1", "--", "x"]) == ["prog", "x"]


def test_fixture_override_and_cli_args(ros):
    ros.override(node="driver", rate_hz=10.0)
    ros.override(gain=3)
    node = Node("driver")
    assert node.declare_parameter("rate_hz", 100.0).value == 10.0
    assert node.declare_parameter("gain", 1).value == 3
    assert Node("other").declare_parameter("rate_hz", 100.0).value == 100.0
    assert Node("x", cli_args=["--ros-args", "-p", "k:=7"]).declare_parameter("k", 0).value == 7


def test_override_of_the_wrong_type_fails_naming_parameter_and_value(ros):
    node = Node("n", parameter_overrides=[Parameter("rate_hz", value=100)])
    with pytest.raises(InvalidParameterTypeException, match="rate_hz.*100.*DOUBLE"):
        node.declare_parameter("rate_hz", 100.0)


def test_statically_typed_declaration_and_empty_list_quirk(ros):
    node = Node("n")
    node.declare_parameter("names", Parameter.Type.STRING_ARRAY)
    with pytest.raises(ParameterUninitializedException):
        node.get_parameter("names")
    node.set_parameters([Parameter("names", value=["a"])])
    assert node.get_parameter("names").value == ["a"]
    # rclpy infers BYTE_ARRAY from an empty list default, so a string list is then the wrong type.
    node.declare_parameter("empty", [])
    assert node.get_parameter("empty").type_ == Parameter.Type.BYTE_ARRAY
    assert not node.set_parameters([Parameter("empty", value=["a"])])[0].successful


def test_descriptor_read_only_and_ranges(ros):
    node = Node("n")
    node.declare_parameter("fixed", 1, ParameterDescriptor(read_only=True))
    assert not node.set_parameters([Parameter("fixed", value=2)])[0].successful
    node.declare_parameter("k", 5, ParameterDescriptor(integer_range=[IntegerRange(from_value=0, to_value=10, step=1)]))
    assert not node.set_parameters([Parameter("k", value=11)])[0].successful
    assert node.set_parameters([Parameter("k", value=10)])[0].successful
    node.declare_parameter(
        "x", 0.5, ParameterDescriptor(floating_point_range=[FloatingPointRange(from_value=0.0, to_value=1.0)]))
    assert not node.set_parameters([Parameter("x", value=1.5)])[0].successful
    with pytest.raises(InvalidParameterValueException):
        node.declare_parameter(
            "y", 2.0, ParameterDescriptor(floating_point_range=[FloatingPointRange(from_value=0.0, to_value=1.0)]))


def test_use_sim_time_is_declared_false(ros):
    node = Node("n")
    assert node.get_parameter("use_sim_time").value is False
    node2 = Node("m", parameter_overrides=[Parameter("use_sim_time", value=True)])
    assert node2.get_parameter("use_sim_time").value is True
    assert node2.get_clock().ros_time_is_active


def test_parameter_type_inference_matches_rclpy():
    assert Parameter("a", value=True).type_ == Parameter.Type.BOOL
    assert Parameter("a", value=1).type_ == Parameter.Type.INTEGER
    assert Parameter("a", value=1.0).type_ == Parameter.Type.DOUBLE
    assert Parameter("a", value=[1.0, 2.0]).type_ == Parameter.Type.DOUBLE_ARRAY
    with pytest.raises(ValueError):
        Parameter("a", Parameter.Type.DOUBLE, 1)
    with pytest.raises(TypeError):
        Parameter("a", value=[1, "x"])


# ------------------------------------------------------------------------------------------------
# Context, names


def test_node_needs_init_and_init_twice_raises(ros):
    with pytest.raises(RuntimeError):
        rclpy.init()
    rclpy.shutdown()
    assert not rclpy.ok()
    with pytest.raises(NotInitializedException):
        Node("n")
    rclpy.init()
    assert rclpy.ok()


def test_topic_name_resolution(ros):
    node = Node("driver", namespace="prisma")
    assert node.get_namespace() == "/prisma" and node.get_fully_qualified_name() == "/prisma/driver"
    assert node.create_publisher(String, "~/state", 10).topic_name == "/prisma/driver/state"
    assert node.create_publisher(String, "taxels", 10).topic_name == "/prisma/taxels"
    assert node.create_publisher(String, "/abs", 10).topic_name == "/abs"
    root = Node("root")
    assert root.create_publisher(String, "~/x", 10).topic_name == "/root/x"
    assert root.create_publisher(String, "x", 10).topic_name == "/x"
    with pytest.raises(InvalidTopicNameException):
        root.create_publisher(String, "bad name", 10)
    with pytest.raises(InvalidNodeNameException):
        Node("bad-name")


# ------------------------------------------------------------------------------------------------
# Publish / subscribe


def test_publish_reaches_only_same_topic_and_type_after_spin(ros):
    pub_node = Node("talker")
    listener = Node("listener")
    got_a, got_b, got_other_type = [], [], []
    listener.create_subscription(String, "/a", got_a.append, 10)
    listener.create_subscription(String, "/b", got_b.append, 10)
    listener.create_subscription(Header, "/a", got_other_type.append, 10)
    publisher = pub_node.create_publisher(String, "/a", 10)
    message = String(data="hello")
    publisher.publish(message)
    assert got_a == []  # delivery happens when the subscriber's node is spun, as in rclpy
    message.data = "changed after publish"
    assert ros.process() == 1
    assert [m.data for m in got_a] == ["hello"] and got_b == [] and got_other_type == []
    assert publisher.get_subscription_count() == 1
    assert pub_node.count_subscribers("/a") == 2


def test_rclpy_spin_once_runs_one_callback_of_that_node(ros):
    node = rclpy.create_node("n")
    got = []
    node.create_subscription(String, "t", got.append, 10)
    pub = node.create_publisher(String, "t", 10)
    pub.publish(String(data="1"))
    pub.publish(String(data="2"))
    rclpy.spin_once(node, timeout_sec=0)
    assert [m.data for m in got] == ["1"]
    rclpy.spin_once(node, timeout_sec=0)
    assert [m.data for m in got] == ["1", "2"]


def test_qos_reliability_and_durability_matching(ros):
    node = Node("n")
    reliable, best_effort = [], []
    node.create_subscription(String, "/s", reliable.append, 10)
    node.create_subscription(String, "/s", best_effort.append, qos_profile_sensor_data)
    node.create_publisher(String, "/s", qos_profile_sensor_data).publish(String(data="sensor"))
    node.create_publisher(String, "/s", 10).publish(String(data="reliable"))
    ros.process()
    assert [m.data for m in reliable] == ["reliable"]  # a RELIABLE reader ignores a BEST_EFFORT writer
    assert [m.data for m in best_effort] == ["sensor", "reliable"]
    with pytest.raises(Exception):
        QoSProfile()


def test_keep_last_depth_drops_oldest_and_transient_local_replays(ros):
    node = Node("n")
    got = []
    node.create_subscription(String, "/q", got.append, 2)
    pub = node.create_publisher(String, "/q", 10)
    for i in range(5):
        pub.publish(String(data=str(i)))
    ros.process()
    assert [m.data for m in got] == ["3", "4"]
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                         reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
    node.create_publisher(String, "/latched", latched).publish(String(data="map"))
    late = []
    node.create_subscription(String, "/latched", late.append, latched)
    ros.process()
    assert [m.data for m in late] == ["map"]


def test_callback_exception_propagates_out_of_spin(ros):
    node = Node("n")

    def boom(msg):
        raise ValueError("callback failed")

    node.create_subscription(String, "/t", boom, 10)
    ros.publish("/t", String(data="x"))
    with pytest.raises(ValueError, match="callback failed"):
        ros.process()


def test_publishing_a_typestore_message_converts_it(ros):
    got = ros.collect(String, "/t")
    ros.publish("/t", get_typestore().types["std_msgs/msg/String"](data="from a bag"))
    ros.process()
    assert type(got[0]) is String and got[0].data == "from a bag"


# ------------------------------------------------------------------------------------------------
# Timers and time


def test_timers_fire_at_their_period_on_the_test_clock(ros):
    node = Node("n")
    stamps, slow = [], []
    start = ros.now_ns()
    node.create_timer(0.1, lambda: stamps.append(node.get_clock().now().nanoseconds))
    node.create_timer(0.25, lambda: slow.append(ros.now_ns()))
    ros.process()
    assert stamps == []  # no time passed
    ros.advance(1.0)
    assert [s - start for s in stamps] == [i * 100_000_000 for i in range(1, 11)]
    assert [s - start for s in slow] == [250_000_000, 500_000_000, 750_000_000, 1_000_000_000]
    assert ros.now_ns() - start == 1_000_000_000


def test_timer_cancel_reset_and_missed_periods(ros):
    node = Node("n")
    calls = []
    timer = node.create_timer(0.1, lambda: calls.append(ros.now_ns()))
    ros.clock.advance(0.55)  # nobody spun: like rcl, the missed periods collapse into one call
    ros.process()
    assert len(calls) == 1
    assert timer.time_until_next_call() == 50_000_000
    timer.cancel()
    ros.advance(1.0)
    assert len(calls) == 1 and timer.is_canceled()
    timer.reset()
    ros.advance(0.1)
    assert len(calls) == 2
    assert node.create_timer(0.1, lambda: None, autostart=False).is_canceled()


def test_spin_once_with_timeout_lets_time_pass_to_the_next_timer(ros):
    node = rclpy.create_node("n")
    calls = []
    node.create_timer(0.5, lambda: calls.append(1))
    start = ros.now_ns()
    rclpy.spin_once(node, timeout_sec=0.1)
    assert calls == [] and ros.now_ns() - start == 100_000_000
    rclpy.spin_once(node, timeout_sec=1.0)
    assert calls == [1] and ros.now_ns() - start == 500_000_000


def test_clock_now_to_msg_and_time_arithmetic(ros):
    node = Node("n")
    ros.clock.advance(1.25)
    now = node.get_clock().now()
    msg = now.to_msg()
    assert isinstance(msg, TimeMsg)
    assert msg.sec * 10**9 + msg.nanosec == now.nanoseconds == ros.now_ns()
    assert msg.nanosec == 250_000_000
    later = now + Duration(seconds=0.5)
    assert (later - now).nanoseconds == 500_000_000 and later > now
    assert Time.from_msg(msg).nanoseconds == now.nanoseconds


def test_logger_records(ros):
    node = Node("driver")
    node.get_logger().info("started")
    node.get_logger().warning("late frame")
    node.get_logger().error("link lost")
    node.get_logger().debug("not shown at INFO")
    for _ in range(3):
        node.get_logger().warn("once only", once=True)
    assert [(r.severity, r.message) for r in ros.logs(name="driver")] == [
        ("INFO", "started"), ("WARN", "late frame"), ("ERROR", "link lost"), ("WARN", "once only")]
    assert ros.logs("error", contains="link")[0].stamp_ns == ros.now_ns()


# ------------------------------------------------------------------------------------------------
# Services


def test_service_call_roundtrip(ros):
    server = Node("server")
    calls = []

    def handle(request, response):
        calls.append(request.data)
        response.success = request.data
        response.message = "enabled" if request.data else "disabled"
        return response

    server.create_service(SetBool, "~/enable", handle)
    server.create_service(Trigger, "/reset", lambda req, resp: Trigger.Response(success=True, message="done"))
    response = ros.call(SetBool, "/server/enable", SetBool.Request(data=True))
    assert response.success and response.message == "enabled" and calls == [True]
    assert ros.call(Trigger, "/reset", Trigger.Request()).message == "done"


def test_client_future_completes_only_when_spun_and_missing_service(ros):
    Node("server").create_service(Trigger, "/t", lambda req, resp: Trigger.Response(success=True))
    client_node = Node("client")
    client = client_node.create_client(Trigger, "/t")
    assert client.wait_for_service(timeout_sec=1.0)
    future = client.call_async(Trigger.Request())
    assert not future.done()
    ros.process()
    assert future.done() and future.result().success
    missing = client_node.create_client(Trigger, "/nobody")
    assert not missing.wait_for_service(timeout_sec=0.1) and not missing.service_is_ready()
    pending = missing.call_async(Trigger.Request())
    assert not ros.spin_until(pending, timeout_sec=0.5) and not pending.done()


# ------------------------------------------------------------------------------------------------
# Actions


class GraspServerNode(Node):
    """The project's pattern: an async execute callback completed from a sensor callback."""

    def __init__(self):
        super().__init__("grasp_server")
        self.accepted_goals = []
        self.server = ActionServer(self, Grasp, "/prisma/grasp", self.execute,
                                   goal_callback=self.on_goal, cancel_callback=self.on_cancel)
        self.create_subscription(JointState, "/joint_states", self.on_joints, 10)
        self.goal = None
        self.allow_cancel = True

    def on_goal(self, goal):
        return GoalResponse.ACCEPT if goal.grasp in ("power", "pinch") else GoalResponse.REJECT

    def on_cancel(self, goal_handle):
        return CancelResponse.ACCEPT if self.allow_cancel else CancelResponse.REJECT

    async def execute(self, goal_handle):
        self.goal = goal_handle
        self.accepted_goals.append(goal_handle.request.grasp)
        self.done = Future()
        return await self.done

    def on_joints(self, msg):
        if self.goal is None:
            return
        if self.goal.is_cancel_requested:
            self.goal.canceled()
            self.finish(Grasp.Result(success=False, reason="canceled"))
            return
        force = float(msg.position[0])
        self.goal.publish_feedback(Grasp.Feedback(phase="closing", finger_force=force))
        if force >= 2.0:
            self.goal.succeed()
            self.finish(Grasp.Result(success=True, reason="force reached", finger_force=force))

    def finish(self, result):
        self.goal = None
        self.done.set_result(result)


def _send(ros, client, goal, feedback=None):
    future = client.send_goal_async(goal, feedback_callback=feedback)
    assert ros.spin_until(future, timeout_sec=1.0)
    return future.result()


def test_action_accept_feedback_result(ros):
    server = GraspServerNode()
    client = ros.action_client(Grasp, "/prisma/grasp")
    assert client.wait_for_server()
    feedback = []
    handle = _send(ros, client, Grasp.Goal(grasp="power", finger_force=2.0), feedback.append)
    assert handle.accepted and server.accepted_goals == ["power"]
    result_future = handle.get_result_async()
    for position in (0.5, 1.5, 2.5):
        ros.publish("/joint_states", JointState(name=["fingers"], position=[position]))
        ros.process()
    assert result_future.done()
    result = result_future.result()
    assert result.status == GoalStatus.STATUS_SUCCEEDED == 4
    assert result.result.success and result.result.finger_force == pytest.approx(2.5)
    assert [f.feedback.finger_force for f in feedback] == [0.5, 1.5, 2.5]
    assert handle.status == GoalStatus.STATUS_SUCCEEDED


def test_action_reject(ros):
    server = GraspServerNode()
    client = ros.action_client(Grasp, "/prisma/grasp")
    handle = _send(ros, client, Grasp.Goal(grasp="unknown"))
    assert not handle.accepted and server.accepted_goals == []
    with pytest.raises(TypeError):
        handle.get_result_async()


def test_action_cancel_accepted_and_rejected(ros):
    server = GraspServerNode()
    client = ros.action_client(Grasp, "/prisma/grasp")
    handle = _send(ros, client, Grasp.Goal(grasp="pinch"))
    result_future = handle.get_result_async()
    server.allow_cancel = False
    cancel = handle.cancel_goal_async()
    ros.process()
    assert cancel.result().return_code == cancel.result().ERROR_REJECTED and not server.goal.is_cancel_requested
    server.allow_cancel = True
    cancel = handle.cancel_goal_async()
    ros.process()
    assert cancel.result().return_code == 0 and len(cancel.result().goals_canceling) == 1
    assert server.goal.is_cancel_requested and server.goal.is_active
    ros.publish("/joint_states", JointState(name=["fingers"], position=[0.1]))
    ros.process()
    assert result_future.result().status == GoalStatus.STATUS_CANCELED == 5
    assert result_future.result().result.reason == "canceled"
    again = handle.cancel_goal_async()
    ros.process()
    assert again.result().return_code == again.result().ERROR_GOAL_TERMINATED


def test_action_plain_execute_callback_abort_and_unset_state(ros):
    node = Node("motors")

    def execute(goal_handle):
        if goal_handle.request.timeout < 0:
            goal_handle.abort()
            return MoveMotors.Result(success=False, reason="bad timeout")
        if goal_handle.request.timeout == 0:
            return MoveMotors.Result(success=True)  # state never set: rclpy aborts
        goal_handle.succeed()
        return MoveMotors.Result(success=True, final_positions=[1.0, 2.0])

    ActionServer(node, MoveMotors, "/prisma/motors/move", execute)
    client = ActionClient(node, MoveMotors, "/prisma/motors/move")
    statuses = {}
    for timeout in (-1.0, 0.0, 1.0):
        handle = _send(ros, client, MoveMotors.Goal(motors=["fingers"], timeout=timeout))
        future = handle.get_result_async()
        ros.spin_until(future, timeout_sec=1.0)
        statuses[timeout] = future.result()
    assert statuses[-1.0].status == GoalStatus.STATUS_ABORTED == 6
    assert statuses[-1.0].result.reason == "bad timeout"
    assert statuses[0.0].status == GoalStatus.STATUS_ABORTED
    assert ros.logs("WARN", contains="assuming aborted")
    assert statuses[1.0].status == GoalStatus.STATUS_SUCCEEDED
    assert list(statuses[1.0].result.final_positions) == [1.0, 2.0]


def test_action_execute_exception_aborts_and_logs(ros):
    node = Node("m")

    def execute(goal_handle):
        raise RuntimeError("controller crashed")

    ActionServer(node, Manipulate, "/prisma/manipulate", execute)
    handle = _send(ros, ros.action_client(Manipulate, "/prisma/manipulate"), Manipulate.Goal(motion="slide"))
    future = handle.get_result_async()
    ros.process()
    assert future.result().status == GoalStatus.STATUS_ABORTED
    assert ros.logs("ERROR", contains="controller crashed")


def test_action_goal_waiting_on_test_time_and_invalid_transition(ros):
    from rclpy._rclpy_pybind11 import RCLError

    node = Node("m")
    errors = []

    async def execute(goal_handle):
        done = Future()
        timer = node.create_timer(0.3, lambda: (done.set_result(None), timer.cancel()))
        await done
        goal_handle.succeed()
        try:
            goal_handle.succeed()
        except RCLError as exc:
            errors.append(str(exc))
        return Grasp.Result(success=True)

    ActionServer(node, Grasp, "g", execute)
    handle = _send(ros, ros.action_client(Grasp, "/g"), Grasp.Goal())
    start = ros.now_ns()
    future = handle.get_result_async()
    assert ros.spin_until(future, timeout_sec=1.0)
    assert ros.now_ns() - start == 300_000_000
    assert future.result().status == GoalStatus.STATUS_SUCCEEDED and errors


def test_action_server_graph_query(ros):
    from rclpy.action import get_action_server_names_and_types_by_node

    GraspServerNode()
    assert get_action_server_names_and_types_by_node(ros.probe, "grasp_server", "/") == [
        ("/prisma/grasp", ["prisma_msgs/action/Grasp"])]


# ------------------------------------------------------------------------------------------------
# Executors


@pytest.mark.parametrize("executor_class", [SingleThreadedExecutor, MultiThreadedExecutor])
def test_executor_runs_only_its_nodes_and_spins_until_future(ros, executor_class):
    ros.executor.shutdown()  # drive the nodes by hand here
    ros.context.graph.node_created_hooks.clear()
    executor = executor_class()
    mine, other = Node("mine"), Node("other")
    executor.add_node(mine)
    got_mine, got_other = [], []
    mine.create_subscription(String, "/t", got_mine.append, 10)
    other.create_subscription(String, "/t", got_other.append, 10)
    mine.create_publisher(String, "/t", 10).publish(String(data="x"))
    executor.spin()
    assert len(got_mine) == 1 and got_other == []
    future = Future()
    mine.create_timer(0.2, lambda: future.done() or future.set_result("fired"))
    start = ros.now_ns()
    executor.spin_until_future_complete(future, timeout_sec=1.0)
    assert future.result() == "fired" and ros.now_ns() - start == 200_000_000


def test_async_subscription_callback_and_create_task(ros):
    node = Node("n")
    gate = Future()
    order = []

    async def on_msg(msg):
        order.append("start " + msg.data)
        value = await gate
        order.append(f"end {value}")

    node.create_subscription(String, "/t", on_msg, 10)
    ros.publish("/t", String(data="a"))
    ros.process()
    assert order == ["start a"]
    gate.set_result(7)
    ros.process()
    assert order == ["start a", "end 7"]
    task = ros.executor.create_task(lambda: 42)
    ros.process()
    assert task.result() == 42


# ------------------------------------------------------------------------------------------------
# Messages


def test_message_defaults_and_fixed_array_sizes():
    taxels = TaxelArray()
    assert taxels.finger == "" and taxels.header.frame_id == "" and taxels.header.stamp.sec == 0
    assert taxels.counts.dtype == np.uint16 and taxels.counts.shape == (9,) and not taxels.counts.any()
    assert taxels.voltages.dtype == np.float32 and taxels.voltages.shape == (9,)
    contact = ContactState()
    assert contact.safe == [False] * 9 and contact.lost_edges == [] and contact.feasible is False
    assert GloveFrame().raw == array.array("H") and Pose().orientation.w == 0.0
    assert JointState().position == array.array("d")
    partial = TaxelArray(finger="thumb", counts=list(range(9)))
    assert partial.counts.tolist() == list(range(9)) and partial.voltages.shape == (9,)


def test_message_field_checks_match_rclpy():
    with pytest.raises(AssertionError, match="Invalid arguments passed to constructor: bogus"):
        TaxelArray(bogus=1)
    with pytest.raises(TypeError):
        String("positional")
    msg = WrenchStamped()
    with pytest.raises(AssertionError):
        msg.wrench.force.x = 1  # float fields take float only
    with pytest.raises(AssertionError):
        msg.wrench.force.x = np.float32(1.0)
    with pytest.raises(AssertionError):
        TaxelArray(counts=[1, 2, 3])  # fixed size 9
    with pytest.raises(AssertionError):
        Image(height=-1)
    with pytest.raises(AttributeError):
        msg.not_a_field = 1
    status = DiagnosticStatus(level=DiagnosticStatus.ERROR, name="hub")
    assert status.level == DiagnosticStatus.ERROR == b"\x02"
    with pytest.raises(AssertionError):
        DiagnosticStatus(level=2)


def test_numeric_sequence_setter_takes_array_array_or_a_list_and_rejects_numpy_like_rclpy():
    msg = JointState()
    with pytest.raises(AssertionError, match="The 'position' field must be a set or sequence"):
        msg.position = np.array([1.0, 2.0])  # an ndarray is no collections.abc.Sequence
    with pytest.raises(AssertionError, match="'position' array.array\\(\\) must have the type code of 'd'"):
        msg.position = array.array("f", [1.0])
    with pytest.raises(AssertionError, match="each value of type 'float'"):
        msg.position = [1.0, 2]  # an int in a float64[]
    with pytest.raises(AssertionError, match="each value of type 'float'"):
        msg.position = [np.float32(1.0)]
    with pytest.raises(AssertionError):
        msg.position = "1.0"
    values = array.array("d", [0.5, 1.5])
    msg.position = values
    assert msg.position is values  # stored as given, like rclpy
    msg.velocity = [0.25, -0.5]
    msg.effort = (1.0,)
    assert msg.velocity == array.array("d", [0.25, -0.5]) and msg.effort == array.array("d", [1.0])
    # What nodes do with a received sequence works on array.array.
    assert list(msg.position) == [0.5, 1.5] and len(msg.position) == 2 and msg.position[-1] == 1.5
    assert np.asarray(msg.position).dtype == np.float64 and np.asarray(msg.velocity).tolist() == [0.25, -0.5]
    frame = GloveFrame()
    with pytest.raises(AssertionError, match="'raw' field must be a set or sequence"):
        frame.raw = np.arange(4, dtype=np.uint16)
    with pytest.raises(AssertionError, match=r"each unsigned integer in \[0, 65535\]"):
        frame.raw = [1, 70000]
    frame.raw = array.array("H", [1, 2, 3])
    frame.pressure = [0.5]
    assert frame.pressure.typecode == "f" and frame.pressure[0] == 0.5


def test_constructor_wraps_numeric_sequences_in_array_array_like_rclpy():
    # rclpy's __init__ runs array.array(typecode, value) before the setter, so ndarrays pass there.
    msg = JointState(position=np.array([1.0, 2.0]), velocity=[1, 2], effort=array.array("d", [3.0]))
    assert msg.position == array.array("d", [1.0, 2.0]) and msg.velocity == array.array("d", [1.0, 2.0])
    assert msg.effort == array.array("d", [3.0])
    with pytest.raises(TypeError):
        GloveFrame(raw=np.array([1.5, 2.5]))  # float elements for a uint16[]
    with pytest.raises(OverflowError):
        GloveFrame(raw=[70000])


def test_bounded_numeric_sequence_checks_its_bound():
    from rosidl_runtime_py.utilities import get_message

    SolidPrimitive = get_message("shape_msgs/msg/SolidPrimitive")  # float64[<=3] dimensions
    shape = SolidPrimitive(dimensions=[0.1, 0.2, 0.3])
    assert shape.dimensions == array.array("d", [0.1, 0.2, 0.3])
    with pytest.raises(AssertionError, match="with length <= 3"):
        shape.dimensions = [0.1, 0.2, 0.3, 0.4]
    with pytest.raises(AssertionError, match="must have a size <= 3"):
        shape.dimensions = array.array("d", [0.1, 0.2, 0.3, 0.4])
    with pytest.raises(AssertionError, match="'dimensions' field must be a set or sequence with length <= 3"):
        shape.dimensions = np.array([0.1])
    with pytest.raises(AssertionError):
        SolidPrimitive(dimensions=np.zeros(4))
    shape.dimensions = array.array("d", [0.5])
    assert list(shape.dimensions) == [0.5]


def test_fixed_numeric_arrays_are_numpy_and_take_an_ndarray_of_their_dtype():
    taxels = TaxelArray(voltages=np.linspace(0.0, 3.3, 9))  # the constructor converts to float32
    assert taxels.voltages.dtype == np.float32
    exact = np.full(9, 1.5, dtype=np.float32)
    taxels.voltages = exact
    assert taxels.voltages is exact
    with pytest.raises(AssertionError, match="'voltages' numpy.ndarray\\(\\) must have the dtype of 'numpy.float32'"):
        taxels.voltages = np.ones(9)
    with pytest.raises(AssertionError, match="must have a size of 9"):
        taxels.voltages = np.ones(8, dtype=np.float32)
    taxels.voltages = [0.5] * 9
    assert isinstance(taxels.voltages, np.ndarray) and taxels.voltages.dtype == np.float32
    with pytest.raises(AssertionError, match="with length 9 and each value of type 'float'"):
        taxels.voltages = [1] * 9
    taxels.counts = np.arange(9, dtype=np.uint16)
    with pytest.raises(AssertionError, match="dtype of 'numpy.uint16'"):
        taxels.counts = np.arange(9)


def test_bool_and_string_arrays_are_lists_and_reject_numpy():
    with pytest.raises(AssertionError, match="The 'safe' field must be a set or sequence with length 9"):
        ContactState(safe=np.ones(9, dtype=bool))  # bool is not an array.array type: no wrapping
    contact = ContactState(safe=[True] * 9, lost_edges=("left",))
    with pytest.raises(AssertionError, match="each value of type 'bool'"):
        contact.safe = [np.bool_(True)] * 9
    with pytest.raises(AssertionError, match="with length 9"):
        contact.safe = [True] * 8
    contact.lost_edges = ["top", "left"]
    with pytest.raises(AssertionError, match="'lost_edges' field must be a set or sequence"):
        contact.lost_edges = np.array(["top"])
    with pytest.raises(AssertionError, match="each value of type 'str'"):
        contact.lost_edges = ["top", 1]
    with pytest.raises(AssertionError):
        contact.lost_edges = (edge for edge in ["top"])  # a generator is no sequence
    with pytest.raises(AssertionError):
        contact.lost_edges = "top"


def test_a_received_message_holds_rclpy_containers(ros):
    got = ros.collect(ContactState, "/c")
    joints = ros.collect(JointState, "/j")
    sent = ContactState(safe=(True,) * 9, voltages=[0.5] * 9, lost_edges=("left",))
    ros.publish("/c", sent)
    ros.publish("/j", JointState(name=["a"], position=[0.5]))
    ros.process()
    (contact,), (joint,) = got, joints
    assert contact == sent and contact is not sent
    assert contact.safe == [True] * 9 and contact.lost_edges == ["left"]  # tuples arrive as lists
    assert contact.voltages.dtype == np.float32 and isinstance(joint.position, array.array)
    assert joint.position.typecode == "d" and list(joint.position) == [0.5]


def test_message_equality_by_fields_and_copy():
    import copy

    a = TaxelArray(finger="index", counts=list(range(9)))
    b = TaxelArray(finger="index", counts=list(range(9)))
    assert a == b and copy.deepcopy(a) == a
    b.counts[0] = 5
    assert a != b


def test_stand_in_messages_serialise_with_the_shared_typestore():
    store = get_typestore()
    messages = [
        TaxelArray(header=Header(stamp=TimeMsg(sec=3, nanosec=4), frame_id="index_pad"), finger="index",
                   counts=np.arange(9, dtype=np.uint16), voltages=np.linspace(0, 3.3, 9).astype(np.float32)),
        ContactState(finger="thumb", safe=[True] * 9, lost_edges=["left"], feasible=True, k=1.5),
        DiagnosticArray(status=[DiagnosticStatus(level=DiagnosticStatus.WARN, name="hub",
                                                 values=[KeyValue(key="crc", value="3")])]),
        JointState(name=["fingers"], position=[0.5], velocity=[0.0], effort=[]),
        GloveFrame(rows=1, cols=2, raw=array.array("H", [1, 1023]), pressure=[0.5, 0.25]),
        ParameterValue(type=4, byte_array_value=[b"\x01", b"\xff"], bool_array_value=[True, False],
                       integer_array_value=[1, -2], double_array_value=array.array("d", [0.5]),
                       string_array_value=["a"]),
        Grasp.Goal(grasp="power", finger_force=2.0), MoveMotors.Result(final_positions=[1.0]),
        Grasp.Impl.FeedbackMessage(feedback=Grasp.Feedback(phase="closing")),
    ]
    for msg in messages:
        raw = store.serialize_cdr(msg, msg.__msgtype__)
        back = store.deserialize_cdr(raw, msg.__msgtype__)
        assert msg == back, msg.__msgtype__
    # Every prisma_msgs type has a stand-in class that serialises at its defaults.
    from rosidl_runtime_py.utilities import get_message

    for typename in registered_prisma_types():
        if "_SendGoal_" in typename or "_GetResult_" in typename:
            continue
        msg = get_message(typename)()
        assert store.deserialize_cdr(store.serialize_cdr(msg, typename), typename) == msg


def test_message_from_a_topic_goes_into_a_bag(ros, tmp_path):
    got = ros.collect(TaxelArray, "/prisma/index/taxels")
    ros.publish("/prisma/index/taxels", TaxelArray(
        header=Header(stamp=TimeMsg(sec=10, nanosec=5)), finger="index", counts=np.full(9, 7, dtype=np.uint16)))
    ros.process()
    with BagWriter(tmp_path / "bag") as writer:
        writer.write("/prisma/index/taxels", got[0])
    (record,) = list(read_bag(tmp_path / "bag"))
    assert record.message == got[0] and record.timestamp_ns == 10 * 10**9 + 5


def test_interface_lookup_and_constants():
    from rosidl_runtime_py.utilities import get_action, get_message, get_service

    assert get_message("prisma_msgs/msg/TaxelArray") is TaxelArray
    assert get_message("std_msgs/String") is String
    assert get_message("prisma_msgs/action/Grasp_Goal") is Grasp.Goal
    assert get_action("prisma_msgs/action/Grasp") is Grasp
    assert get_service("std_srvs/srv/Trigger") is Trigger
    assert (GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_CANCELED, GoalStatus.STATUS_ABORTED) == (4, 5, 6)
    assert set(Grasp.Goal.get_fields_and_field_types()) == {"grasp", "finger_force", "thumb_force", "speed_rpm", "timeout"}
    assert Grasp.Impl.SendGoalService.Request().goal == Grasp.Goal()
    with pytest.raises(AttributeError):
        get_message("std_msgs/msg/NoSuchMessage")
