"""Tactile marker data -> visualization_msgs/MarkerArray.

Every marker of a pad has namespace = the finger and the pad's frame, `frame_locked` with stamp 0:
RViz places it on the newest transform of that frame each frame it draws, so a moving finger keeps
its markers and a marker is never refused for a transform newer or older than its sample. The
sample's stamp is not lost: `taxel_decisions` reads it back from the cells marker's text.
ids: 0 taxel cells (CUBE_LIST, one colour per taxel), 1 contact point (SPHERE), 2 normal force
(ARROW), 3 force label (TEXT_VIEW_FACING). Without a contact, 1-3 are deleted.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from .node_config import TactileMarkersConfig
from .tactile_markers_core import PadDrawing

Types = Callable[[str], Any]
CELLS, CONTACT, FORCE, LABEL = 0, 1, 2, 3
ADD, DELETE = 0, 2  # visualization_msgs/Marker actions
CUBE_LIST, SPHERE, ARROW, TEXT = 6, 2, 0, 9  # visualization_msgs/Marker types
CONTACT_COLOUR = (1.0, 1.0, 1.0, 1.0)
FORCE_COLOUR = (0.1, 0.9, 0.2, 1.0)


def _marker(types: Types, drawing: PadDrawing, marker_id: int, kind: int, action: int = ADD, **fields: Any) -> Any:
    header = types("std_msgs/msg/Header")(stamp=types("builtin_interfaces/msg/Time")(sec=0, nanosec=0),
                                          frame_id=drawing.frame_id)
    return types("visualization_msgs/msg/Marker")(header=header, ns=drawing.finger, id=marker_id, type=kind,
                                                  action=action, frame_locked=True, **fields)


def _point(types: Types, xyz: Sequence[float]) -> Any:
    return types("geometry_msgs/msg/Point")(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]))


def _colour(types: Types, rgba: Sequence[float]) -> Any:
    return types("std_msgs/msg/ColorRGBA")(r=float(rgba[0]), g=float(rgba[1]), b=float(rgba[2]), a=float(rgba[3]))


def _scale(types: Types, x: float, y: float, z: float) -> Any:
    return types("geometry_msgs/msg/Vector3")(x=float(x), y=float(y), z=float(z))


def _pose(types: Types, xyz: Sequence[float] = (0.0, 0.0, 0.0)) -> Any:
    """A pose at xyz with the pad frame's orientation."""
    identity = types("geometry_msgs/msg/Quaternion")(x=0.0, y=0.0, z=0.0, w=1.0)
    return types("geometry_msgs/msg/Pose")(position=_point(types, xyz), orientation=identity)


def pad_markers(types: Types, drawing: PadDrawing, config: TactileMarkersConfig) -> list[Any]:
    """The markers of one pad (cells, and contact, force and label or their deletion)."""
    cell = config.taxel_pitch * 0.9
    decisions = "".join("1" if s else "0" for s in drawing.safe)
    markers = [_marker(types, drawing, CELLS, CUBE_LIST, pose=_pose(types),
                       scale=_scale(types, cell, cell, config.cell_thickness),
                       color=_colour(types, drawing.cell_colours[0]),
                       points=[_point(types, p) for p in drawing.cell_centres],
                       colors=[_colour(types, c) for c in drawing.cell_colours],
                       text=f"{drawing.stamp_ns} {decisions}")]
    arrow = drawing.arrow(config.arrow_m_per_n, config.arrow_max_length)
    if drawing.contact is None or arrow is None or drawing.normal_force_n is None:
        return markers + [_marker(types, drawing, i, kind, DELETE)
                          for i, kind in ((CONTACT, SPHERE), (FORCE, ARROW), (LABEL, TEXT))]
    x, y, z = drawing.contact
    dot = config.taxel_pitch * 0.6
    shaft = config.taxel_pitch * 0.5
    above = arrow[0]
    return markers + [
        _marker(types, drawing, CONTACT, SPHERE, pose=_pose(types, (x, y, z + config.cell_thickness)),
                scale=_scale(types, dot, dot, dot), color=_colour(types, CONTACT_COLOUR)),
        _marker(types, drawing, FORCE, ARROW, pose=_pose(types), points=[_point(types, p) for p in arrow],
                scale=_scale(types, shaft, 2 * shaft, 2 * shaft), color=_colour(types, FORCE_COLOUR)),
        _marker(types, drawing, LABEL, TEXT, pose=_pose(types, (above[0], above[1], above[2] + 0.004)),
                scale=_scale(types, 0.0, 0.0, 0.005), color=_colour(types, FORCE_COLOUR),
                text=f"{drawing.normal_force_n:.2f} N"),
    ]


def tactile_markers_to_msg(types: Types, drawings: Sequence[PadDrawing], config: TactileMarkersConfig) -> Any:
    return types("visualization_msgs/msg/MarkerArray")(
        markers=[m for drawing in drawings for m in pad_markers(types, drawing, config)])


def taxel_decisions(msg: Any) -> dict[str, tuple[int, tuple[bool, ...]]]:
    """finger -> (sample stamp, per-taxel safe decision) carried by a MarkerArray's cell markers."""
    found = {}
    for marker in msg.markers:
        if marker.id == CELLS and marker.action == ADD:
            stamp, decisions = marker.text.split()
            found[marker.ns] = (int(stamp), tuple(c == "1" for c in decisions))
    return found
