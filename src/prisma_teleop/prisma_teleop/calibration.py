"""One operator's calibration of a hand-pose glove: the joint angles of four captured poses, the
normalisation retargeting reads them through, and their YAML file.

The four poses (each a snapshot of every joint, captured by the teleop node's services):
- `open_hand`: the hand flat and open, the thumb resting beside it -> every flexion 0, opposition 0;
- `fist`: a closed fist -> every flexion 1;
- `thumb_adducted`, `thumb_opposed`: the thumb's two extremes of abduction/opposition, pressed
  against the index and swung across the palm -> opposition -1 and +1.
A flexion joint is normalised linearly from its open-hand to its fist angle, an opposition joint
piecewise linearly through adducted (-1), open hand (0) and opposed (+1), both clipped to their
range: monotone in the joint angle, and exactly 0 and 1 (or -1, 0, +1) at the captured poses.
Whichever way a glove counts its angles, the captures fix the direction.

The file (`save_calibration`, `load_calibration`) is written whole or not at all (staged and
renamed, prisma_common.atomic); a file that cannot be read or holds a bad value raises
`CalibrationError` naming the file, the entry and the value, and what to do (fix or delete it);
`unwritable` says at start why a file could not be written.
"""
from __future__ import annotations

import math
import tempfile
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import yaml

from prisma_common.atomic import atomic_output
from prisma_common.hand_config import default_writer, now_iso
from prisma_common.os_errors import describe_os_error

FORMAT = "prisma_teleop_calibration"
VERSION = 1
POSES = ("open_hand", "fist", "thumb_adducted", "thumb_opposed")
# Two captured angles closer than this cannot be told apart on a glove (sensor noise of a few
# hundredths of a radian): the normalisation would amplify that noise to the whole motor range.
MIN_SPAN_RAD = 0.1


class CalibrationError(ValueError):
    """A calibration that cannot be used: the message names the file or the pose, the joint and the value."""


@dataclass(frozen=True)
class OperatorCalibration:
    """Joint name -> angle (rad) of each captured pose."""

    open_hand: dict[str, float] = field(default_factory=dict)
    fist: dict[str, float] = field(default_factory=dict)
    thumb_adducted: dict[str, float] = field(default_factory=dict)
    thumb_opposed: dict[str, float] = field(default_factory=dict)
    operator: str = ""

    def pose(self, name: str) -> dict[str, float]:
        if name not in POSES:
            raise ValueError(f"unknown calibration pose {name!r}; expected one of {POSES}")
        return getattr(self, name)

    def with_pose(self, name: str, angles: Mapping[str, float]) -> OperatorCalibration:
        """A copy with pose `name` replaced by the joint angles `angles` (a capture)."""
        self.pose(name)
        changes: dict[str, Any] = {name: {str(k): float(v) for k, v in angles.items()}}
        return replace(self, **changes)

    def flexion(self, joint: str, angle: float) -> float:
        """0 at the open hand, 1 at the fist, linear between and clipped."""
        lo, hi = self.open_hand[joint], self.fist[joint]
        return min(1.0, max(0.0, (angle - lo) / (hi - lo)))

    def opposition(self, joint: str, angle: float) -> float:
        """-1 thumb adducted, 0 open hand, +1 thumb opposed, piecewise linear between and clipped
        (the extremes lie on either side of the open hand: `check`)."""
        centre = self.open_hand[joint]
        toward_opposed = (angle - centre) / (self.thumb_opposed[joint] - centre)
        if toward_opposed >= 0.0:
            return min(1.0, toward_opposed)
        return -min(1.0, (angle - centre) / (self.thumb_adducted[joint] - centre))

    def check(self, flexion_joints: Iterable[str], opposition_joints: Iterable[str]) -> None:
        """CalibrationError naming the pose, the joint and the angles unless every flexion joint has
        an open-hand and a fist angle at least MIN_SPAN_RAD apart, and every opposition joint has its
        two thumb extremes on either side of the open hand, each at least MIN_SPAN_RAD from it."""
        for joint in flexion_joints:
            lo, hi = self._angle("open_hand", joint), self._angle("fist", joint)
            if abs(hi - lo) < MIN_SPAN_RAD:
                raise CalibrationError(f"{joint}: fist {hi:.3f} rad and open hand {lo:.3f} rad are less than "
                                       f"{MIN_SPAN_RAD} rad apart; capture the open hand and the fist again")
        for joint in opposition_joints:
            centre = self._angle("open_hand", joint)
            low, high = self._angle("thumb_adducted", joint), self._angle("thumb_opposed", joint)
            if not (abs(low - centre) >= MIN_SPAN_RAD and abs(high - centre) >= MIN_SPAN_RAD
                    and (low - centre) * (high - centre) < 0):
                raise CalibrationError(
                    f"{joint}: thumb adducted {low:.3f} rad and opposed {high:.3f} rad must lie on either side of "
                    f"the open hand's {centre:.3f} rad, each at least {MIN_SPAN_RAD} rad from it; capture the thumb's "
                    "extremes again")

    def _angle(self, pose: str, joint: str) -> float:
        value = self.pose(pose).get(joint)
        if value is None:
            raise CalibrationError(f"{joint}: not in the captured {pose.replace('_', ' ')} "
                                   f"(the glove did not report it); capture the {pose.replace('_', ' ')} again")
        if not math.isfinite(value):
            raise CalibrationError(f"{joint}: {pose.replace('_', ' ')} angle {value} is not finite")
        return value


# --------------------------------------------------------------------------------------- the file
def calibration_document(calibration: OperatorCalibration) -> dict[str, Any]:
    """What the YAML file holds."""
    document: dict[str, Any] = {"format": FORMAT, "version": VERSION, "operator": calibration.operator,
                                "written_by": default_writer(), "written_at": now_iso()}
    for pose in POSES:
        document[pose] = {joint: float(angle) for joint, angle in calibration.pose(pose).items()}
    return document


def save_calibration(calibration: OperatorCalibration, path: str | Path) -> Path:
    """Write the calibration to `path`, whole or not at all; CalibrationError naming the path when it
    cannot be written (the old file, if any, is left as it was)."""
    target = Path(path).expanduser()
    text = ("# prisma_teleop: one operator's hand-pose glove calibration (rad), written by the teleop node's\n"
            "# ~/capture_* services; docs: docs/teleoperation.md, 'Calibration'\n"
            + yaml.safe_dump(calibration_document(calibration), sort_keys=False, default_flow_style=False, width=120))
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with atomic_output(target) as staged:
            staged.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise CalibrationError(f"{target}: cannot write the calibration ({describe_os_error(exc)}); "
                               "choose a writable calibration_file") from None
    return target


def load_calibration(path: str | Path) -> OperatorCalibration:
    """The calibration in `path`; CalibrationError naming the file and the bad entry."""
    path = Path(path).expanduser()
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = describe_os_error(exc) if isinstance(exc, OSError) else str(exc)
        raise CalibrationError(f"{path}: cannot read the calibration ({reason}); give an existing "
                               "calibration_file or \"\" for the default calibration") from None
    try:
        document = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        where = getattr(exc, "problem_mark", None)
        line = f" at line {where.line + 1}" if where is not None else ""
        raise _bad_file(path, f"not valid YAML{line}") from None
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise _bad_file(path, f"not a {FORMAT} file (no 'format: {FORMAT}')")
    if document.get("version") != VERSION:
        raise _bad_file(path, f"version {document.get('version')!r}, this program reads version {VERSION}")
    poses = {pose: _angles(path, pose, document.get(pose)) for pose in POSES}
    operator = document.get("operator", "")
    return OperatorCalibration(**poses, operator="" if operator is None else str(operator))


def _bad_file(path: Path, what: str) -> CalibrationError:
    """A file that cannot be used, with what to do: the node that read it has exited, so the remedy is
    the file (or another one), not a capture."""
    return CalibrationError(f"{path}: {what}; fix or delete {path} (without it the teleop node starts with the "
                            "nominal hand, and the ~/capture_* services write it anew), or give another "
                            "calibration_file")


def _angles(path: Path, pose: str, value: Any) -> dict[str, float]:
    if not isinstance(value, dict) or not value:
        raise _bad_file(path, f"'{pose}' must map joint names to angles in rad, got {value!r}")
    angles = {}
    for joint, angle in value.items():
        if isinstance(angle, bool) or not isinstance(angle, (int, float)) or not math.isfinite(angle):
            raise _bad_file(path, f"{pose}.{joint} = {angle!r} is not a finite angle in rad")
        angles[str(joint)] = float(angle)
    return angles


def unwritable(path: str | Path) -> str | None:
    """None when `save_calibration` could write `path` (its directory, or the nearest one that exists
    and would hold the new ones, takes a new file), else why not: for the node to say at start, not
    at the operator's last capture."""
    target = Path(path).expanduser()
    if target.is_dir():
        return f"{target} is a directory"
    folder = target.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        return f"{folder} is not a directory"
    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".prisma_teleop_probe_"):
            pass
    except OSError as exc:
        return f"cannot create a file in {folder} ({describe_os_error(exc)})"
    return None
