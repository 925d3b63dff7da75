"""The objects the simulated hand can be given (`sim_object:=`): how each is presented, how stiff it
is, when its support lets go and its shape for a display. `HandWorld` takes one by name or as
`ObjectParams`.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace


@dataclass(frozen=True)
class ObjectParams:
    name: str
    # motor angle (rad) at which each pad first touches the object in its presented pose;
    # a finger absent from the map, or the thumb at None, never touches it
    finger_contact_rad: Mapping[str, float]
    thumb_contact_rad: float | None
    stiffness_n_per_mm: float  # object compliance (foam ball ~0.4)
    fixture_n_per_mm: float = 1.0  # support presenting the object
    release_force_n: float | None = None  # support lets go once thumb and partner press this hard...
    release_hold_s: float = 0.5  # ...for this long,
    release_tau_s: float = 0.2  # fading with this time constant,
    residual_fixture_n_per_mm: float = 0.01  # down to this (keeps the balance well posed)
    released: bool = False  # start already released (object held by the hand alone)
    # its shape for a display: "sphere" (size = its diameter three times) or "box" (size x, y along
    # the thumb pad's x and y, z along the grasp axis); "" = no object
    shape: str = "sphere"
    size_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)


OBJECTS: dict[str, ObjectParams] = {
    # 30 mm foam ball, thumb-index tip pinch; the experimenter lets go once the pinch holds it
    "pinch_ball": ObjectParams("pinch_ball", {"index": 3.0}, 2.5, 0.4, release_force_n=0.6, size_mm=(30.0,) * 3),
    # 70 mm foam ball touched by all four fingers
    "power_ball": ObjectParams("power_ball", {"index": 2.6, "middle": 2.5, "ring": 2.7, "little": 2.9},
                               2.0, 0.4, fixture_n_per_mm=2.0, size_mm=(70.0,) * 3),
    # card pressed by the thumb pad against the side of the flexed index (no sensor there: the
    # index side acts as a stiff support); an ID-1 card (ISO/IEC 7810), 85.60 x 53.98 x 0.76 mm
    "lateral_card": ObjectParams("lateral_card", {}, 3.5, 2.0, fixture_n_per_mm=5.0, shape="box",
                                 size_mm=(85.60, 53.98, 0.76)),
    # an empty hand: no pad ever touches anything (a gripper closing on nothing)
    "none": ObjectParams("none", {}, None, 0.4, shape=""),
}


def released(obj: ObjectParams | str) -> ObjectParams:
    """The object already held by the hand alone (manipulation scenarios start from a pinch)."""
    base = OBJECTS[obj] if isinstance(obj, str) else obj
    return replace(base, released=True)


def pinch_ball_variant(index_contact_rad: float, thumb_contact_rad: float, stiffness_n_per_mm: float) -> ObjectParams:
    """The pinch ball presented elsewhere or of another size (the motor angles at which the index and
    the thumb pad first touch it: a larger or nearer ball is touched earlier) and stiffness: the
    objects prisma-sim's demonstrations and prisma-policy's trials vary."""
    return replace(OBJECTS["pinch_ball"],
                   name=f"pinch_ball(index {index_contact_rad:.2f} rad, thumb {thumb_contact_rad:.2f} rad, "
                        f"{stiffness_n_per_mm:.2f} N/mm)",
                   finger_contact_rad={"index": index_contact_rad}, thumb_contact_rad=thumb_contact_rad,
                   stiffness_n_per_mm=stiffness_n_per_mm)
