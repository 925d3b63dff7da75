"""The hand's description as data: joints, mimic couplings and forward kinematics of a URDF (the
text robot_state_publisher publishes on robot_description), without ROS.

Joint positions follow robot_state_publisher (Jazzy, 3.3): a mimic joint is at multiplier x its
joint + offset unless the positions given name it, in which case the given value wins.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

MOVING = ("revolute", "continuous", "prismatic")


class DescriptionError(ValueError):
    """A robot description that cannot be read (the message names what is wrong)."""


@dataclass(frozen=True)
class Mimic:
    joint: str
    multiplier: float
    offset: float


@dataclass(frozen=True)
class Joint:
    name: str
    type: str
    parent: str
    child: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    axis: tuple[float, float, float]
    mimic: Mimic | None


def _floats(text: str | None, default: tuple[float, float, float], what: str) -> tuple[float, float, float]:
    if text is None:
        return default
    try:
        x, y, z = (float(v) for v in text.split())
    except ValueError:
        raise DescriptionError(f"{what}: {text!r} is not three numbers") from None
    return (x, y, z)


def rpy_matrix(rpy: tuple[float, float, float]) -> np.ndarray:
    """URDF's fixed-axis roll, pitch, yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def axis_rotation(axis: tuple[float, float, float], angle: float) -> np.ndarray:
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def quaternion(rotation: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation matrix (Shepperd's method: stable for every rotation)."""
    m = rotation
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(1.0 + trace)
        return ((m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s)
    i = int(np.argmax(np.diag(m)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * math.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
    q = [0.0, 0.0, 0.0, 0.0]
    q[i] = 0.25 * s
    q[j] = (m[j, i] + m[i, j]) / s
    q[k] = (m[k, i] + m[i, k]) / s
    q[3] = (m[k, j] - m[j, k]) / s
    return (q[0], q[1], q[2], q[3])


class RobotModel:
    """The joints of a URDF, its root link and the chain of joints above each link."""

    def __init__(self, joints: list[Joint]) -> None:
        self.joints = {j.name: j for j in joints}
        self._parent_joint = {j.child: j for j in joints}
        children = set(self._parent_joint)
        roots = {j.parent for j in joints} - children
        if len(roots) != 1:
            raise DescriptionError(f"the description has {len(roots)} root links ({sorted(roots)}), not one")
        self.root = roots.pop()

    @classmethod
    def from_urdf(cls, text: str) -> RobotModel:
        try:
            robot = ET.fromstring(text)
        except ET.ParseError as exc:
            raise DescriptionError(f"the robot description is not XML ({exc})") from None
        joints = []
        for element in robot.iter("joint"):
            name = element.get("name", "")
            parent, child = element.find("parent"), element.find("child")
            if parent is None or child is None:
                raise DescriptionError(f"joint {name!r} has no parent or child link")
            origin, axis, mimic = element.find("origin"), element.find("axis"), element.find("mimic")
            joints.append(Joint(
                name, element.get("type", ""), parent.get("link", ""), child.get("link", ""),
                _floats(None if origin is None else origin.get("xyz"), (0.0, 0.0, 0.0), f"joint {name} origin xyz"),
                _floats(None if origin is None else origin.get("rpy"), (0.0, 0.0, 0.0), f"joint {name} origin rpy"),
                _floats(None if axis is None else axis.get("xyz"), (1.0, 0.0, 0.0), f"joint {name} axis"),
                None if mimic is None else Mimic(mimic.get("joint", ""), float(mimic.get("multiplier", "1")),
                                                 float(mimic.get("offset", "0")))))
        return cls(joints)

    def chain(self, link: str) -> list[Joint]:
        """The joints from the root down to `link`, root first."""
        if link != self.root and link not in self._parent_joint:
            raise DescriptionError(f"the description has no link {link!r}")
        out = []
        while link in self._parent_joint:
            joint = self._parent_joint[link]
            out.append(joint)
            link = joint.parent
        return out[::-1]

    def joint_positions(self, given: Mapping[str, float]) -> dict[str, float]:
        """Every moving joint whose position follows from `given`: given ones as they are, mimic
        joints not given at multiplier x their joint + offset (robot_state_publisher's rule)."""
        positions = dict(given)
        for joint in self.joints.values():
            if joint.mimic is not None and joint.name not in positions and joint.mimic.joint in given:
                positions[joint.name] = joint.mimic.multiplier * given[joint.mimic.joint] + joint.mimic.offset
        return positions

    def link_pose(self, link: str, given: Mapping[str, float]) -> np.ndarray:
        """4x4 pose of `link` in the root link's frame; a moving joint without a position is at 0."""
        positions = self.joint_positions(given)
        pose = np.eye(4)
        for joint in self.chain(link):
            step = np.eye(4)
            step[:3, :3] = rpy_matrix(joint.rpy)
            step[:3, 3] = joint.xyz
            q = positions.get(joint.name, 0.0)
            if joint.type in ("revolute", "continuous"):
                motion = np.eye(4)
                motion[:3, :3] = axis_rotation(joint.axis, q)
                step = step @ motion
            elif joint.type == "prismatic":
                motion = np.eye(4)
                motion[:3, 3] = np.asarray(joint.axis) / np.linalg.norm(joint.axis) * q
                step = step @ motion
            pose = pose @ step
        return pose
