"""The MoveMotors lease (move_lease.py) and the core's use of it: every velocity command leased for
0.3 s and re-sent every 0.1 s while it holds, a stop as a cancel, and each goal's lease counted
from the data it rests on, so that renewals a dropped link held back are refused when it returns."""
from __future__ import annotations

import pytest

from prisma_manipulation.controllers import JointSample
from prisma_manipulation.manipulation_core import (
    Feedback,
    Finished,
    ManipulateRequest,
)
from prisma_manipulation.move_lease import MOVE_LEASE_S, MoveLease, SendMove, StopMotors
from prisma_manipulation.node_config import ManipulationConfig
from prisma_motor_driver.motor_goals import goal_expired
from prisma_motor_driver.ros_conversions import velocity_goal
from prisma_testing.core_inputs import core_at_rest, pressed_pad

MS = 1_000_000


def test_motor_commands_are_leased_and_refreshed_while_they_hold():
    """The motor driver stops a MoveMotors goal after MOVE_LEASE_S (0.3 s); the core re-sends the
    running command every 0.1 s, so the motors stop within 0.3 s of the last refresh when it dies."""
    core = core_at_rest()
    rotate = {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 20.0}
    back = {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": -20.0}

    def scan(t_ms, rotation=0.5, right_lost=False):
        """Joint states (refreshes ride on their check) and a thumb sample at t_ms: what was sent."""
        t = t_ms * MS
        sent = core.on_joints(JointSample(t, {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": rotation}), t)
        sent += core.on_taxels("thumb", t, pressed_pad(right_lost), t)[1]
        return [a for a in sent if not isinstance(a, Feedback)]

    assert core.start(ManipulateRequest("horizontal"), 0)[0] == SendMove(rotate, 0.3, 0)
    assert [scan(t) for t in range(10, 100, 10)] == [[]] * 9  # same command: nothing sent
    # the refresh rides on /joint_states' check: its lease counts from the thumb's sample before (90 ms)
    assert scan(100) == [SendMove(rotate, 0.3, 90 * MS)]
    assert core.check(150 * MS) == [] and scan(190) == [] and scan(200) == [SendMove(rotate, 0.3, 190 * MS)]
    # the driver's goal timed out before a refresh reached it (this node stalled): sent again at once
    assert core.on_move_result("timeout", 230 * MS) == [SendMove(rotate, 0.3, 200 * MS)]
    assert scan(240) == [] and scan(320) == [] and scan(330) == [SendMove(rotate, 0.3, 320 * MS)]
    # a new command restarts the lease period
    assert scan(340, right_lost=True) == [SendMove(back, 0.3, 340 * MS)]
    assert [scan(t) for t in range(350, 440, 10)] == [[]] * 9 and scan(440) == [SendMove(back, 0.3, 430 * MS)]
    # the driver stopped the motors at its joint limit: no refresh drives them on
    assert core.on_move_result("joint_limit", 450 * MS) == []
    assert [scan(t) for t in range(450, 610, 10)] == [[]] * 16 and core.busy
    # a stop is a cancel, and nothing is refreshed after the goal
    core.on_joints(JointSample(610 * MS, {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}), 610 * MS)
    _, actions = core.on_taxels("thumb", 610 * MS, pressed_pad(), 610 * MS)
    assert isinstance(actions[0], StopMotors) and isinstance(actions[-1], Finished)
    assert core.check(10**9) == [] and core.on_move_result("timeout", 10**9) == []


def test_move_lease_decisions():
    lease = MoveLease(lease_s=0.3, refresh_s=0.1)
    assert lease.refresh(0, 0) is None  # nothing to keep alive
    assert lease.command({"fingers": 60.0}, 5 * MS, 2 * MS) == SendMove({"fingers": 60.0}, 0.3, 2 * MS)
    assert lease.refresh(104 * MS, 100 * MS) is None
    assert lease.refresh(105 * MS, 100 * MS) == SendMove({"fingers": 60.0}, 0.3, 100 * MS)
    assert lease.renew(106 * MS, 200 * MS) == SendMove({"fingers": 60.0}, 0.3, 106 * MS)  # never from the future
    # data 400 ms old counts as 150 ms: 150 ms of lease left, a refresh period and 50 ms
    assert lease.renew(500 * MS, 100 * MS) == SendMove({"fingers": 60.0}, 0.3, 350 * MS)
    with pytest.raises(ValueError, match="max data age 0.25 s must be from 0 to the lease less a refresh"):
        MoveLease(lease_s=0.3, refresh_s=0.1, max_data_age_s=0.25)
    assert lease.command({"fingers": 0.0, "thumb_flexion": 0.0}, 110 * MS, 110 * MS) == StopMotors()
    assert lease.refresh(10**9, 10**9) is None and lease.renew(10**9, 10**9) is None
    with pytest.raises(ValueError, match="refresh 0.3 s must be > 0 and below the lease 0.3 s"):
        MoveLease(lease_s=0.3, refresh_s=0.3)


def test_no_renewal_sent_into_a_dropped_link_restarts_the_motors_when_it_comes_back():
    """Two hosts, the link down 0.4 s: manipulation (stale_timeout 0.24 s) goes on renewing the
    command until its watchdog fires, and every renewal is delivered when the link comes back. Each
    lease counts from the data it rests on, so the driver refuses every one as expired; counted from
    its send time, the last would have run the motors again for 0.1 s."""
    core = core_at_rest(ManipulationConfig(stale_timeout=0.24))
    core.on_taxels("thumb", 0, pressed_pad(), 0)
    assert core.start(ManipulateRequest("horizontal"), 0)[0] == SendMove(
        {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 20.0}, MOVE_LEASE_S, 0)
    for t_ms in range(10, 110, 10):  # scans until the link drops after the one at 100 ms
        t = t_ms * MS
        core.on_joints(JointSample(t, {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 0.5}), t)
        core.on_taxels("thumb", t, pressed_pad(), t)
    outage = []
    for t_ms in range(120, 500, 20):  # the watchdog's ticks while nothing arrives
        actions = core.check(t_ms * MS)
        outage += [(t_ms * MS, a) for a in actions if isinstance(a, SendMove)]
        if not core.busy:
            break
    assert t_ms == 360 and isinstance(actions[-1], Finished) and actions[-1].reason == "sensor_stale"
    # the second renewal's data is 200 ms old: counted as 150 (MAX_DATA_AGE_S), its lease ends 450 ms
    assert [(t // MS, a.stamp_ns // MS) for t, a in outage] == [(200, 100), (300, 150)]
    back_ns = 500 * MS
    for _, action in outage:
        goal = velocity_goal(action.velocities_rpm, action.timeout_s, action.stamp_ns)
        assert goal_expired(goal, back_ns) is not None
    last_sent_ns, last = outage[-1]
    by_send_time = velocity_goal(last.velocities_rpm, last.timeout_s, last_sent_ns)
    assert goal_expired(by_send_time, back_ns) is None  # the old stamp: accepted, runs until 600 ms
