"""Closed-loop scenarios on the cores (hand/world + PadModel taxels + contact monitor + controllers +
sim motors, no ROS). Every stop is checked against a reference computed independently from the
recorded taxel stream, and against the physical cause in the world model."""
from __future__ import annotations

import numpy as np
import pytest

from prisma_common.hand import MOTOR_NAMES
from prisma_manipulation.contact_monitor import first_lost_index
from prisma_manipulation.scenarios import DEFAULT_K, build
from prisma_testing.repo_paths import CONFIG

BUNDLE = CONFIG / "models" / "cnn2"
THUMB = 0  # FINGERS index


def thumb_xy(trace, i):
    return trace.array("contact_xy")[i, THUMB]


def run_to_first_loss(name, edge):
    """Scenario `name` run whole: it, its trace, the thumb pad's voltages and the first sample at which
    the pad lost `edge` (computed from the recorded taxels, apart from the controller)."""
    sc = build(name)
    tr = sc.run()
    v = tr.finger_voltages("thumb")
    i = first_lost_index(v, DEFAULT_K, edge)
    assert i is not None, f"{name}: the thumb pad never lost its {edge} side"
    return sc, tr, v, i


def left_safe_count(voltages_row, k=DEFAULT_K):
    return int((voltages_row[[2, 5, 8]] >= k * voltages_row.mean()).sum())


@pytest.fixture(scope="module")
def horizontal():
    sc = build("horizontal")
    return sc, sc.run()


def test_horizontal_stops_within_one_sample_of_losing_6_3_0(horizontal):
    sc, tr = horizontal
    c = sc.controller
    v = tr.finger_voltages("thumb")
    i = first_lost_index(v, DEFAULT_K, "right")
    assert i is not None, "the right side was never lost"
    assert c.reason == "edge_lost" and c.success
    assert 0 <= c.stop_ns - tr.stamps_ns[i] <= tr.period_ns  # same sample (or the next)
    assert all(v[i][[0, 3, 6]] < DEFAULT_K * v[i].mean())
    # the physical cause: clockwise rotation rolled the contact toward the thumb pad's left side
    assert tr.position("thumb_rotation")[i] > 0.2
    assert thumb_xy(tr, i)[0] > 1.0 and abs(thumb_xy(tr, i)[1]) < 0.5
    assert tr.force("thumb")[i] == pytest.approx(1.0, abs=0.05)  # still held: not a release
    rotating = tr.array("commands")[:i, MOTOR_NAMES.index("thumb_rotation")]
    assert np.all(rotating == 20.0)
    for edge in ("top", "bottom", "left"):
        assert first_lost_index(v[: i + 1], DEFAULT_K, edge) is None


def test_horizontal_then_returns_to_the_start_angle(horizontal):
    sc, tr = horizontal
    c = sc.controller
    i = tr.index_of(c.stop_ns)
    assert tr.array("commands")[i, MOTOR_NAMES.index("thumb_rotation")] == -20.0  # anticlockwise back
    start = c.start_positions["thumb_rotation"]
    assert tr.position("thumb_rotation").max() > start + 0.3
    assert tr.position("thumb_rotation")[-1] == pytest.approx(start, abs=0.02)
    assert abs(thumb_xy(tr, len(tr.stamps_ns) - 1)[0]) < 0.3  # contact back at the pad centre


def test_vertical_stops_on_the_top_row_then_on_the_bottom_row():
    sc, tr, v, i_top = run_to_first_loss("vertical", "top")
    c = sc.controller
    down_stop, down_reason = c.phase_stops["down"]
    assert down_reason == "edge_lost"
    assert 0 <= down_stop - tr.stamps_ns[i_top] <= tr.period_ns
    # cause: fingers closed while the thumb extended, rolling the contact toward the bottom row
    assert tr.position("fingers")[i_top] > tr.position("fingers")[0] + 0.3
    assert tr.position("thumb_flexion")[i_top] < tr.position("thumb_flexion")[0] - 0.3
    assert thumb_xy(tr, i_top)[1] < -1.0
    i_bottom = first_lost_index(v, DEFAULT_K, "bottom", start=i_top + 1)
    assert i_bottom is not None
    assert c.reason == "edge_lost" and c.phase_stops["up"][1] == "edge_lost"
    assert 0 <= c.stop_ns - tr.stamps_ns[i_bottom] <= tr.period_ns
    assert thumb_xy(tr, i_bottom)[1] > 1.0
    # rolling keeps the grip: the thumb force stays near 1 N the whole time
    done = tr.done_index
    assert np.all(np.abs(tr.force("thumb")[:done] - 1.0) < 0.1)
    commands = tr.array("commands")
    assert np.all(commands[:i_top, 0] == 10.0) and np.all(commands[:i_top, 1] == -10.0)
    assert np.all(commands[i_top:done, 0] == -10.0) and np.all(commands[i_top:done, 1] == 10.0)


def test_disturbance_losing_the_left_side_is_restored_by_thumb_rotation():
    sc, tr, v, i_lost = run_to_first_loss("disturbance", "left")
    c = sc.controller
    # cause: the push (from 0.5 s) slid the contact toward the right side, no motor moved
    assert tr.stamps_ns[i_lost] > 0.5e9
    assert thumb_xy(tr, i_lost)[0] < -1.0
    assert np.all(tr.position("thumb_rotation")[: i_lost + 1] == tr.position("thumb_rotation")[0])
    assert len(c.restorations) == 1
    side, lost_ns, restored_ns = c.restorations[0]
    assert side == "left"
    assert 0 <= lost_ns - tr.stamps_ns[i_lost] <= tr.period_ns
    i_restored = tr.index_of(restored_ns)
    rotation = tr.array("commands")[:, MOTOR_NAMES.index("thumb_rotation")]
    i_cmd = tr.index_of(lost_ns)
    assert np.all(rotation[i_cmd:i_restored] == 20.0)  # clockwise: moves the contact back to +x
    # restored = at least two left taxels at or above v_t, computed from the recorded volts; the
    # sample before had fewer
    assert left_safe_count(v[i_restored]) >= 2
    assert left_safe_count(v[i_restored - 1]) < 2
    assert rotation[i_restored] == 0.0
    assert thumb_xy(tr, i_restored)[0] > thumb_xy(tr, i_lost)[0] + 1.0
    assert c.reason == "timeout" and c.success  # a hold goal ends when its time is up


SETTLE_SAMPLES = 10  # 100 ms = 10 velocity-loop time constants: the stopped motor has settled


def _check_grasp(tr, c, which):
    fingers_end = tr.index_of(c.phase_end_ns["close_fingers"])
    thumb_end = tr.index_of(c.phase_end_ns["close_thumb"])
    index_force, thumb_force = tr.force("index", which), tr.force("thumb", which)
    # each phase stops on the first sample at or above its target...
    assert index_force[fingers_end] >= 0.8 and index_force[fingers_end - 1] < 0.8
    assert thumb_force[thumb_end] >= 1.0 and thumb_force[thumb_end - 1] < 1.0
    # ...and the force settles no more than 0.1 N above it (motor deceleration included): the
    # fingers' step response until their motor has settled (later the thumb's push moves the
    # object and the index contact, which is no longer this phase's response), the thumb's until
    # the end of the recording
    assert np.all(tr.force("thumb")[fingers_end:fingers_end + SETTLE_SAMPLES + 1] == 0.0)
    assert index_force[fingers_end:fingers_end + SETTLE_SAMPLES + 1].max() <= 0.8 + 0.1
    assert thumb_force[thumb_end:].max() <= 1.0 + 0.1
    assert len(tr.stamps_ns) - thumb_end >= 40  # 0.4 s of settling observed
    commands = tr.array("commands")
    assert np.all(commands[:fingers_end, 0] == 60.0) and np.all(commands[fingers_end:thumb_end, 1] == 60.0)
    return fingers_end, thumb_end


def test_pinch_grasp_with_ground_truth_force_reaches_targets_without_overshoot():
    sc = build("pinch_grasp")
    tr = sc.run()
    c = sc.controller
    assert c.reason == "force_reached" and c.success
    fingers_end, thumb_end = _check_grasp(tr, c, "true")
    # ground truth has no estimator error: the index stays within 0.1 N through the thumb phase too
    assert tr.force("index")[fingers_end:].max() <= 0.8 + 0.1


@pytest.mark.skipif(not (BUNDLE / "model.pt").exists(),
                    reason=f"default force-estimator bundle {BUNDLE} not built yet")
def test_pinch_grasp_at_60_rpm_100_hz_with_the_estimators_forces():
    from prisma_force_estimator.inference import ForceEstimator

    estimator = ForceEstimator.from_bundle(BUNDLE)
    sc = build("pinch_grasp", estimator=estimator)
    assert sc.loop.period_ns == 10_000_000 and sc.request.speed_rpm == 60.0
    tr = sc.run()
    c = sc.controller
    assert c.speed_rpm == 60.0
    assert c.reason == "force_reached" and c.success
    fingers_end, thumb_end = _check_grasp(tr, c, "used")
    # what the pads really carry: close to the targets as well (estimator error included)
    assert tr.force("index")[fingers_end:fingers_end + SETTLE_SAMPLES + 1].max() <= 0.8 + 0.1
    assert tr.force("index")[fingers_end] == pytest.approx(0.8, abs=0.1)
    assert tr.force("thumb")[thumb_end:].max() <= 1.0 + 0.1
    assert tr.force("thumb")[thumb_end] == pytest.approx(1.0, abs=0.1)


@pytest.mark.skipif(not (BUNDLE / "model.pt").exists(),
                    reason=f"default force-estimator bundle {BUNDLE} not built yet")
def test_a_pinch_reports_the_index_force_the_thumb_pushed_it_to():
    """docs/manipulation.md, "The finger force a pinch reports": on the sim graph's world (the ball let
    go once held) the fingers stop at their 0.8 N target; the thumb then presses the ball against the
    stopped index, so the result's finger_force, read when the thumb reaches 1 N, is ~0.97 N."""
    from prisma_force_estimator.inference import ForceEstimator
    from prisma_hand_sim.hand_world import HandWorld
    from prisma_manipulation.closed_loop import ClosedLoop
    from prisma_manipulation.grasp_goal import GraspRequest

    loop = ClosedLoop(HandWorld(obj="pinch_ball"), ForceEstimator.from_bundle(BUNDLE), seed=0)
    tr = loop.run(GraspRequest("pinch"), 5.0)
    assert loop.finished is not None and loop.finished.reason == "force_reached"
    fingers_stop = tr.index_of(loop.controller.phase_end_ns["close_fingers"])
    assert tr.force("index", "used")[fingers_stop] == pytest.approx(0.83, abs=0.02)  # the target and its overshoot
    assert tr.force("index")[fingers_stop] == pytest.approx(0.825, abs=0.02)
    assert loop.finished.status.finger_force == pytest.approx(0.97, abs=0.03)  # 0.969 N measured
    assert loop.finished.status.thumb_force == pytest.approx(1.02, abs=0.03)
    assert tr.force("index")[-1] == pytest.approx(0.92, abs=0.02)  # true: the thumb's 1.0 N less the support's share


def test_combined_restores_force_and_orientation_after_a_slip():
    sc = build("combined")
    tr = sc.run()
    c = sc.controller
    thumb_force = tr.force("thumb")
    dropped = int(np.argmax(thumb_force < 0.85))
    assert thumb_force[dropped] < 0.85  # the slip to a narrower section lowered the grasp force
    assert c.force_keeper.restores >= 1
    flexion = tr.array("commands")[:, MOTOR_NAMES.index("thumb_flexion")]
    assert np.any(flexion[dropped:] > 0)  # the thumb flexed to restore it
    assert thumb_force[-1] >= 0.95 and thumb_force[dropped:].max() <= 1.1
    assert len(c.restorations) == 1 and c.restorations[0][0] == "left"
    assert left_safe_count(tr.finger_voltages("thumb")[-1]) >= 2


@pytest.mark.parametrize("obj, preset", [("power_ball", "power"), ("lateral_card", "lateral")])
def test_power_and_lateral_presets_close_on_their_objects(obj, preset):
    from prisma_hand_sim.hand_world import HandWorld
    from prisma_manipulation.closed_loop import ClosedLoop
    from prisma_manipulation.manipulation_core import GraspRequest

    world = HandWorld(obj=obj)
    loop = ClosedLoop(world)
    tr = loop.run(GraspRequest(preset), 10.0, settle_s=0.3)
    c = loop.controller
    assert c.reason == "force_reached"
    i_fingers = tr.index_of(c.phase_end_ns["close_fingers"])
    if preset == "power":
        pads = np.stack([tr.force(f) for f in ("index", "middle", "ring", "little")], axis=1)[i_fingers]
        assert np.all(pads > 0.1)  # all four fingers wrap the ball
        assert pads.mean() >= 0.8 and c.fingers_force(dict(zip(("index", "middle", "ring", "little"), pads))) >= 0.8
    else:
        assert tr.position("fingers")[i_fingers] >= 7.0  # fist made by position, no fingertip contact
        assert np.all(tr.force("index") == 0.0)
    i_thumb = tr.index_of(c.phase_end_ns["close_thumb"])
    assert tr.force("thumb")[i_thumb] >= 1.0 and tr.force("thumb")[i_thumb:].max() <= 1.1


@pytest.mark.parametrize("name", ["disturbance", "combined"])
def test_index_force_true_and_estimated_agree_on_the_pad_and_are_zero_off_it(name):
    """The push slides the ball off the index pad: from then on the pad carries no force, in the
    world (the finger still squeezes the ball beside the pad) as in the estimate from its taxels."""
    from prisma_force_estimator.inference import ForceEstimator

    estimator = ForceEstimator.from_bundle(BUNDLE)
    trace = build(name, estimator=estimator).run()
    true, used = trace.force("index", "true"), trace.force("index", "used")
    on_pad = ~np.isnan(trace.array("contact_xy")[:, 1, 0])
    assert 50 < on_pad.sum() < len(on_pad) - 50  # on the pad before the push, off it after
    assert np.abs(used - true)[on_pad].max() < 0.15  # N: the estimator's error on this pad
    assert (true[~on_pad] == 0.0).all()
    assert np.abs(used[~on_pad]).max() < 0.05  # the estimate of an unloaded pad


def _gripper(world, estimator=None):
    """The pinch ball or an empty hand, closed with GripperCommand position 9 rad (fully) and a 1 N
    force limit, then opened with position 0; each goal's trace."""
    from prisma_manipulation.closed_loop import ClosedLoop
    from prisma_manipulation.manipulation_core import GripperRequest

    loop = ClosedLoop(world, estimator)
    close = loop.run(GripperRequest(9.0, 1.0), 5.0, settle_s=0.3)
    closer = loop.controller
    opened = loop.run(GripperRequest(0.0), 5.0, start_ns=close.stamps_ns[-1] + close.period_ns, settle_s=0.3)
    return (close, closer), (opened, loop.controller)


@pytest.mark.skipif(not (BUNDLE / "model.pt").exists(),
                    reason=f"default force-estimator bundle {BUNDLE} not built yet")
def test_gripper_closing_on_the_pinch_ball_stalls_at_1_n_estimated_then_opens():
    from prisma_force_estimator.inference import ForceEstimator
    from prisma_hand_sim.hand_world import HandWorld

    (close, c), (opened, o) = _gripper(HandWorld(obj="pinch_ball"), ForceEstimator.from_bundle(BUNDLE))
    assert (c.reason, c.success, c.stalled, c.reached_goal) == ("force_reached", True, True, False)
    i = close.done_index
    used = close.array("forces_used")[i]
    assert c.effort == used.max() and 1.0 <= c.effort <= 1.1  # stopped on the first sample at the limit
    assert np.nanmax(close.array("forces_used")[:i]) < 1.0
    # thumb and index both press the ball (the thumb follows at 0.8333 of the fingers angle); the
    # index, closing faster, reaches the limit ...
    true = dict(zip(("thumb", "index"), close.array("forces_true")[i]))
    assert true["index"] == pytest.approx(1.0, abs=0.1) and true["thumb"] == pytest.approx(0.85, abs=0.1)
    assert close.array("forces_true")[i:].max() <= 1.1  # ... and they settle below the limit + 0.1 N
    assert c.position == pytest.approx(4.9, abs=0.1)  # index contact at 3.0 rad + 1.9 rad of tendon stretch
    assert close.position("thumb_flexion")[-1] == pytest.approx(0.8333 * close.position("fingers")[-1], abs=0.01)
    assert close.position("fingers")[-1] < 9.0 - 3.0  # far from the position asked for
    # open: position 0 is reached whatever the force limit; nothing touches the pads any more
    assert (o.reason, o.success, o.stalled, o.reached_goal) == ("reached", True, False, True)
    assert opened.position("fingers")[-1] == pytest.approx(0.0, abs=0.1)
    assert opened.position("thumb_flexion")[-1] == pytest.approx(0.0, abs=0.1)
    assert np.all(opened.array("forces_true")[-1] == 0.0)


def test_gripper_closing_on_nothing_reaches_its_position():
    from prisma_hand_sim.hand_world import HandWorld

    (close, c), (opened, o) = _gripper(HandWorld(obj="none"))
    assert (c.reason, c.success, c.stalled, c.reached_goal) == ("reached", True, False, True)
    assert c.effort == 0.0 and np.all(close.array("forces_true") == 0.0)
    # fingers 9 rad at 60 rpm takes 1.43 s; the thumb's target 0.8333 x 9 is clamped to its 7 rad end
    assert (c.stop_ns - c.start_ns) * 1e-9 == pytest.approx(9.0 / (2 * np.pi), abs=0.02)
    assert close.position("fingers")[-1] == pytest.approx(9.0, abs=0.05)
    assert close.position("thumb_flexion")[-1] == pytest.approx(7.0, abs=0.05)
    assert (o.reason, o.reached_goal) == ("reached", True)
    assert opened.position("fingers")[-1] == pytest.approx(0.0, abs=0.1)
