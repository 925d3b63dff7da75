"""A fifth goal kind is its module and one registration line (issue 42): a test-only kind, ThumbTurn
(the thumb's rotation motor to an angle), defined below as a kind module would be and added with one
line (`KINDS`), runs through everything that serves goals, none of which names it: the manipulation
core (admission, one goal at a time with the other kinds, its controller stepped per scan), the
off-robot closed loop (the sim motor driver turns the thumb), the sim recorder (its action's topics
and messages in the bag, by its converters) and the manipulation node (its action server, its
request and result converters, its log and /diagnostics settings).

Also: the core's actions are told apart in one place (ActionHandlers.carry_out), not by an isinstance
chain in each of their users.
"""
from __future__ import annotations

import ast
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from prisma_hand_sim.hand_world import HandWorld
from prisma_manipulation.closed_loop import ClosedLoop
from prisma_manipulation.controllers import (
    JOINT_LIMIT,
    REACHED,
    ControlInput,
    ControlOutput,
    Controller,
    JointSample,
    MotorCommand,
)
from prisma_manipulation.goal_kind import (
    Built,
    Feedback,
    Finished,
    GoalContext,
    GoalKind,
    Streams,
    Types,
    finite,
)
from prisma_manipulation.goal_kinds import GOAL_KINDS, kind_named
from prisma_manipulation.manipulation_core import ActionHandlers, GraspRequest, ManipulationCore, SendMove
from prisma_manipulation.node_config import ManipulationConfig
from prisma_testing.repo_paths import ROOT

# ---- the kind's module (what thumb_turn_goal.py would hold) ----------------------------------------
TOLERANCE_RAD = 0.03  # a 20 rpm thumb moves 0.021 rad per 10 ms scan: it stops within one scan


@dataclass(frozen=True)
class ThumbTurnRequest:
    angle_rad: float  # thumb_rotation motor target
    speed_rpm: float = 20.0


@dataclass(frozen=True)
class ThumbTurnStatus:
    angle_rad: float  # where the thumb's rotation stands (NaN: not known yet)
    thumb_force: float  # N, the thumb pad's latest estimate
    reached: bool = False


class ThumbTurnController(Controller):
    """Turns thumb_rotation toward its target at a constant speed, done within TOLERANCE_RAD."""

    kind = "thumb_turn"
    fingers = ("thumb",)

    def __init__(self, limits: Any, angle_rad: float, speed_rpm: float) -> None:
        super().__init__(limits, timeout_s=5.0)
        self.angle_rad, self.speed_rpm = angle_rad, speed_rpm
        self.position = math.nan

    def _on_start(self, joints: JointSample) -> ControlOutput:
        return self._drive(joints)

    def _on_step(self, inp: ControlInput) -> ControlOutput:
        if self._moving_into_limit(inp.joints) is not None:
            return self._finish(inp.stamp_ns, JOINT_LIMIT, success=False)
        return self._drive(inp.joints)

    def _drive(self, joints: JointSample) -> ControlOutput:
        self.position = joints.positions["thumb_rotation"]
        error = self.angle_rad - self.position
        if abs(error) <= TOLERANCE_RAD:
            return self._finish(joints.stamp_ns, REACHED, success=True)
        return self._set(joints.stamp_ns, "turning", MotorCommand.of(thumb_rotation=math.copysign(self.speed_rpm,
                                                                                                   error)))


class ThumbTurnGoal(GoalKind[ThumbTurnRequest]):
    name, label = "thumb_turn", "ThumbTurn"
    # a test kind has no .action file of its own: it borrows MoveMotors' messages (the goal's
    # thumb_rotation target is the angle; the result's reason its end), served on its own name
    action, action_type = "prisma/test_thumb_turn", "prisma_msgs/action/MoveMotors"
    request_type = ThumbTurnRequest

    def resolve(self, req: ThumbTurnRequest, ctx: GoalContext) -> tuple[ThumbTurnRequest | None, str | None]:
        limit = ctx.limits.motors["thumb_rotation"]
        if not finite(req.angle_rad) or not limit.min_position_rad <= req.angle_rad <= limit.max_position_rad:
            return None, f"angle {req.angle_rad} rad outside thumb_rotation's range"
        if not finite(req.speed_rpm) or not 0 < req.speed_rpm <= ctx.config.max_speed_rpm:
            return None, f"speed_rpm {req.speed_rpm} must be in (0, {ctx.config.max_speed_rpm}]"
        return req, None

    def streams(self, req: ThumbTurnRequest, ctx: GoalContext) -> Streams:
        return Streams(("thumb",), ("thumb",))

    def build(self, req: ThumbTurnRequest, ctx: GoalContext) -> Built:
        return Built(ThumbTurnController(ctx.limits, req.angle_rad, req.speed_rpm))

    def status(self, controller: Controller, ctx: GoalContext) -> ThumbTurnStatus:
        assert isinstance(controller, ThumbTurnController)
        return ThumbTurnStatus(controller.position, ctx.forces.get("thumb", 0.0), controller.reason == REACHED)

    def idle_status(self, ctx: GoalContext) -> ThumbTurnStatus:
        angle = ctx.joints.positions.get("thumb_rotation", math.nan) if ctx.joints is not None else math.nan
        return ThumbTurnStatus(angle, ctx.forces.get("thumb", 0.0))

    def request_from_msg(self, msg: Any) -> ThumbTurnRequest:
        """The goal's target for thumb_rotation (NaN without one: refused invalid)."""
        targets = dict(zip(msg.motors, msg.targets))
        return ThumbTurnRequest(float(targets.get("thumb_rotation", math.nan)))

    def request_to_msg(self, types: Types, req: ThumbTurnRequest) -> Any:
        return types("prisma_msgs/action/MoveMotors_Goal")(
            motors=["thumb_rotation"], mode="position", targets=np.array([req.angle_rad]),
            position_limits=np.array([], dtype=np.float64), timeout=0.0,
            stamp=types("builtin_interfaces/msg/Time")(sec=0, nanosec=0), controller="")

    def feedback_to_msg(self, types: Types, fb: Feedback) -> Any:
        s: ThumbTurnStatus = fb.status
        return types("prisma_msgs/action/MoveMotors_Feedback")(
            positions=np.array([s.angle_rad]), velocities=np.array([], dtype=np.float64),
            currents=np.array([], dtype=np.float64))

    def result_to_msg(self, types: Types, done: Finished) -> Any:
        s: ThumbTurnStatus = done.status
        reason = f"{done.reason}: {done.detail}" if done.detail else done.reason
        return types("prisma_msgs/action/MoveMotors_Result")(success=bool(done.success),
                                                             final_positions=np.array([s.angle_rad]), reason=reason)


THUMB_TURN_GOAL = ThumbTurnGoal()

# ---- the registration: the one line a fifth kind adds ---------------------------------------------------
KINDS = GOAL_KINDS + (THUMB_TURN_GOAL,)

# ---- it runs through everything that serves goals ------------------------------------------------------
MS = 1_000_000
RAD_PER_S_AT_20_RPM = 20.0 * 2 * math.pi / 60


def _feed(core: ManipulationCore, t_ms: int, thumb_rotation: float = 0.0) -> list:
    t = t_ms * MS
    joints = {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": thumb_rotation}
    out = core.on_joints(JointSample(t, joints), t)
    out += core.on_taxels("thumb", t, np.full(9, 1.0, dtype=np.float32), t)[1]
    return out + core.on_wrench("thumb", t, 0.2, t)


def test_the_core_serves_the_fifth_kind_beside_the_others():
    core = ManipulationCore(ManipulationConfig(), KINDS)
    _feed(core, 0)
    assert str(core.accept(ThumbTurnRequest(4.0), True, 0)) == "invalid: angle 4.0 rad outside thumb_rotation's range"
    assert str(core.accept(ThumbTurnRequest(0.5, 90.0), True, 0)) == "invalid: speed_rpm 90.0 must be in (0, 70.0]"
    assert core.accept(ThumbTurnRequest(0.5), True, 0) is None
    # one goal at a time, across kinds
    assert str(core.accept(GraspRequest("pinch"), True, 0)) == "busy: a thumb_turn goal was accepted and is starting"
    started = core.start(ThumbTurnRequest(0.5), 0)
    assert started[0] == SendMove({"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 20.0}, 0.3, 0)
    assert started[1] == Feedback("thumb_turn", "turning", ThumbTurnStatus(0.0, 0.2))
    # the thumb comes within the tolerance: the motors stop, the goal ends reached
    ended = _feed(core, 10, thumb_rotation=0.49)
    assert [type(a).__name__ for a in ended] == ["StopMotors", "Feedback", "Finished"]
    assert ended[-1] == Finished("thumb_turn", True, REACHED, 0.01, ThumbTurnStatus(0.49, 0.2, True))
    # and it ends as its kind says, for any server of it
    assert THUMB_TURN_GOAL.outcome(ended[-1]) == "succeeded"
    assert kind_named("test_thumb_turn", KINDS) is kind_named("thumb_turn", KINDS) is THUMB_TURN_GOAL


def test_the_closed_loop_turns_the_thumb_for_the_fifth_kind():
    loop = ClosedLoop(HandWorld(obj="none"), kinds=KINDS)
    trace = loop.run(ThumbTurnRequest(0.8), 3.0, settle_s=0.2)
    done = loop.finished
    assert done is not None and (done.kind, done.success, done.reason) == ("thumb_turn", True, REACHED)
    # 0.8 rad at 20 rpm (2.09 rad/s) takes 0.38 s; the sim motor's velocity lags by its 10 ms time constant
    assert done.stop_time_s == pytest.approx(0.8 / RAD_PER_S_AT_20_RPM, abs=0.03)
    assert done.status.angle_rad == pytest.approx(0.8, abs=TOLERANCE_RAD)
    # stopped there: the thumb coasts less than a scan's travel after the stop
    assert trace.position("thumb_rotation")[-1] == pytest.approx(0.8, abs=0.05)
    assert trace.position("fingers")[-1] == 0.0 and trace.position("thumb_flexion")[-1] == 0.0


def test_the_closed_loop_ends_the_fifth_kind_at_a_joint_limit():
    world = HandWorld(obj="none")
    world.set_positions({"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 2.9})
    loop = ClosedLoop(world, kinds=KINDS)
    loop.run(ThumbTurnRequest(3.0), 2.0)  # the target lies within the limit margin (0.02 rad) of the 3 rad end
    done = loop.finished
    assert done is not None and (done.success, done.reason) == (False, JOINT_LIMIT)
    assert 2.95 <= done.status.angle_rad <= 3.0


BUNDLE = ROOT / "config" / "models" / "cnn2"


@pytest.mark.skipif(not (BUNDLE / "model.pt").exists(), reason=f"force-estimator bundle {BUNDLE} not built yet")
def test_the_sim_recorder_writes_the_fifth_kind_s_action(tmp_path):
    from prisma_common.bag import BagWriter, bag_topics
    from prisma_force_estimator.inference import ForceEstimator
    from prisma_manipulation.scenarios import Scenario
    from prisma_sim.hand_session import HandRecorder, goal_result

    loop = ClosedLoop(HandWorld(obj="none"), ForceEstimator.from_bundle(BUNDLE), kinds=KINDS)
    scenario = Scenario("thumb_turn", loop, ThumbTurnRequest(-0.6), 3.0, 0.1)
    with BagWriter(tmp_path / "bag") as writer:
        recorder = HandRecorder(scenario, writer, "test_thumb_turn")
        scenario.run()
        recording = recorder.finish()
    [goal] = [g for g in recording.goals if g.action == "test_thumb_turn"]
    assert goal.status == 4 and goal.feedback >= 10  # SUCCEEDED, a feedback per scan while it turned
    assert recording.counts["/prisma/test_thumb_turn/_action/feedback"] == goal.feedback
    assert recording.counts["/prisma/test_thumb_turn/_action/status"] == 2  # executing, succeeded
    # the result as the node would return it: the kind's result message's fields, and only those
    result = goal_result(loop.finished, KINDS)
    assert list(result) == ["success", "final_positions", "reason"]
    assert (result["success"], result["reason"]) == (True, REACHED)
    assert result["final_positions"] == [pytest.approx(-0.6, abs=TOLERANCE_RAD)]
    assert bag_topics(tmp_path / "bag")["/prisma/test_thumb_turn/_action/feedback"] == \
        "prisma_msgs/action/MoveMotors_FeedbackMessage"


def test_the_node_serves_the_fifth_kind(ros):
    """The node's action server for it and its converters: a goal sent before any stream flows is
    refused not_ready, with the kind's idle status in its result (the angle not known yet), and
    /diagnostics names its kind; a goal without a thumb_rotation target is refused invalid."""
    import os

    from prisma_msgs.action import MoveMotors
    from rclpy.action import ActionClient

    from prisma_manipulation.manipulation_node import ManipulationNode
    from prisma_testing.repo_paths import CONFIG

    namespace = f"/fifth{os.getpid()}"
    node = ros.node(ManipulationNode, params_files=[CONFIG / "manipulation.yaml"], namespace=namespace, kinds=KINDS)
    client = ActionClient(ros.probe, MoveMotors, f"{namespace}/prisma/test_thumb_turn")
    assert ros.spin_until(client.server_is_ready, 10.0)
    result = ros.result(ros.send_goal(client, MoveMotors.Goal(motors=["thumb_rotation"], targets=[0.5])),
                        timeout_sec=10.0)
    assert result.status == 6 and not result.result.success  # ABORTED
    assert result.result.reason.startswith("not_ready: MoveMotors action server")  # no motor driver here
    assert len(result.result.final_positions) == 1 and math.isnan(result.result.final_positions[0])
    last = node.goal_ends.last
    assert (last.kind, last.end, last.reason) == ("thumb_turn", "refused", result.result.reason)
    result = ros.result(ros.send_goal(client, MoveMotors.Goal(motors=["fingers"], targets=[0.5])), timeout_sec=10.0)
    assert result.result.reason == "invalid: angle nan rad outside thumb_rotation's range"


# ---- one dispatch over the core's actions ----------------------------------------------------------------
# the modules that define the manipulation core's actions (names may be imported through the core)
CORE_ACTIONS = {"SendMove", "StopMotors", "Feedback", "Finished", "Ignored", "StampNews"}
ACTION_MODULES = ("manipulation_core", "goal_kind", "move_lease", "sample_stamps")


def test_the_core_s_actions_are_told_apart_in_one_place():
    chains = []
    for path in sorted((ROOT / "src").glob("*/*/*.py")):
        if path.parent.name != path.parent.parent.name:
            continue  # a package's own modules, not its tests
        tree = ast.parse(path.read_text())
        # the core's action classes this module imports (another package's `Finished` is not one)
        actions = {alias.asname or alias.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
                   and (node.module or "").rsplit(".", 1)[-1] in ACTION_MODULES
                   for alias in node.names if alias.name in CORE_ACTIONS}
        for node in ast.walk(tree):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "isinstance"
                    and len(node.args) == 2 and isinstance(node.args[1], ast.Name) and node.args[1].id in actions):
                chains.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.args[1].id}")
    assert not chains, f"isinstance over the core's actions outside ActionHandlers.carry_out: {chains}"


def test_an_action_of_no_known_type_is_refused():
    with pytest.raises(TypeError, match="str is none of the core's actions"):
        ActionHandlers().carry_out(["move"])
    seen: list = []
    ActionHandlers(send_move=seen.append).carry_out([SendMove({"fingers": 1.0}, 0.3, 5),
                                                     Feedback("grasp", "close", None)])
    assert seen == [SendMove({"fingers": 1.0}, 0.3, 5)]  # the feedback, not named, let pass
