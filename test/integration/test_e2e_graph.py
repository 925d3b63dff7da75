"""End to end on real rclpy over DDS: the whole simulated hand graph from the real node classes.

motor_driver (sim) -> /joint_states -> tactile_driver (sim, contact_source hand_world) ->
/prisma/<f>/taxels -> force_estimator (default bundle) -> /prisma/<f>/wrench -> manipulation
(Algorithm 1 + controllers) -> /prisma/motors/move -> motor_driver. Nothing in the loop is a test
double: the grasp closes on the estimator's Fz, the manipulation stops on the published taxels.

Each node takes its config/*.yaml as hand.launch.py passes it, and runs on a /clock the test
publishes: time moves in settled 10 ms steps (every message of an instant handled before the next),
so every stamp is exact. The goals are sent as a client does right after start-up: sent again only
while the manipulation node refuses them `not_ready` (aborted at once, the reason in the result)
because a stream is not there yet.

A Grasp goal (pinch) closes the open hand on the presented ball; once the presenting support has
let go, a Manipulate goal (horizontal) rolls the ball until the thumb pad's right side is lost.
"""
from __future__ import annotations

import time

import numpy as np
import pytest

from prisma_testing.goals import refusal_for_now
from prisma_testing.repo_paths import CONFIG
from prisma_testing.ros_harness import require_ros, stamp_ns

require_ros()

from action_msgs.msg import GoalStatus  # noqa: E402
from geometry_msgs.msg import WrenchStamped  # noqa: E402
from prisma_msgs.action import Grasp, Manipulate  # noqa: E402
from prisma_msgs.msg import ContactState, TaxelArray  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from prisma_common.hand import FINGERS
from prisma_tactile_driver.taxels import EDGES  # noqa: E402

BUNDLE = CONFIG / "models" / "cnn2"
pytestmark = pytest.mark.skipif(not (BUNDLE / "model.pt").exists(), reason=f"default bundle {BUNDLE} not built")

K = 0.8  # config/manipulation.yaml
STEP = 0.01  # s: the drivers' period
READINESS = ("MoveMotors action server", "no /joint_states", "no taxels/", "no wrench/", "silent for",
             "older than /joint_states")


@pytest.fixture
def graph(ros):
    from prisma_force_estimator.force_estimator_node import ForceEstimatorNode
    from prisma_manipulation.manipulation_node import ManipulationNode
    from prisma_motor_driver.motor_driver_node import MotorDriverNode
    from prisma_tactile_driver.tactile_driver_node import TactileDriverNode

    ros.capture_logs()
    streams = dict(
        taxels={f: ros.collect(TaxelArray, f"/prisma/{f}/taxels") for f in FINGERS},
        wrench={f: ros.collect(WrenchStamped, f"/prisma/{f}/wrench") for f in FINGERS},
        contact={f: ros.collect(ContactState, f"/prisma/{f}/contact") for f in FINGERS},
        joints=ros.collect(JointState, "/joint_states"),
    )

    def node(cls, name, **params):
        return ros.node(cls, params_files=[CONFIG / f"{name}.yaml"], params=params, sim_time=True)

    nodes = dict(motor=node(MotorDriverNode, "motor_driver", backend="sim"),
                 tactile=node(TactileDriverNode, "tactile_driver", backend="sim", contact_source="hand_world"),
                 estimator=node(ForceEstimatorNode, "force_estimator", model_bundle=str(BUNDLE)),
                 manipulation=node(ManipulationNode, "manipulation"))
    return type("Graph", (), {**nodes, **streams, "world": nodes["tactile"]._source.world})


def _run(ros, name, action, goal, feedback, timeout_sec=120.0):
    """Send the goal as soon as the server is there, again after every refusal for a stream not
    ready yet (advancing the clock 10 ms), and run the clock until its result."""
    client = ros.action_client(action, name)
    for _ in range(500):
        handle = ros.send_goal(client, goal, feedback)
        future = handle.get_result_async()
        assert ros.spin_until(lambda: feedback or future.done())  # noqa: B023 - runs now
        refused = refusal_for_now(future.result().result) if future.done() else None
        if refused is None:
            break
        assert refused.startswith("not_ready: ") and any(r in refused for r in READINESS), refused
        ros.advance(STEP, step=STEP, settle=True)
    assert handle.accepted and refused is None
    sent = ros.now_ns()
    deadline = time.monotonic() + timeout_sec
    while not future.done() and time.monotonic() < deadline:
        ros.advance(STEP, step=STEP, settle=True)
    assert future.done(), f"no result within {timeout_sec} s"
    return sent, future.result()


def _stamps(messages):
    return [stamp_ns(m) for m in messages]


def test_grasp_then_horizontal_manipulation_through_every_node(ros, graph):
    g = graph
    assert g.world.forces()["thumb"] == 0.0  # the hand starts open, the ball on its support

    # ---- Grasp: fingers to 0.8 N, then thumb to 1 N, on the force estimator's Fz ----------------
    grasp_feedback = []
    sent, outcome = _run(ros, "/prisma/grasp", Grasp,
                         Grasp.Goal(grasp="pinch", finger_force=0.8, thumb_force=1.0, speed_rpm=60.0, timeout=10.0),
                         grasp_feedback)
    assert outcome.status == GoalStatus.STATUS_SUCCEEDED
    r = outcome.result
    assert r.success and r.reason == "force_reached"
    # the thumb phase ends on the first estimate at or above 1 N; the index force rose further
    # while the thumb pushed the ball against it
    assert 1.0 <= r.thumb_force <= 1.15 and 0.8 <= r.finger_force <= 1.3
    phases = [f.feedback.phase for f in grasp_feedback]
    assert phases[0] == "close_fingers" and "close_thumb" in phases and phases[-1] == "done"
    switch = phases.index("close_thumb")
    assert grasp_feedback[switch - 1].feedback.finger_force < 0.8 <= grasp_feedback[switch].feedback.finger_force
    # the result's forces are the estimator's: the thumb's is the estimate that ended its phase, the
    # first at or above 1 N (the result itself comes once the motor driver has ended the stopped
    # MoveMotors goal, up to 0.5 s later, while the braking thumb still presses on)
    done = ros.now_ns()
    assert ros.spin_until(lambda: g.wrench["thumb"] and stamp_ns(g.wrench["thumb"][-1]) >= done - 10_000_000)
    thumb_fz = [w.wrench.force.z for w, s in zip(g.wrench["thumb"], _stamps(g.wrench["thumb"])) if sent <= s <= done]
    assert r.thumb_force == pytest.approx(next(fz for fz in thumb_fz if fz >= 1.0), abs=1e-4)
    # ...and close to what the pads really carry
    assert g.world.forces()["thumb"] == pytest.approx(1.0, abs=0.15)
    assert g.world.forces()["index"] == pytest.approx(0.85, abs=0.15)
    assert 0.3 < (done - sent) * 1e-9 < 3.0

    # the presenting support lets go once the pinch has held the ball for a while
    ros.advance(1.0, step=STEP, settle=True)
    assert g.world.obj.released or g.world.state.fixture_n_per_mm < 0.1
    assert ros.spin_until(lambda: stamp_ns(g.contact["thumb"][-1]) == ros.now_ns())
    thumb = g.contact["thumb"][-1]
    assert thumb.feasible and list(thumb.lost_edges) == []

    # ---- Manipulate: horizontal until the right side 6-3-0 is lost, then back ---------------------
    manipulate_feedback = []
    sent, outcome = _run(ros, "/prisma/manipulate", Manipulate,
                         Manipulate.Goal(motion="horizontal", speed_rpm=20.0, k=K, use_force=False, timeout=10.0),
                         manipulate_feedback)
    assert outcome.status == GoalStatus.STATUS_SUCCEEDED
    r = outcome.result
    assert r.success and r.stop_reason == "edge_lost"
    ros.advance(0.3, step=STEP, settle=True)
    assert ros.spin_until(lambda: all(stamp_ns(g.contact[f][-1]) == ros.now_ns() for f in FINGERS))
    # the stop is the first published ContactState after the goal with the right side lost, and
    # that sample's right taxels really are all below K * mean
    contacts = [c for c in g.contact["thumb"] if stamp_ns(c) >= sent]
    first_lost = next(c for c in contacts if "right" in list(c.lost_edges))
    lost_ns = stamp_ns(first_lost)
    assert (lost_ns - sent) * 1e-9 == pytest.approx(r.stop_time, abs=1e-6)
    v = np.asarray(first_lost.voltages)
    assert np.all(v[list(EDGES["right"])] < K * v.mean())
    before = [c for c in contacts if stamp_ns(c) < lost_ns]
    assert before and all(c.feasible for c in before)
    assert {"rotate", "return"} <= {f.feedback.phase for f in manipulate_feedback}
    rotation = float(g.joints[-1].position[list(g.joints[-1].name).index("thumb_rotation")])
    assert rotation == pytest.approx(0.0, abs=0.03)  # returned to the start angle
    assert g.world.forces()["thumb"] > 0.8  # still held

    # ---- the ContactState stream: one per taxel sample of every finger, with Algorithm 1 -----------
    ros.spin_for(0.1)
    for f in FINGERS:
        # every sample from the first one the manipulation node saw (a scan published before the
        # subscriber was discovered is the only one it may miss)
        taxel_stamps, contact_stamps = _stamps(g.taxels[f]), _stamps(g.contact[f])
        assert contact_stamps[0] - taxel_stamps[0] <= 10_000_000
        assert contact_stamps == [s for s in taxel_stamps if s >= contact_stamps[0]] and len(contact_stamps) > 250
        wrench_stamps = _stamps(g.wrench[f])  # the estimator stamps with the input's stamp
        assert wrench_stamps[0] - taxel_stamps[0] <= 10_000_000
        assert wrench_stamps == [s for s in taxel_stamps if s >= wrench_stamps[0]]
        assert all(b - a == 10_000_000 for a, b in zip(taxel_stamps, taxel_stamps[1:]))  # 100 Hz
        taxels_at = {stamp_ns(t): t for t in g.taxels[f]}
        for c in g.contact[f][::25]:
            t = taxels_at[stamp_ns(c)]
            assert np.array_equal(np.asarray(c.voltages), np.asarray(t.voltages))
            assert c.k == pytest.approx(K)
            assert c.threshold == pytest.approx(K * c.mean_voltage, rel=1e-5)
            assert list(c.safe) == list(np.asarray(c.voltages) >= c.threshold)
    # untouched pads are reported, and never as a feasible contact
    assert not any(c.feasible for c in g.contact["ring"])
    # nothing went wrong on the way: no goal ended any other way, no stream went stale
    assert ros.logs(severity="error") == []
    assert [m for m in ros.logs(name="manipulation") if "goal ended" in m] == \
        ["grasp goal ended: force_reached", "manipulate goal ended: edge_lost"]
