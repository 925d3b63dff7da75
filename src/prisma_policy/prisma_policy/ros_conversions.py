"""The policy node's messages: the ones it shares with the teleop node and the hand's drivers are
their packages' converters (imported here so the node has one place to take them from); new is only
the Teleoperate goal it sends, the teleop node's default goal."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from prisma_force_estimator.ros_conversions import hand_wrench_samples, wrench_from_msg
from prisma_manipulation.ros_conversions import joint_sample_from_msg
from prisma_tactile_driver.ros_conversions import hand_taxels_samples, taxel_frame_from_msg
from prisma_teleop.node_config import TeleopConfig
from prisma_teleop.ros_conversions import motor_targets_to_msg, teleoperate_goal_to_msg
from prisma_teleop.teleop_core import TeleopGoal

__all__ = ["hand_taxels_samples", "hand_wrench_samples", "joint_sample_from_msg", "motor_targets_to_msg",
           "policy_goal_to_msg", "taxel_frame_from_msg", "wrench_from_msg"]


def policy_goal_to_msg(types: Callable[[str], Any]) -> Any:
    """The Teleoperate goal with the teleop node's defaults (0 = the manipulation node's touch limit,
    speed and input timeout), so the policy is held to the same limits as an operator."""
    return teleoperate_goal_to_msg(types, TeleopGoal.of(TeleopConfig()))
