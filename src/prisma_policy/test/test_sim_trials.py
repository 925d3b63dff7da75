"""The trials: balls outside what the demonstrations showed, the closed / touch-limit verdicts by hand,
and a policy that always asks for a fist held by the Teleoperate goal's touch limit in the closed loop."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from prisma_common.hand import FINGERS
from prisma_force_estimator.force_estimator_core import load_estimator
from prisma_hand_sim.sim_objects import OBJECTS, pinch_ball_variant
from prisma_policy.bc_policy import Policy
from prisma_policy.sim_trials import (
    CLOSED_N,
    TOUCH_LIMIT_N,
    TOUCH_TOLERANCE_N,
    TrialResult,
    policy_trial,
    table,
    unseen_balls,
)
from prisma_testing.repo_paths import ROOT

SHOWN = {"index_contact_rad": [2.8, 3.2], "thumb_contact_rad": [2.3, 2.7], "stiffness_n_per_mm": [0.3, 0.5]}


def test_unseen_balls_lie_outside_every_shown_range():
    balls = unseen_balls(SHOWN, 6, seed=3)
    assert len(balls) == 6
    for number, ball in enumerate(balls):
        values = (ball.finger_contact_rad["index"], ball.thumb_contact_rad, ball.stiffness_n_per_mm)
        for value, (low, high) in zip(values, SHOWN.values()):
            assert (value > high) if number % 2 == 0 else (value < low), (number, value)
    assert [b.name for b in unseen_balls(SHOWN, 6, seed=3)] == [b.name for b in balls]  # seeded
    # without ranges: around the sim hand's own pinch ball
    plain = unseen_balls({}, 2, seed=0)
    assert plain[0].finger_contact_rad["index"] > OBJECTS["pinch_ball"].finger_contact_rad["index"] + 0.09
    assert plain[1].thumb_contact_rad < OBJECTS["pinch_ball"].thumb_contact_rad - 0.09


def result(thumb, index, other=0.0, period_s=0.01):
    forces = np.zeros((len(thumb), len(FINGERS)))
    forces[:, FINGERS.index("thumb")], forces[:, FINGERS.index("index")] = thumb, index
    forces[:, FINGERS.index("ring")] = other
    stamps = np.arange(len(thumb)) * period_s
    return TrialResult("policy", OBJECTS["pinch_ball"], stamps, forces, np.zeros((len(thumb), 3)), "")


def test_closed_needs_both_pads_for_half_a_second():
    assert result([1.0] * 50, [1.0] * 50).closed  # 0.5 s at 100 Hz
    assert not result([1.0] * 49, [1.0] * 49).closed
    assert not result([1.0] * 100, [CLOSED_N - 0.01] * 100).closed  # the index never pressed enough
    interrupted = [1.0] * 30 + [0.0] + [1.0] * 30
    assert not result(interrupted, interrupted).closed


def test_within_the_limit_is_any_pads_peak():
    assert result([1.0] * 60, [TOUCH_LIMIT_N + TOUCH_TOLERANCE_N] * 60).within_limit
    over = result([1.0] * 60, [1.0] * 60, other=TOUCH_LIMIT_N + TOUCH_TOLERANCE_N + 0.01)
    assert not over.within_limit and over.peak_force_n == pytest.approx(2.16)


def fist_policy(targets=(8.0, 6.5, 0.0)) -> Policy:
    """A network of zeros: it always asks for `targets` (the action mean), past every ball."""
    network = torch.nn.Sequential(torch.nn.Linear(81, 3))
    torch.nn.init.zeros_(network[0].weight)
    torch.nn.init.zeros_(network[0].bias)
    return Policy(network, np.zeros(81), np.ones(81), np.asarray(targets), np.ones(3), 0, 50)


def test_the_touch_limit_holds_a_policy_that_asks_for_a_fist():
    estimator = load_estimator(ROOT / "config" / "models" / "cnn2", threads=1)
    ball = pinch_ball_variant(2.9, 2.4, 0.4)
    trial = policy_trial(fist_policy(), ball, estimator, duration_s=3.0)
    assert trial.reason == ""  # the goal runs on: the targets keep coming
    assert trial.closed and trial.within_limit
    thumb, index = trial.forces_true[:, FINGERS.index("thumb")], trial.forces_true[:, FINGERS.index("index")]
    assert 1.7 < index[-1] <= TOUCH_LIMIT_N + TOUCH_TOLERANCE_N and 1.7 < thumb[-1] <= 2.15
    # the motors stand where the touch limit held them, short of the targets (8 and 6.5 rad)
    assert 8.0 - trial.positions[-1, 0] > 0.5 and 6.5 - trial.positions[-1, 1] > 0.1, trial.positions[-1]
    assert "| 0 | index 2.90 / thumb 2.40 rad, 0.40 N/mm | yes |" in table([(trial, trial)])
