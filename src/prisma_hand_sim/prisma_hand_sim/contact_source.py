"""Contact sources: who decides what touches each fingertip pad in simulation.

The sim backend asks a ContactSource for every finger at every sample stamp. The scripted source
makes the node publish meaningful data on its own; `HandWorldContactSource` takes the contacts from
the hand/world model (`hand_world`), fed with the motors' /joint_states.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from prisma_common.hand import FINGERS, check_finger

from .hand_world import HandWorld
from .pad_model import PadContact


@runtime_checkable
class ContactSource(Protocol):
    def contact(self, finger: str, stamp_ns: int) -> PadContact | None:
        """What touches `finger`'s pad at `stamp_ns` (None = nothing)."""
        ...


def _smoothstep(u: float) -> float:
    u = min(max(u, 0.0), 1.0)
    return u * u * (3.0 - 2.0 * u)


@dataclass
class ScriptedContactSource:
    """A repeating press -> slide -> roll -> release cycle, a pure function of the stamp.

    Phases of one `period_s` cycle (seconds from the start of the cycle):
      [0, 1)      no contact
      [1, 2)      press at the pad centre up to `normal_n`
      [2, 3.5)    slide toward the left side to x = +`travel_mm`, shear = friction * normal along the
                  direction of travel (the object drags the cap with it)
      [3.5, 5.5)  roll on a half circle through the top to x = -`travel_mm`, small rolling shear
      [5.5, 6.5)  release at the right side
      [6.5, period_s) no contact
    Each finger runs `finger_phase_s` later than the previous one so the five pads differ.
    """

    period_s: float = 8.0
    normal_n: float = 2.0
    friction: float = 0.4
    travel_mm: float = 5.0
    rolling_resistance: float = 0.05
    finger_phase_s: float = 0.4

    def __post_init__(self) -> None:
        if self.period_s < 6.5:
            raise ValueError(f"period_s must be >= 6.5 s to fit the cycle, got {self.period_s}")
        if self.normal_n <= 0:
            raise ValueError(f"normal_n must be > 0, got {self.normal_n}")

    def contact(self, finger: str, stamp_ns: int) -> PadContact | None:
        check_finger(finger)
        t = (stamp_ns * 1e-9 - FINGERS.index(finger) * self.finger_phase_s) % self.period_s
        n, r = self.normal_n, self.travel_mm
        if t < 1.0 or t >= 6.5:
            return None
        if t < 2.0:
            return PadContact(0.0, 0.0, n * _smoothstep(t - 1.0))
        if t < 3.5:
            u = (t - 2.0) / 1.5
            # shear builds up over the first fifth (stick, then slip)
            return PadContact(r * _smoothstep(u), 0.0, n, self.friction * n * _smoothstep(5.0 * u), 0.0)
        if t < 5.5:
            angle = math.pi * _smoothstep((t - 3.5) / 2.0)
            x, y = r * math.cos(angle), r * math.sin(angle)
            # direction of travel along the arc (tangent), rolling resistance along it
            tx, ty = -math.sin(angle), math.cos(angle)
            f = self.rolling_resistance * n
            return PadContact(x, y, n, f * tx, f * ty)
        return PadContact(-r, 0.0, n * (1.0 - _smoothstep(t - 5.5)))


class HandWorldContactSource:
    """ContactSource for the tactile driver's sim backend (contracts: constructed with no arguments,
    fed with /joint_states through `update_joints`)."""

    def __init__(self, world: HandWorld | None = None) -> None:
        self.world = world or HandWorld()
        self._last_ns: int | None = None

    def update_joints(self, names: list[str], positions: list[float], stamp_ns: int) -> bool:
        """Take a /joint_states sample; False (nothing changes) for one that is not the hand's.

        Other publishers share /joint_states (an arm driver, joint_state_publisher, a message with
        names but no positions): their samples must neither move the world nor set its time.
        """
        if len(names) != len(positions) or not set(names) & set(self.world.positions):
            return False
        self.world.update_joints(dict(zip(names, positions)), stamp_ns)
        self._last_ns = stamp_ns
        return True

    def contact(self, finger: str, stamp_ns: int) -> PadContact | None:
        if self._last_ns is None or stamp_ns > self._last_ns:
            self.world.advance(stamp_ns)  # disturbances and the support release keep time
            self._last_ns = stamp_ns
        return self.world.contact(finger)

