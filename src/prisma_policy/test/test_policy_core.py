"""The policy node's decisions per tick, with a policy whose targets are a known function of what it
observes: fresh inputs -> those targets, stamped with the tick; missing, stale or future inputs ->
nothing, with the reason; the Teleoperate goal with the first targets and again after it ended."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from prisma_common.diagnostics import ERROR, OK, WARN
from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_motor_driver.control_table import rpm_to_rad_s
from prisma_policy.bc_policy import Policy
from prisma_policy.policy_core import NS, RETRY_S, Act, Hold, PolicyCore

TACTILE_N, WRENCH_N = 45, 30  # the flat observation: 45 taxel voltages, 30 wrench values, then 6 of state
THUMB_FZ = TACTILE_N + FINGERS.index("thumb") * 6 + 2
INDEX_TAXEL_4 = FINGERS.index("index") * 9 + 4


def linear_policy() -> Policy:
    """fingers = 2 x fingers position + 0.5; thumb_flexion = thumb Fz + index centre taxel;
    thumb_rotation = 0.25 (no normalisation: mean 0, std 1)."""
    network = torch.nn.Sequential(torch.nn.Linear(81, 3))
    with torch.no_grad():
        network[0].weight.zero_()
        network[0].bias.copy_(torch.tensor([0.5, 0.0, 0.25]))
        network[0].weight[0, TACTILE_N + WRENCH_N + 0] = 2.0
        network[0].weight[1, THUMB_FZ] = 1.0
        network[0].weight[1, INDEX_TAXEL_4] = 1.0
    return Policy(network, np.zeros(81), np.ones(81), np.zeros(3), np.ones(3), 0, 50)


def fed(core: PolicyCore, stamp_ns: int) -> PolicyCore:
    """Every finger's taxels (centre taxel 0.1 x finger number) and wrench (Fz 0.3 N per finger number),
    and the motors at 1.2 rad / 0.3 / -0.4 moving at 30 rpm, all stamped `stamp_ns`."""
    for number, finger in enumerate(FINGERS):
        volts = np.zeros(9)
        volts[4] = 0.1 * number
        core.on_taxels(finger, stamp_ns, volts)
        core.on_wrench(finger, stamp_ns, np.array([0.0, 0.0, 0.3 * number, 0.0, 0.0, 0.0]))
    positions = dict(zip(MOTOR_NAMES, (1.2, 0.3, -0.4)))
    assert core.on_joints(stamp_ns, positions, {m: 30.0 for m in MOTOR_NAMES})
    return core


def test_fresh_inputs_give_the_policys_targets_stamped_with_the_tick():
    core = fed(PolicyCore(linear_policy(), max_input_age_s=0.1), stamp_ns=10 * NS)
    decision = core.tick(10 * NS + 40_000_000)
    assert isinstance(decision, Act)
    assert decision.stamp_ns == 10 * NS + 40_000_000
    thumb_fz = 0.3 * FINGERS.index("thumb")
    index_centre = 0.1 * FINGERS.index("index")
    assert decision.targets == pytest.approx({MOTOR_NAMES[0]: 2 * 1.2 + 0.5, MOTOR_NAMES[1]: thumb_fz + index_centre,
                                              MOTOR_NAMES[2]: 0.25}, abs=1e-6)
    assert core.state[3:] == pytest.approx([rpm_to_rad_s(30.0)] * 3)  # velocities in rad/s, as the dataset's
    assert decision.send_goal  # the first targets carry the goal


def test_missing_stale_and_future_inputs_hold_with_the_reason():
    core = PolicyCore(linear_policy(), max_input_age_s=0.1)
    assert core.tick(NS) == Hold(f"no taxels/{FINGERS[0]} sample yet")
    fed(core, stamp_ns=NS)
    core.stamps.pop("joint_states")
    assert core.tick(NS) == Hold("no joint_states sample yet")
    fed(core, stamp_ns=NS)
    core.on_wrench("middle", NS - 150_000_000, np.zeros(6))  # one finger's wrench 0.25 s old at the tick
    held = core.tick(NS + 100_000_000)
    assert held == Hold("wrench/middle is 0.250 s old (max_input_age 0.1 s)")
    assert core.tick(NS + 100_000_000) == held and not core.goal_running  # nothing sent while held
    fed(core, stamp_ns=NS)
    assert isinstance(core.tick(NS + 100_000_000), Act)  # exactly max_input_age old still acts
    assert core.tick(NS + 100_000_001) == Hold(f"taxels/{FINGERS[0]} is 0.100 s old (max_input_age 0.1 s)")
    fed(core, stamp_ns=2 * NS)
    assert core.tick(2 * NS - 20_000_000) == Hold(f"taxels/{FINGERS[0]} is stamped 0.020 s ahead of this node's clock")


def test_no_model_holds_with_its_reason():
    core = fed(PolicyCore(None, 0.1, "no model: give model_path"), stamp_ns=NS)
    assert core.tick(NS) == Hold("no model: give model_path")
    assert core.period_s(0.0) == pytest.approx(0.1)


def test_a_joint_state_without_every_motor_is_not_taken():
    core = PolicyCore(linear_policy(), 0.1)
    assert not core.on_joints(NS, {MOTOR_NAMES[0]: 1.0}, {MOTOR_NAMES[0]: 0.0})
    assert "joint_states" not in core.stamps and core.state.tolist() == [0.0] * 6
    core.on_taxels("sixth", NS, np.ones(9))  # not a finger of the hand: ignored
    assert "taxels/sixth" not in core.stamps


def test_the_goal_once_then_again_retry_s_after_it_ended():
    core = fed(PolicyCore(linear_policy(), 0.1), stamp_ns=NS)
    assert [core.tick(NS + k * 20_000_000).send_goal for k in range(3)] == [True, False, False]  # type: ignore[union-attr]
    core.on_goal_ended(NS + 40_000_000)  # e.g. input_stale
    retry = NS + 40_000_000 + int(RETRY_S * NS)
    fed(core, stamp_ns=retry - 60_000_000)
    assert core.tick(retry - 20_000_000).send_goal is False  # type: ignore[union-attr]
    assert core.tick(retry).send_goal is True  # type: ignore[union-attr]


def test_the_period_is_the_rate_or_the_models_fps():
    core = PolicyCore(linear_policy(), 0.1)
    assert core.period_s(0.0) == pytest.approx(1 / 50)
    assert core.period_s(25.0) == pytest.approx(1 / 25)


def test_diagnostics_say_no_model_holding_and_acting_with_the_counts():
    without = PolicyCore(None, 0.05, "no model: give model_path")
    without.tick(NS)
    status = without.diagnostics()
    assert (status.name, status.level, status.message) == ("policy", ERROR, "no model: give model_path")
    assert status.values["model"] == "none" and status.values["targets_published"] == "0"

    core = PolicyCore(linear_policy(), 0.05)
    core.tick(NS)
    status = core.diagnostics()
    assert (status.level, status.message) == (WARN, "publishing nothing: no taxels/thumb sample yet")
    fed(core, 2 * NS)
    core.tick(2 * NS)
    core.tick(2 * NS + NS // 100)
    status = core.diagnostics()
    assert (status.level, status.message) == (OK, "acting")
    assert status.values == {"model": "0 episodes at 50 fps", "targets_published": "2", "goals_sent": "1",
                             "goal_running": "true", "last_goal_end": "none"}
    core.on_goal_ended(2 * NS + NS // 50, "aborted: touch_limit")
    core.tick(2 * NS + NS)  # inputs 1 s old: held
    status = core.diagnostics()
    assert status.level == WARN and status.message.startswith("publishing nothing: taxels/thumb is 1.000 s old")
    assert (status.values["goal_running"], status.values["last_goal_end"]) == ("false", "aborted: touch_limit")
