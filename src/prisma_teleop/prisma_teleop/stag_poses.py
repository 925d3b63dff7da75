"""The STAG glove's hand-pose classes -> the hand's grasps, with hysteresis, and the glove's pressure
-> the grasp force. ROS-free.

glove_perception publishes one hand-pose estimate (/stag/hand_pose: the class, its confidence) per
non-shorted glove frame; its classes are the pose bundle's labels (config/models/glove_pose):

| pose class | the hand |
|---|---|
| pinch, tripod | Grasp `pinch` (thumb against the index) |
| lateral | Grasp `lateral` (thumb against the side of the index) |
| power, spherical, hook | Grasp `power` (four fingers round the object) |
| empty | open: GripperCommand position 0 |
| point | nothing: the hand keeps what it does |

Hysteresis (`PoseMapper`): a class counts on a frame when it is the estimate with at least
`min_confidence`; it starts its command once it counted on `frames` frames in a row, and a different
class must do the same to change the command. A frame of another class or below the confidence
breaks the run, so a class flickering in for fewer than `frames` frames starts nothing. The empty
hand is also recognised by its pressure: a frame whose total pressure is below `empty_pressure`
counts as `empty` whatever the class (a hand holding nothing presses nothing).

Force: the total pressure of a frame (the sum of its sensors' normalised pressures, 0..1 each: what
/stag/frame carries), averaged over the run of frames that started the grasp, maps linearly from
`min_force` at `pressure_low` to `max_force` at `pressure_high` (clipped there) onto the grasp's
finger force; the thumb's is that times `thumb_force_ratio`. The synthetic glove's grasps press
~18 (pinch), ~32 (lateral), ~62 (power); its empty hand 1-3.
"""
from __future__ import annotations

from dataclasses import dataclass

EMPTY = "empty"
# pose class -> the grasp it starts (None: the hand opens); a class not here changes nothing
POSE_GRASPS: dict[str, str | None] = {
    "pinch": "pinch", "tripod": "pinch",
    "lateral": "lateral",
    "power": "power", "spherical": "power", "hook": "power",
    EMPTY: None,
}
IGNORED_POSES = ("point",)  # classes glove_perception knows that start nothing


@dataclass(frozen=True)
class GraspCommand:
    """A Grasp goal: the preset and its forces (N)."""

    grasp: str
    finger_force: float
    thumb_force: float
    pose: str  # the class that started it


@dataclass(frozen=True)
class OpenCommand:
    """GripperCommand position 0: the hand opens."""

    pose: str = EMPTY


StagCommand = GraspCommand | OpenCommand


@dataclass(frozen=True)
class PoseMapping:
    """The settings of `PoseMapper` (the module docstring says what each does)."""

    frames: int = 3
    min_confidence: float = 0.6
    empty_pressure: float = 4.0
    pressure_low: float = 5.0
    pressure_high: float = 65.0
    min_force: float = 0.4  # N
    max_force: float = 2.0  # N
    thumb_force_ratio: float = 1.25  # the manipulation node's defaults: finger 0.8 N, thumb 1.0 N

    def __post_init__(self) -> None:
        if self.frames < 1:
            raise ValueError(f"frames {self.frames} must be >= 1")
        if not self.pressure_low < self.pressure_high:
            raise ValueError(f"pressure_low {self.pressure_low} must be below pressure_high {self.pressure_high}")
        if not 0.0 < self.min_force <= self.max_force:
            raise ValueError(f"forces: 0 < min_force {self.min_force} <= max_force {self.max_force}")

    def force(self, pressure: float) -> float:
        """The finger force (N) a total pressure asks for."""
        share = (pressure - self.pressure_low) / (self.pressure_high - self.pressure_low)
        return self.min_force + min(1.0, max(0.0, share)) * (self.max_force - self.min_force)


class PoseMapper:
    """One pose estimate after the other -> the command to carry out, when it changes."""

    def __init__(self, mapping: PoseMapping = PoseMapping()) -> None:
        self.mapping = mapping
        self.current: StagCommand | None = None  # the command last started
        self.stable: str | None = None  # the class that started it (or last held, if it maps to nothing)
        self._run_class: str | None = None
        self._run_pressures: list[float] = []

    def update(self, label: str, confidence: float, pressure: float) -> StagCommand | None:
        """The new command when this frame completes a held class that changes it, else None."""
        m = self.mapping
        counted = EMPTY if pressure < m.empty_pressure else label if confidence >= m.min_confidence else None
        if counted is None or counted != self._run_class:
            self._run_class, self._run_pressures = counted, []
        if counted is None:
            return None
        self._run_pressures.append(pressure)
        if len(self._run_pressures) < m.frames or counted == self.stable:
            return None
        self.stable = counted
        if counted not in POSE_GRASPS:
            return None  # held, but starts nothing (point)
        command = self._command(counted, sum(self._run_pressures) / len(self._run_pressures))
        if _same(command, self.current):
            return None  # another class of the same grasp (tripod after pinch)
        self.current = command
        return command

    def _command(self, label: str, pressure: float) -> StagCommand:
        grasp = POSE_GRASPS[label]
        if grasp is None:
            return OpenCommand(label)
        force = self.mapping.force(pressure)
        return GraspCommand(grasp, force, force * self.mapping.thumb_force_ratio, label)


def _same(a: StagCommand | None, b: StagCommand | None) -> bool:
    if isinstance(a, GraspCommand) and isinstance(b, GraspCommand):
        return a.grasp == b.grasp
    return type(a) is type(b) and a is not None
