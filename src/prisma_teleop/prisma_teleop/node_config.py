"""Parameters of the teleop and synthetic_glove nodes: defaults (= config/teleop.yaml and
config/synthetic_glove.yaml), their descriptions and ranges, validation naming the bad parameter and
value, and the core settings they make.

Live on teleop: the deadband, the stamp limits of the glove's samples, what each new goal asks for
(the Teleoperate goal's pad force, speed and input timeout; the STAG grasps' speed and forces) and the
STAG pose hysteresis, from the next sample or goal. Read-only: the input, the joint names, the
calibration file, the motor ranges and the filter, which the node is built with at start.
"""
from __future__ import annotations

from dataclasses import dataclass

from prisma_common.parameters import ParameterError, Params, parameter
from prisma_common.sample_stamps import StampLimits

from .episodes import DEFAULT_TASK
from .retargeting import DEFAULT_JOINTS, JointGroups, MotorRanges, TargetFilter
from .stag_poses import PoseMapping

INPUTS = ("joint_states", "stag")
MOTOR_RAD = (-20.0, 20.0)  # a motor target, rad: beyond any hand's travel (the manipulation node clamps to its own)
JOINT_RULE = "glove joint names, none in two groups"
_RANGES = MotorRanges()
_MAPPING = PoseMapping()


@dataclass
class TeleopConfig(Params):
    input: str = parameter("joint_states", "what drives the hand: joint_states (a hand-pose glove's joint angles on "
                                           "glove/joint_states) or stag (the STAG glove's pose classes and pressure)",
                           choices=INPUTS)
    engage_at_start: bool = parameter(False, "take the hand as soon as the glove's input flows (else: service "
                                             "~/engage)")
    retry_period: float = parameter(0.5, "wait before sending a goal again that the hand refused for now "
                                         "(not_ready, busy)", unit="s", bounds=(0.0, 10.0), open_low=True)
    max_input_age: float = parameter(0.5, "input joint_states: a glove sample stamped longer than this before it "
                                          "arrives is refused: nothing moves on it", unit="s", bounds=(0.0, 60.0),
                                     open_low=True, live=True)
    max_pose_age: float = parameter(5.0, "input stag: a pose estimate stamped (with its glove frame) longer than this "
                                         "before it arrives is refused (the estimate waits for glove_perception's "
                                         "inference: 0.7 s while it warms up, 3 s seen on a loaded machine)",
                                    unit="s", bounds=(0.0, 60.0), open_low=True, live=True)
    max_input_ahead: float = parameter(0.5, "a glove sample or pose estimate stamped further than this ahead of this "
                                            "node's clock is refused (the glove's clock is not synchronised)",
                                       unit="s", bounds=(0.0, 60.0), open_low=True, live=True)
    episode_task: str = parameter(DEFAULT_TASK, "the task of an episode engaging starts, as the episode markers on "
                                                "prisma/teleop/episode carry it (~/mark_episode may give another)",
                                  live=True, rules="not empty")
    # --- input joint_states
    finger_flexion_joints: list = parameter(list(DEFAULT_JOINTS.finger_flexion),
                                            "glove joints whose mean flexion closes the fingers motor",
                                            rules=JOINT_RULE)
    thumb_flexion_joints: list = parameter(list(DEFAULT_JOINTS.thumb_flexion),
                                           "glove joints whose mean flexion flexes the thumb", rules=JOINT_RULE)
    thumb_opposition_joints: list = parameter(list(DEFAULT_JOINTS.thumb_opposition),
                                              "glove joints whose mean abduction rotates the thumb", rules=JOINT_RULE)
    calibration_file: str = parameter("", "this operator's calibration (YAML): loaded at start if it exists, "
                                           "written by the ~/capture_* services; \"\" = the nominal hand, not saved")
    capture_samples: int = parameter(10, "glove samples averaged by a ~/capture_* service", bounds=(1, 1000))
    fingers_closed: float = parameter(_RANGES.fingers_closed, "fingers motor target of the operator's fist",
                                      unit="rad", bounds=(0.0, MOTOR_RAD[1]), open_low=True)
    thumb_flexion_closed: float = parameter(_RANGES.thumb_flexion_closed, "thumb_flexion target of the fist",
                                            unit="rad", bounds=(0.0, MOTOR_RAD[1]), open_low=True)
    thumb_rotation_adducted: float = parameter(_RANGES.thumb_rotation_adducted, "thumb_rotation target of the "
                                               "thumb pressed against the index", unit="rad", bounds=MOTOR_RAD)
    thumb_rotation_opposed: float = parameter(_RANGES.thumb_rotation_opposed, "thumb_rotation target of the thumb "
                                              "opposed across the palm", unit="rad", bounds=MOTOR_RAD,
                                              rules="on the other side of 0 than thumb_rotation_adducted")
    glove_rate_hz: float = parameter(60.0, "the glove's nominal sample rate, for which the filter is designed",
                                     unit="Hz", bounds=(1.0, 2000.0))
    filter_cutoff_hz: float = parameter(6.0, "low-pass cutoff of the targets (Butterworth)", unit="Hz",
                                        bounds=(0.0, 1000.0), open_low=True, rules="below glove_rate_hz / 2")
    filter_order: int = parameter(2, "order of the Butterworth low-pass", bounds=(1, 8))
    filter_reset_gap: float = parameter(0.1, "a silence of the glove longer than this starts the filter again at "
                                             "the next sample", unit="s", bounds=(0.0, 10.0), open_low=True)
    deadband: float = parameter(0.02, "least change of a motor target sent", unit="rad", bounds=(0.0, 1.0),
                                live=True)
    max_pad_force: float = parameter(0.0, "Teleoperate goal: no finger closes further once its pad's force reaches "
                                          "this; 0 = the manipulation node's teleop_max_pad_force", unit="N",
                                     bounds=(0.0, 10.0), live=True)
    max_speed_rpm: float = parameter(0.0, "Teleoperate goal: the fastest a motor follows its target; 0 = the "
                                          "manipulation node's teleop_max_speed_rpm", unit="rpm",
                                     bounds=(0.0, 1000.0), live=True)
    input_timeout: float = parameter(0.0, "Teleoperate goal: targets silent this long end it input_stale; 0 = the "
                                          "manipulation node's teleop_input_timeout", unit="s",
                                     bounds=(0.0, 10.0), live=True)
    # --- input stag
    pose_frames: int = parameter(_MAPPING.frames, "frames in a row a pose class must hold to start its grasp",
                                 bounds=(1, 100), live=True)
    pose_confidence: float = parameter(_MAPPING.min_confidence, "least confidence of a pose estimate that counts",
                                       bounds=(0.0, 1.0), live=True)
    empty_pressure: float = parameter(_MAPPING.empty_pressure, "a glove frame pressing less than this in total is "
                                                                "the empty hand", bounds=(0.0, 1024.0), live=True)
    pressure_low: float = parameter(_MAPPING.pressure_low, "total glove pressure that asks for min_grasp_force",
                                    bounds=(0.0, 1024.0), live=True)
    pressure_high: float = parameter(_MAPPING.pressure_high, "total glove pressure that asks for max_grasp_force",
                                     bounds=(0.0, 1024.0), live=True, rules="above pressure_low")
    min_grasp_force: float = parameter(_MAPPING.min_force, "finger force of a grasp pressed lightly", unit="N",
                                       bounds=(0.0, 10.0), open_low=True, live=True)
    max_grasp_force: float = parameter(_MAPPING.max_force, "finger force of a grasp pressed hard", unit="N",
                                       bounds=(0.0, 10.0), open_low=True, live=True,
                                       rules="at least min_grasp_force")
    thumb_force_ratio: float = parameter(_MAPPING.thumb_force_ratio, "a grasp's thumb force over its finger force",
                                         bounds=(0.0, 10.0), open_low=True, live=True)
    grasp_speed_rpm: float = parameter(0.0, "speed of the STAG grasps; 0 = the manipulation node's grasp_speed_rpm",
                                       unit="rpm", bounds=(0.0, 1000.0), live=True)

    def check_rules(self) -> None:
        if not self.episode_task.strip():
            raise ParameterError("episode_task", self.episode_task, "describe what the operator demonstrates, e.g. "
                                                                    "'pinch the ball'")
        try:
            self.joint_groups()
        except ValueError as exc:
            raise ParameterError("finger_flexion_joints", self.finger_flexion_joints, str(exc)) from None
        for name in ("finger_flexion_joints", "thumb_flexion_joints", "thumb_opposition_joints"):
            if any(not isinstance(j, str) or not j for j in getattr(self, name)):
                raise ParameterError(name, getattr(self, name), "non-empty joint names")
        if self.thumb_rotation_adducted * self.thumb_rotation_opposed >= 0.0:
            raise ParameterError("thumb_rotation_opposed", self.thumb_rotation_opposed,
                                 f"must lie on the other side of 0 than thumb_rotation_adducted "
                                 f"{self.thumb_rotation_adducted} (the open hand's thumb is at 0)")
        if self.filter_cutoff_hz >= self.glove_rate_hz / 2.0:
            raise ParameterError("filter_cutoff_hz", self.filter_cutoff_hz,
                                 f"must be below half the glove rate, {self.glove_rate_hz / 2.0} Hz")
        if self.pressure_high <= self.pressure_low:
            raise ParameterError("pressure_high", self.pressure_high, f"must be above pressure_low {self.pressure_low}")
        if self.max_grasp_force < self.min_grasp_force:
            raise ParameterError("max_grasp_force", self.max_grasp_force,
                                 f"must be at least min_grasp_force {self.min_grasp_force}")

    def joint_groups(self) -> JointGroups:
        return JointGroups(tuple(self.finger_flexion_joints), tuple(self.thumb_flexion_joints),
                           tuple(self.thumb_opposition_joints))

    def motor_ranges(self) -> MotorRanges:
        return MotorRanges(self.fingers_closed, self.thumb_flexion_closed, self.thumb_rotation_adducted,
                           self.thumb_rotation_opposed)

    def target_filter(self) -> TargetFilter:
        return TargetFilter(self.motor_ranges(), self.glove_rate_hz, self.filter_cutoff_hz, self.filter_order,
                            self.deadband, self.filter_reset_gap)

    def stamp_limits(self) -> StampLimits:
        """How old (or ahead) an input sample may be on arrival: a glove sample's or a pose estimate's."""
        age = self.max_input_age if self.input == "joint_states" else self.max_pose_age
        return StampLimits.of_seconds(age, self.max_input_ahead)

    def pose_mapping(self) -> PoseMapping:
        return PoseMapping(self.pose_frames, self.pose_confidence, self.empty_pressure, self.pressure_low,
                           self.pressure_high, self.min_grasp_force, self.max_grasp_force, self.thumb_force_ratio)


@dataclass
class SyntheticGloveConfig(Params):
    rate_hz: float = parameter(60.0, "samples per second on glove/joint_states", unit="Hz", bounds=(1.0, 1000.0))
    loop: bool = parameter(True, "start the operator's script again when it ends (else: stop publishing)")
    rest_s: float = parameter(1.0, "the open hand before each closing and after each opening", unit="s",
                              bounds=(0.0, 60.0))
    close_s: float = parameter(1.5, "the operator closes around the ball in this time", unit="s",
                               bounds=(0.0, 60.0), open_low=True)
    hold_s: float = parameter(2.0, "the operator holds the closed hand", unit="s", bounds=(0.0, 60.0))
    open_s: float = parameter(1.5, "the operator opens in this time", unit="s", bounds=(0.0, 60.0), open_low=True)
    sweep_s: float = parameter(4.0, "the thumb's opposition sweep (adducted, opposed, back to open); 0 = none",
                               unit="s", bounds=(0.0, 60.0))
    closure: float = parameter(1.0, "how far the operator closes (0 open hand, 1 fist): the hand's touch limit stops "
                                    "it on the ball", bounds=(0.0, 1.0))
    noise_rad: float = parameter(0.005, "standard deviation of the glove's noise on each joint", unit="rad",
                                 bounds=(0.0, 0.5))
    seed: int = parameter(0, "seed of the glove's noise", bounds=(0, 2**31 - 1))
    frame_id: str = parameter("glove", "header.frame_id of the joint states")
