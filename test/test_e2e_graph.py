"""End to end on the rclpy stand-in: the whole simulated hand graph from the real node classes.

motor_driver (sim) -> /joint_states -> tactile_driver (sim, contact_source hand_world) ->
/prisma/<f>/taxels -> force_estimator (default bundle) -> /prisma/<f>/wrench -> manipulation
(Algorithm 1 + controllers) -> /prisma/motors/move -> motor_driver. Nothing in the loop is a test
double: the grasp closes on the estimator's Fz, the manipulation stops on the published taxels.

A Grasp goal (pinch) closes the open hand on the presented ball; once the presenting support has
let go, a Manipulate goal (horizontal) rolls the ball until the thumb pad's right side is lost.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from action_msgs.msg import GoalStatus
from geometry_msgs.msg import WrenchStamped
from prisma_msgs.action import Grasp, Manipulate
from prisma_msgs.msg import ContactState, TaxelArray
from sensor_msgs.msg import JointState

from prisma_tactile_driver.ros_conversions import ns_from_stamp
from prisma_tactile_driver.taxels import EDGES, FINGERS

BUNDLE = Path(__file__).resolve().parents[1] / "config" / "models" / "cnn2"
pytestmark = pytest.mark.skipif(not (BUNDLE / "model.pt").exists(), reason=f"default bundle {BUNDLE} not built")

K = 0.8  # config/manipulation.yaml


@pytest.fixture
def graph(ros):
    from prisma_force_estimator.force_estimator_node import ForceEstimatorNode
    from prisma_manipulation.manipulation_node import ManipulationNode
    from prisma_manipulation.motor_driver_node import MotorDriverNode
    from prisma_tactile_driver.tactile_driver_node import TactileDriverNode

    config = Path(__file__).resolve().parents[1] / "config"
    for name in ("motor_driver", "tactile_driver", "force_estimator", "manipulation"):
        ros.params_file(config / f"{name}.yaml")  # as hand.launch.py passes them
    ros.override(node="tactile_driver", backend="sim", contact_source="hand_world")
    ros.override(node="motor_driver", backend="sim")
    ros.override(node="force_estimator", model_bundle=str(BUNDLE))
    nodes = dict(motor=MotorDriverNode(), tactile=TactileDriverNode(), estimator=ForceEstimatorNode(),
                 manipulation=ManipulationNode())
    streams = dict(
        taxels={f: ros.collect(TaxelArray, f"/prisma/{f}/taxels") for f in FINGERS},
        wrench={f: ros.collect(WrenchStamped, f"/prisma/{f}/wrench") for f in FINGERS},
        contact={f: ros.collect(ContactState, f"/prisma/{f}/contact") for f in FINGERS},
        joints=ros.collect(JointState, "/joint_states"),
    )
    ros.advance(0.05)
    return type("Graph", (), {**nodes, **streams, "world": nodes["tactile"]._source.world})


def _send(ros, name, action, goal, feedback):
    client = ros.action_client(action, name)
    future = client.send_goal_async(goal, feedback_callback=feedback.append)
    assert ros.spin_until(future, timeout_sec=1.0)
    handle = future.result()
    assert handle.accepted
    result = handle.get_result_async()
    assert ros.spin_until(result, timeout_sec=10.0)
    return result.result()


def _stamps(messages):
    return [ns_from_stamp(m.header.stamp) for m in messages]


def test_grasp_then_horizontal_manipulation_through_every_node(ros, graph):
    g = graph
    assert g.world.forces()["thumb"] == 0.0  # the hand starts open, the ball on its support

    # ---- Grasp: fingers to 0.8 N, then thumb to 1 N, on the force estimator's Fz ----------------
    grasp_feedback = []
    sent = ros.now_ns()
    outcome = _send(ros, "/prisma/grasp", Grasp,
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
    # the result's forces are the estimator's: the last wrenches published before the goal ended
    done = ros.now_ns()
    thumb_fz = [w.wrench.force.z for w, s in zip(g.wrench["thumb"], _stamps(g.wrench["thumb"])) if s <= done]
    assert r.thumb_force == pytest.approx(thumb_fz[-1], abs=0.05)
    # ...and close to what the pads really carry
    assert g.world.forces()["thumb"] == pytest.approx(1.0, abs=0.15)
    assert g.world.forces()["index"] == pytest.approx(0.85, abs=0.15)
    assert 0.3 < (done - sent) * 1e-9 < 3.0

    # the presenting support lets go once the pinch has held the ball for a while
    ros.advance(1.0)
    assert g.world.obj.released or g.world.state.fixture_n_per_mm < 0.1
    thumb = g.contact["thumb"][-1]
    assert thumb.feasible and list(thumb.lost_edges) == []

    # ---- Manipulate: horizontal until the right side 6-3-0 is lost, then back ---------------------
    manipulate_feedback = []
    sent = ros.now_ns()
    outcome = _send(ros, "/prisma/manipulate", Manipulate,
                    Manipulate.Goal(motion="horizontal", speed_rpm=20.0, k=K, use_force=False, timeout=10.0),
                    manipulate_feedback)
    assert outcome.status == GoalStatus.STATUS_SUCCEEDED
    r = outcome.result
    assert r.success and r.stop_reason == "edge_lost"
    # the stop is the first published ContactState after the goal with the right side lost, and
    # that sample's right taxels really are all below K * mean
    contacts = [c for c in g.contact["thumb"] if ns_from_stamp(c.header.stamp) >= sent]
    first_lost = next(c for c in contacts if "right" in list(c.lost_edges))
    lost_ns = ns_from_stamp(first_lost.header.stamp)
    assert (lost_ns - sent) * 1e-9 == pytest.approx(r.stop_time, abs=0.011)
    v = np.asarray(first_lost.voltages)
    assert np.all(v[list(EDGES["right"])] < K * v.mean())
    before = [c for c in contacts if ns_from_stamp(c.header.stamp) < lost_ns]
    assert before and all(c.feasible for c in before)
    assert {"rotate", "return"} <= {f.feedback.phase for f in manipulate_feedback}
    ros.advance(0.3)
    rotation = float(g.joints[-1].position[list(g.joints[-1].name).index("thumb_rotation")])
    assert rotation == pytest.approx(0.0, abs=0.03)  # returned to the start angle
    assert g.world.forces()["thumb"] > 0.8  # still held

    # ---- the ContactState stream: one per taxel sample of every finger, with Algorithm 1 -----------
    for f in FINGERS:
        taxel_stamps, contact_stamps = _stamps(g.taxels[f]), _stamps(g.contact[f])
        assert contact_stamps == taxel_stamps and len(taxel_stamps) > 250
        assert _stamps(g.wrench[f]) == taxel_stamps  # the estimator stamps with the input's stamp
        assert all(b - a == 10_000_000 for a, b in zip(taxel_stamps, taxel_stamps[1:]))  # 100 Hz
        for c, t in zip(g.contact[f][::25], g.taxels[f][::25]):
            assert np.array_equal(np.asarray(c.voltages), np.asarray(t.voltages))
            assert c.k == pytest.approx(K)
            assert c.threshold == pytest.approx(K * c.mean_voltage, rel=1e-5)
            assert list(c.safe) == list(np.asarray(c.voltages) >= c.threshold)
    # untouched pads are reported, and never as a feasible contact
    assert not any(c.feasible for c in g.contact["ring"])
