"""Forward kinematics of a URDF parsed by urdf_parser_py, mimic joints included: what
robot_state_publisher computes, for tests that check the hand's frames against its coupling."""
from __future__ import annotations

from typing import Any

import numpy as np


def rpy_matrix(rpy: Any) -> np.ndarray:
    """URDF's fixed-axis roll, pitch, yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def axis_rotation(axis: Any, angle: float) -> np.ndarray:
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def joint_positions(robot: Any, motors: dict[str, float]) -> dict[str, float]:
    """Every moving joint's position from the independent ones: a mimic joint is at
    multiplier * its joint + offset, unless `motors` names it (robot_state_publisher's rule: a
    joint given in the message wins)."""
    positions = dict(motors)
    for joint in robot.joints:
        if joint.mimic is not None and joint.name not in motors:
            positions[joint.name] = joint.mimic.multiplier * motors[joint.mimic.joint] + (joint.mimic.offset or 0.0)
    return positions


def link_poses(robot: Any, motors: dict[str, float]) -> dict[str, np.ndarray]:
    """4x4 pose of every link in the root link's frame, the independent joints at `motors`."""
    positions = joint_positions(robot, motors)
    poses = {robot.get_root(): np.eye(4)}
    pending = [robot.get_root()]
    while pending:
        parent = pending.pop()
        for joint in (j for j in robot.joints if j.parent == parent):
            step = np.eye(4)
            if joint.origin is not None:
                step[:3, :3] = rpy_matrix(joint.origin.rpy or [0.0, 0.0, 0.0])
                step[:3, 3] = joint.origin.xyz or [0.0, 0.0, 0.0]
            if joint.type in ("revolute", "continuous"):
                motion = np.eye(4)
                motion[:3, :3] = axis_rotation(joint.axis, positions[joint.name])
                step = step @ motion
            poses[joint.child] = poses[parent] @ step
            pending.append(joint.child)
    return poses
