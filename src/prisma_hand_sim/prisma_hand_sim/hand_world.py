"""Hand/world model (docs/manipulation.md): motor positions -> fingertip contacts on a compliant object.

What it models, along the grasp axis z (fingers push +z, the thumb pushes -z):
- Tendon-coupled closure. Each finger pad's free position follows its motor, s = travel * angle
  (the fingers motor drives all four fingers, thumb_flexion the thumb). Until a pad touches the
  object it moves with the motor; after contact the elastic tendon stretches instead, so the pad
  stays on the object and the normal force grows with the closure beyond contact:
  F = k * (s - contact position), k = the series stiffness of tendon and object.
- A compliant ball (or card) between thumb and fingers (`sim_objects`). It is presented by a compliant support (the
  experimenter's hand or a stand, `fixture_n_per_mm`) that can let go once the hand holds the object.
  The object's position along z is the static balance of pad forces, support and external force.
- Contact location on every pad. Pads slide tangentially as they close (an arc: `*_slide_per_mm` of
  tangential motion per mm of pad travel) and thumb rotation moves the thumb pad sideways. When the
  thumb and the pinch partner (index) both touch, the object rolls between them without slipping:
  its centre moves by the mean of the two pads' tangential motions, so the contact point on the thumb
  pad moves by half their relative motion. Hence:
    * thumb rotation (clockwise, +) moves the contact toward the thumb pad's left side: the right
      side 6-3-0 empties first (horizontal scenario);
    * fingers closing while the thumb extends shifts both pads the same way along z but tangentially
      in opposite senses: the object rolls and the contact moves toward the bottom row, so the top
      row empties; the reverse motion empties the bottom row (vertical scenario);
    * an external push slips the object across the pads (disturbance scenario); rotating the thumb
      brings the contact back.
- External disturbances: timed pushes (tangential slip and/or a narrower grip width that lowers the
  grasp force).

Pad frames follow prisma_hand_sim.pad_model: +x toward the pad's LEFT side, +y toward the TOP
row. The finger pads face the thumb pad, so their x axis is mirrored with respect to the thumb's.
Shear is not modelled (rolling without slip carries little tangential force): PadContact shear = 0.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from prisma_common.hand import FINGERS, MOTOR_NAMES, check_finger

from .pad_model import PadContact, PadParams
from .sim_objects import OBJECTS, ObjectParams

FINGER_PADS = FINGERS[1:]  # index, middle, ring, little (driven by the "fingers" motor)
# the motor whose tendon closes each finger
TENDON_MOTOR: dict[str, str] = {"thumb": "thumb_flexion", **dict.fromkeys(FINGER_PADS, "fingers")}




@dataclass(frozen=True)
class HandWorldParams:
    finger_travel_mm_per_rad: float = 8.0  # pad free travel along z per rad of the fingers motor
    thumb_travel_mm_per_rad: float = 8.0  # equal to the fingers': equal speeds keep the grip width
    tendon_stiffness_n_per_mm: float = 0.08  # elastic tendon, referred to fingertip travel
    finger_slide_per_mm: float = 0.4  # finger pad tangential (-y) motion per mm of pad travel (arc)
    thumb_slide_per_mm: float = 0.4  # thumb pad tangential (-y) motion per mm of pad travel
    thumb_lateral_mm_per_rad: float = 6.0  # thumb pad sideways motion per rad of thumb rotation
    partner: str = "index"  # the finger the thumb pinches against (rolling pair)
    pad_half_size_mm: float = PadParams().pad_size_mm / 2.0  # contact beyond it has slipped off
    load_nm_per_n: float = 0.05  # motor load torque per N of pad force (tendon lever x spool)
    rotation_load_fraction: float = 0.2  # thumb rotation carries this share of the thumb load

    def pad_travel_mm_per_rad(self, finger: str) -> float:
        """Free travel of `finger`'s pad per rad of its tendon motor (TENDON_MOTOR)."""
        return self.thumb_travel_mm_per_rad if check_finger(finger) == "thumb" else self.finger_travel_mm_per_rad

    def series_stiffness(self, obj: ObjectParams) -> float:
        return 1.0 / (1.0 / self.tendon_stiffness_n_per_mm + 1.0 / obj.stiffness_n_per_mm)


@dataclass(frozen=True)
class ObjectPose:
    """Where the object is and how it is squeezed, for a display. Coordinates in mm in the thumb
    pad's frame where the object was presented (the thumb at the object's thumb_contact_rad,
    thumb_rotation 0): origin the point the thumb pad first touches, z out of the pad along the
    grasp axis (toward the fingers), x and y the pad's. `size_mm` is the object's, its z shortened
    by how far the pads press into it."""

    shape: str
    centre_mm: tuple[float, float, float]
    size_mm: tuple[float, float, float]


@dataclass(frozen=True)
class Disturbance:
    """An external push: over [start_s, start_s + duration_s] the object slips by (dx, dy) mm across
    the pads (hand frame = thumb pad frame) and the grip width at the pads changes by dwidth_mm
    (negative = the object slides to a narrower section and the grasp force drops)."""

    start_s: float
    duration_s: float
    dx_mm: float = 0.0
    dy_mm: float = 0.0
    dwidth_mm: float = 0.0

    def fraction(self, t_s: float) -> float:
        if t_s <= self.start_s:
            return 0.0
        if self.duration_s <= 0 or t_s >= self.start_s + self.duration_s:
            return 1.0
        u = (t_s - self.start_s) / self.duration_s
        return u * u * (3.0 - 2.0 * u)


@dataclass
class WorldState:
    stamp_ns: int
    # normal force each finger presses the object with, N (on its sensor pad or, once the object
    # has slipped off the pad, on the finger beside it): the grasp balance and the tendon loads
    finger_forces: dict[str, float]
    contacts: dict[str, PadContact | None]
    object_z_mm: float  # object displacement along the grasp axis (toward the thumb)
    object_xy_mm: tuple[float, float]  # object tangential position (hand frame)
    fixture_n_per_mm: float
    pad_positions_mm: dict[str, float] = field(default_factory=dict)  # actual pad travel along z

    @property
    def forces(self) -> dict[str, float]:
        """Normal force on each sensor pad, N: the finger's force while the object touches the pad,
        0 once it has slipped off (what the pad can measure)."""
        return {f: force if self.contacts.get(f) is not None else 0.0 for f, force in self.finger_forces.items()}


class HandWorld:
    def __init__(self, params: HandWorldParams | None = None, obj: ObjectParams | str = "pinch_ball",
                 disturbances: Sequence[Disturbance] = ()) -> None:
        self.params = params or HandWorldParams()
        self.obj = OBJECTS[obj] if isinstance(obj, str) else obj
        self.disturbances = list(disturbances)
        self.k = self.params.series_stiffness(self.obj)
        self.positions = {name: 0.0 for name in MOTOR_NAMES}
        self._stamp_ns: int | None = None
        self._origin_ns: int | None = None  # the first stamp moved to: disturbance times count from it
        self._applied = [0.0] * len(self.disturbances)
        self._pad_tangent: dict[str, tuple[float, float]] | None = None
        self._present_object()
        self.state = self._solve(0)
        self._pad_tangent = self._tangents(self.state)

    # ---- inputs ----------------------------------------------------------------------------
    def add_disturbance(self, disturbance: Disturbance) -> None:
        self.disturbances.append(disturbance)
        self._applied.append(0.0)

    def remove_disturbances(self) -> None:
        """No timed pushes (none applied yet: call it before the world moves)."""
        if any(self._applied):
            raise RuntimeError("remove_disturbances: a push is already under way; remove them before the world moves")
        self.disturbances.clear()
        self._applied.clear()

    def set_positions(self, positions: Mapping[str, float], centre_on_thumb: bool = True) -> None:
        """Place the motors without any motion history (the object neither rolls nor slips); with
        centre_on_thumb the object sits where it touches the middle of the thumb pad."""
        self.positions.update({k: float(v) for k, v in positions.items() if k in self.positions})
        state = self._solve(self.state.stamp_ns)
        if centre_on_thumb:
            self._bx, self._by = self._tangents(state)["thumb"]
            state = self._solve(self.state.stamp_ns)
        self.state = state
        self._pad_tangent = self._tangents(state)

    def replace_object(self) -> str:
        """Put the object back between the thumb and its partner, as an operator does between
        trials: unshifted, no width change, on its support again, where the thumb pad will touch it
        in the middle at the thumb's present rotation. The object's motion in the trials before
        (rolled off the pad by a manipulation, pushed by a disturbance) is gone; timed disturbances
        already applied stay applied. ValueError while a finger touches it (the hand opens first) or
        in an empty hand (object none: nothing to put back). Returns what was done, for a log."""
        if not self.obj.finger_contact_rad and self.obj.thumb_contact_rad is None:
            objects = [name for name, o in OBJECTS.items() if o.finger_contact_rad or o.thumb_contact_rad is not None]
            raise ValueError(f"no object to put back: the hand is empty (object {self.obj.name!r}); start it with "
                             f"one: sim_object:={'|'.join(objects)}")
        touching = sorted(f for f, force in self.state.finger_forces.items() if force > 0.0)
        if touching:
            raise ValueError(f"the object cannot be re-placed while {', '.join(touching)} touch it: "
                             "open the hand first (GripperCommand position 0)")
        self._present_object()
        self.state = self._solve(self.state.stamp_ns)
        self._pad_tangent = self._tangents(self.state)
        rotation = self.positions["thumb_rotation"]
        return f"{self.obj.name} re-placed at the thumb pad's middle (thumb rotation {rotation:+.3f} rad)"

    def _present_object(self) -> None:
        """The object as presented: no shift or width change, on its support (or already held by the
        hand alone when `released`), centred where the thumb pad at its present rotation touches."""
        self._bx = 0.0 - self.params.thumb_lateral_mm_per_rad * self.positions["thumb_rotation"]  # never -0.0
        self._by = 0.0
        self._width_mm = 0.0
        self._fixture = self.obj.residual_fixture_n_per_mm if self.obj.released else self.obj.fixture_n_per_mm
        self._held_since_ns: int | None = None
        self._released_ns: int | None = 0 if self.obj.released else None

    def elapsed_s(self, stamp_ns: int) -> float:
        """Seconds from the world's first stamp to stamp_ns: the time a Disturbance's start_s counts."""
        return 0.0 if self._origin_ns is None else (stamp_ns - self._origin_ns) * 1e-9

    def update_joints(self, positions: Mapping[str, float], stamp_ns: int) -> WorldState:
        """Move to new motor positions at stamp_ns; unknown names are ignored."""
        self.positions.update({k: float(v) for k, v in positions.items() if k in self.positions})
        return self.advance(stamp_ns)

    def advance(self, stamp_ns: int) -> WorldState:
        """Apply disturbances and the support release up to stamp_ns and re-solve the contacts.
        Disturbance times count from the first stamp the world is moved to (a clock need not start
        at 0)."""
        if self._origin_ns is None:
            self._origin_ns = stamp_ns
        t_s = (stamp_ns - self._origin_ns) * 1e-9
        for i, d in enumerate(self.disturbances):
            f = d.fraction(t_s)
            delta, self._applied[i] = f - self._applied[i], f
            if delta:
                self._bx += d.dx_mm * delta
                self._by += d.dy_mm * delta
                self._width_mm += d.dwidth_mm * delta
        self._update_fixture(stamp_ns)
        state = self._solve(stamp_ns)
        tangents = self._tangents(state)
        partner = self.params.partner
        before, now = self.state.finger_forces, state.finger_forces
        pinched_before = before["thumb"] > 0 and before.get(partner, 0.0) > 0
        pinched_now = now["thumb"] > 0 and now.get(partner, 0.0) > 0
        if pinched_before and pinched_now and self._pad_tangent:
            # rolling without slip between thumb and partner: the object moves by the mean motion
            (tx0, ty0), (px0, py0) = self._pad_tangent["thumb"], self._pad_tangent[partner]
            (tx1, ty1), (px1, py1) = tangents["thumb"], tangents[partner]
            self._bx += ((tx1 - tx0) + (px1 - px0)) / 2.0
            self._by += ((ty1 - ty0) + (py1 - py0)) / 2.0
            state = self._solve(stamp_ns)
        self._pad_tangent = tangents
        self.state = state
        self._stamp_ns = stamp_ns
        return state

    # ---- outputs ---------------------------------------------------------------------------
    def contact(self, finger: str) -> PadContact | None:
        return self.state.contacts[check_finger(finger)]

    def forces(self) -> dict[str, float]:
        return dict(self.state.forces)

    def motor_loads(self) -> dict[str, float]:
        p = self.params
        fingers = sum(self.state.finger_forces[f] for f in FINGER_PADS)
        thumb = self.state.finger_forces["thumb"]
        return {"fingers": fingers * p.load_nm_per_n, "thumb_flexion": thumb * p.load_nm_per_n,
                "thumb_rotation": thumb * p.load_nm_per_n * p.rotation_load_fraction}

    def object_pose(self) -> ObjectPose | None:
        """The object as a display draws it; None for an empty hand (shape "")."""
        o, s = self.obj, self.state
        if not o.shape:
            return None
        sx, sy, sz = o.size_mm
        # the thumb side of the object moves along z by -u (u is toward the thumb), each pad
        # pressing into it by force / object stiffness
        thumb_side = -s.object_z_mm + s.finger_forces["thumb"] / o.stiffness_n_per_mm
        finger_side = sz - s.object_z_mm - max(s.finger_forces[f] for f in FINGER_PADS) / o.stiffness_n_per_mm
        bx, by = s.object_xy_mm
        return ObjectPose(o.shape, (bx, by, (thumb_side + finger_side) / 2.0), (sx, sy, finger_side - thumb_side))

    def grasp_pose(self, force_n: float) -> dict[str, float]:
        """Motor positions of a balanced pinch (thumb vs partner) at force_n, object centred."""
        p = self.params
        partner = p.partner
        if self.obj.thumb_contact_rad is None or partner not in self.obj.finger_contact_rad:
            raise ValueError(f"object {self.obj.name!r} is not pinched between the thumb and the {partner}")
        travel = force_n / self.k
        return {
            "fingers": self.obj.finger_contact_rad[partner] + travel / p.finger_travel_mm_per_rad,
            "thumb_flexion": self.obj.thumb_contact_rad + travel / p.thumb_travel_mm_per_rad,
            "thumb_rotation": 0.0,
        }

    # ---- internals -------------------------------------------------------------------------
    def _update_fixture(self, stamp_ns: int) -> None:
        o = self.obj
        if self._released_ns is None and o.release_force_n is not None:
            f = self.state.finger_forces
            if f["thumb"] >= o.release_force_n and f.get(self.params.partner, 0.0) >= o.release_force_n:
                if self._held_since_ns is None:
                    self._held_since_ns = stamp_ns
                elif stamp_ns - self._held_since_ns >= o.release_hold_s * 1e9:
                    self._released_ns = stamp_ns
            else:
                self._held_since_ns = None
        if self._released_ns is not None and not o.released:
            fade = math.exp(-max(0, stamp_ns - self._released_ns) * 1e-9 / o.release_tau_s)
            self._fixture = o.residual_fixture_n_per_mm + (o.fixture_n_per_mm - o.residual_fixture_n_per_mm) * fade

    def _free_travel(self) -> tuple[dict[str, float], float]:
        p = self.params
        s_f = {f: p.pad_travel_mm_per_rad(f) * self.positions[TENDON_MOTOR[f]] for f in FINGER_PADS}
        return s_f, p.pad_travel_mm_per_rad("thumb") * self.positions[TENDON_MOTOR["thumb"]]

    def _contact_travel(self) -> tuple[dict[str, float], float | None]:
        """Pad travel at which each pad touches the object in its presented pose (width change
        moves both surfaces away by half of it); None for a thumb that never touches it."""
        p = self.params
        half = -self._width_mm / 2.0
        h_f = {f: p.finger_travel_mm_per_rad * a + half for f, a in self.obj.finger_contact_rad.items()}
        if self.obj.thumb_contact_rad is None:
            return h_f, None
        return h_f, p.thumb_travel_mm_per_rad * self.obj.thumb_contact_rad + half

    def _balance(self, s_f, h_f, s_t, h_t) -> float:
        """Object displacement u (toward the thumb) where pad forces and support balance.
        g(u) = sum_f k*max(0, s_f - h_f - u) - k*max(0, s_t - h_t + u) - fixture*u is piecewise
        linear and strictly decreasing: find its root exactly between breakpoints."""
        k, kfix = self.k, self._fixture

        def thumb(u: float) -> float:
            return 0.0 if h_t is None else k * max(0.0, s_t - h_t + u)

        def g(u: float) -> float:
            return sum(k * max(0.0, s_f[f] - h_f[f] - u) for f in h_f) - thumb(u) - kfix * u

        thumb_point = () if h_t is None else (h_t - s_t,)
        points = sorted({0.0, *thumb_point, *(s_f[f] - h_f[f] for f in h_f)})
        values = [g(u) for u in points]
        if values[0] <= 0.0:
            # left of every breakpoint all finger pads press and the thumb does not
            return points[0] + values[0] / (kfix + k * len(h_f))
        for (u0, g0), (u1, g1) in zip(zip(points, values), zip(points[1:], values[1:])):
            if g1 <= 0.0:
                return u0 + (u1 - u0) * g0 / (g0 - g1)
        # right of every breakpoint only the thumb presses
        return points[-1] + values[-1] / (kfix + k)

    def _solve(self, stamp_ns: int) -> WorldState:
        k = self.k
        s_f, s_t = self._free_travel()
        h_f, h_t = self._contact_travel()
        u = self._balance(s_f, h_f, s_t, h_t)
        forces = {f: 0.0 for f in FINGERS}
        pads = {}
        for f in FINGER_PADS:
            if f in h_f and s_f[f] > h_f[f] + u:
                forces[f] = k * (s_f[f] - h_f[f] - u)
                pads[f] = h_f[f] + u + forces[f] / self.obj.stiffness_n_per_mm  # indents the object
            else:
                pads[f] = s_f[f]
        if h_t is not None and s_t > h_t - u:
            forces["thumb"] = k * (s_t - h_t + u)
            pads["thumb"] = h_t - u + forces["thumb"] / self.obj.stiffness_n_per_mm
        else:
            pads["thumb"] = s_t
        state = WorldState(stamp_ns, forces, {}, u, (self._bx, self._by), self._fixture, pads)
        tangents = self._tangents(state)
        for f in FINGERS:
            state.contacts[f] = self._pad_contact(f, forces[f], tangents[f])
        return state

    def _tangents(self, state: WorldState) -> dict[str, tuple[float, float]]:
        """Tangential (x, y) position of each pad in the hand frame, relative to the pose where it
        first touches the object."""
        p = self.params
        h_f, h_t = self._contact_travel()
        out = {}
        for f in FINGER_PADS:
            ref = h_f.get(f, 0.0)
            out[f] = (0.0, -p.finger_slide_per_mm * (state.pad_positions_mm[f] - ref))
        out["thumb"] = (-p.thumb_lateral_mm_per_rad * self.positions["thumb_rotation"],
                        -p.thumb_slide_per_mm * (state.pad_positions_mm["thumb"] - (h_t or 0.0)))
        return out

    def _pad_contact(self, finger: str, force: float, tangent: tuple[float, float]) -> PadContact | None:
        if force <= 0.0:
            return None
        x_hand = self._bx - tangent[0]
        y = self._by - tangent[1]
        x = x_hand if finger == "thumb" else -x_hand  # finger pads face the thumb: mirrored x
        half = self.params.pad_half_size_mm
        if abs(x) > half or abs(y) > half:
            return None  # the object has slipped off the pad
        return PadContact(x, y, force)
