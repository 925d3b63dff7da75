"""Parameters of the manipulation node: defaults (= config/manipulation.yaml), their specs
(description, unit, bounds, live or read-only) and validation.

`from_parameters` raises ParameterError naming the parameter and the bad value, so a node with an
invalid parameter fails at start with that message, and a run-time change with it is refused.

Live (changeable while the node runs, through the same checks): k and min_mean_voltage (Algorithm 1,
from the next sample, also during a goal: tuning K while rqt_plot draws the threshold is how the
paper's experiments were run), the watchdog's stale_timeout and the stamp limits (from the next
check and sample), and the goal defaults and controller settings with hold_min_k (from the next
goal: a running goal keeps what it started with). Read-only: what the node is built from at start
(fingers, topics, the watchdog timer, the motor limits shared with motor_driver) and the goal limits
max_speed_rpm / max_force_n, the envelope every goal is checked against, which only a restart with a
new configuration widens.
"""
from __future__ import annotations

from dataclasses import dataclass

from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_common.parameters import ParameterError, Params, check_fingers, parameter
from prisma_common.sample_stamps import StampLimits
from prisma_common.topics import MOVE_MOTORS_ACTION
from prisma_motor_driver.backend import (
    DEFAULT_MAX_POSITIONS,
    DEFAULT_MIN_POSITIONS,
    MotorConfig,
    MotorMap,
)
from prisma_motor_driver.control_table import VELOCITY_LIMIT_MAX_RPM

from .contact_monitor import DEFAULT_K, K_RANGE
from .gripper_controller import DEFAULT_THUMB_RATIO
from .move_lease import MOVE_LEASE_S
from .teleop_controller import COMMAND_PERIOD_S

MAX_FORCE_N = 10.0  # the highest force any parameter may name: twice the calibrated range of the pads
MAX_TIMEOUT_S = 600.0
MAX_INPUT_TIMEOUT_S = 1.0  # a Teleoperate goal's input_timeout: a glove silent longer is not teleoperating
SPEED = (0.0, VELOCITY_LIMIT_MAX_RPM)
FORCE = (0.0, MAX_FORCE_N)
TIMEOUT = (0.0, MAX_TIMEOUT_S)
BELOW_MAX_SPEED = "at most max_speed_rpm"
BELOW_MAX_FORCE = "at most max_force_n"
GOAL_SPEEDS = ("grasp_speed_rpm", "horizontal_speed_rpm", "vertical_speed_rpm", "hold_speed_rpm", "force_speed_rpm",
               "gripper_speed_rpm", "teleop_max_speed_rpm")
GOAL_FORCES = ("grasp_finger_force", "grasp_thumb_force", "force_target_n", "gripper_max_effort",
               "teleop_max_pad_force")


@dataclass
class ManipulationConfig(Params):
    fingers: list = parameter(list(FINGERS), "fingertip pads whose taxels and wrenches this node takes",
                              rules=f"distinct names of {', '.join(FINGERS)}")
    frame_id_format: str = parameter("prisma_{finger}_pad", "header.frame_id of each ContactState",
                                     rules="contains {finger}, replaced by the finger's name")
    k: float = parameter(DEFAULT_K, "Algorithm 1 threshold factor: a taxel is safe while its voltage >= k x its "
                                    "pad's mean voltage", bounds=K_RANGE, open_low=True, live=True)
    min_mean_voltage: float = parameter(0.55, "below this mean voltage a pad is not in contact "
                                              "(ContactState.feasible false)", unit="V", bounds=(0.0, 3.3),
                                        open_high=True, live=True)
    monitored_finger: str = parameter("thumb", "the pad Manipulate goals steer by", choices=FINGERS,
                                      rules="one of fingers")
    stale_timeout: float = parameter(0.1, "watchdog: taxels, wrenches or /joint_states older or silent this long "
                                          "abort the goal with sensor_stale", unit="s", bounds=(0.0, 1.0),
                                     open_low=True, live=True,
                                     rules=f"at least 4 x watchdog_period, below the MoveMotors lease "
                                           f"{MOVE_LEASE_S:g} s")
    watchdog_period: float = parameter(0.02, "how often the watchdog checks", unit="s", bounds=(0.0, 1.0),
                                       open_low=True)
    max_stamp_age: float = parameter(2.0, "a taxel, wrench, /joint_states or motor-target sample stamped longer than "
                                          "this before it arrives (this node's clock) is refused: no goal steps or "
                                          "starts on it", unit="s", bounds=(0.0, 60.0), open_low=True, live=True)
    max_stamp_ahead: float = parameter(0.5, "a sample stamped further than this ahead of this node's clock is refused "
                                            "(its publisher's clock is not synchronised)", unit="s",
                                       bounds=(0.0, 60.0), open_low=True, live=True)
    max_speed_rpm: float = parameter(70.0, "goals asking for a faster motor speed are rejected", unit="rpm",
                                     bounds=SPEED, open_low=True)
    max_force_n: float = parameter(3.0, "goals asking for a larger force are rejected", unit="N", bounds=FORCE,
                                   open_low=True)
    hold_min_k: float = parameter(0.6, "hold goals need k above this (docs/manipulation.md)",
                                  bounds=K_RANGE, open_high=True, live=True)
    # defaults for goal fields left at 0
    grasp_finger_force: float = parameter(0.8, "Grasp finger_force when the goal leaves it 0", unit="N",
                                          bounds=FORCE, open_low=True, live=True, rules=BELOW_MAX_FORCE)
    grasp_thumb_force: float = parameter(1.0, "Grasp thumb_force when the goal leaves it 0", unit="N",
                                         bounds=FORCE, open_low=True, live=True, rules=BELOW_MAX_FORCE)
    grasp_speed_rpm: float = parameter(60.0, "Grasp speed_rpm when the goal leaves it 0", unit="rpm",
                                       bounds=SPEED, open_low=True, live=True, rules=BELOW_MAX_SPEED)
    grasp_timeout: float = parameter(10.0, "Grasp timeout when the goal leaves it 0", unit="s", bounds=TIMEOUT,
                                     open_low=True, live=True)
    horizontal_speed_rpm: float = parameter(20.0, "Manipulate horizontal speed_rpm when the goal leaves it 0",
                                            unit="rpm", bounds=SPEED, open_low=True, live=True,
                                            rules=BELOW_MAX_SPEED)
    vertical_speed_rpm: float = parameter(10.0, "Manipulate vertical speed_rpm when the goal leaves it 0",
                                          unit="rpm", bounds=SPEED, open_low=True, live=True, rules=BELOW_MAX_SPEED)
    hold_speed_rpm: float = parameter(20.0, "Manipulate hold speed_rpm when the goal leaves it 0", unit="rpm",
                                      bounds=SPEED, open_low=True, live=True, rules=BELOW_MAX_SPEED)
    manipulate_timeout: float = parameter(30.0, "Manipulate timeout when the goal leaves it 0", unit="s",
                                          bounds=TIMEOUT, open_low=True, live=True)
    # GripperCommand (/prisma/gripper_cmd): position = the fingers motor angle; docs/manipulation.md
    gripper_max_effort: float = parameter(1.0, "GripperCommand force limit on the estimated pad forces when the "
                                               "goal's max_effort is 0 (MoveIt's default)", unit="N", bounds=FORCE,
                                          open_low=True, live=True, rules=BELOW_MAX_FORCE)
    gripper_speed_rpm: float = parameter(60.0, "GripperCommand speed of the fingers motor (the thumb flexion "
                                               "moves at gripper_thumb_ratio x this)", unit="rpm", bounds=SPEED,
                                         open_low=True, live=True, rules=BELOW_MAX_SPEED)
    gripper_thumb_ratio: float = parameter(DEFAULT_THUMB_RATIO, "GripperCommand thumb_flexion target per rad of "
                                                                "the fingers position", bounds=(0.0, 2.0),
                                           open_low=True, live=True,
                                           rules="gripper_thumb_ratio x gripper_speed_rpm at most max_speed_rpm")
    gripper_timeout: float = parameter(10.0, "a GripperCommand goal ends after this long", unit="s",
                                       bounds=TIMEOUT, open_low=True, live=True)
    # Teleoperate (/prisma/teleoperate): the motors follow prisma/teleop/motor_targets; docs/manipulation.md
    teleop_max_pad_force: float = parameter(2.0, "Teleoperate touch limit when the goal's max_pad_force is 0: no "
                                                 "finger closes further once its pad's estimated normal force "
                                                 "reaches this (the sim ball held well inside the pads' range)",
                                            unit="N", bounds=FORCE, open_low=True, live=True, rules=BELOW_MAX_FORCE)
    teleop_max_speed_rpm: float = parameter(40.0, "Teleoperate: the fastest a motor follows its target when the "
                                                  "goal's max_speed_rpm is 0", unit="rpm", bounds=SPEED,
                                            open_low=True, live=True, rules=BELOW_MAX_SPEED)
    teleop_input_timeout: float = parameter(0.15, "Teleoperate: targets silent this long end the goal input_stale "
                                                  "when the goal's input_timeout is 0 (0.15 s + the watchdog: the "
                                                  "motors stop within 0.3 s of the glove falling silent)", unit="s",
                                            bounds=(0.0, MAX_INPUT_TIMEOUT_S), open_low=True, live=True)
    teleop_gain: float = parameter(10.0, "Teleoperate: velocity toward the target per rad of error, rad/s per rad "
                                         "(10 = 95 rpm per rad of error, capped at the goal's max_speed_rpm)",
                                   unit="1/s", bounds=(0.0, 1.0 / COMMAND_PERIOD_S), open_low=True, live=True,
                                   rules=f"at most {1.0 / COMMAND_PERIOD_S:g}: the speed is updated every "
                                         f"{COMMAND_PERIOD_S} s, a higher gain would overshoot the target")
    # controller details
    contact_force_n: float = parameter(0.1, "a pad touches above this force (the power grasp averages those)",
                                       unit="N", bounds=FORCE, open_low=True, live=True)
    lateral_closure: float = parameter(7.0, "fingers motor position of the lateral grasp's fist", unit="rad",
                                       bounds=(0.0, 20.0), open_low=True, live=True)
    force_target_n: float = parameter(1.0, "use_force: thumb force kept during a manipulation", unit="N",
                                      bounds=FORCE, open_low=True, live=True, rules=BELOW_MAX_FORCE)
    force_band_n: float = parameter(0.15, "use_force: restored when the thumb force falls this far below the target",
                                    unit="N", bounds=FORCE, open_low=True, live=True, rules="below force_target_n")
    force_speed_rpm: float = parameter(20.0, "use_force: thumb flexion speed restoring the force", unit="rpm",
                                       bounds=SPEED, open_low=True, live=True, rules=BELOW_MAX_SPEED)
    # the motor_driver's motors and limits (keep equal to config/motor_driver.yaml)
    motor_names: list = parameter(list(MOTOR_NAMES), "the motor driver's motors (as config/motor_driver.yaml)",
                                  rules=f"each of {', '.join(MOTOR_NAMES)} once")
    min_positions: list = parameter(list(DEFAULT_MIN_POSITIONS), "lowest position of each motor "
                                    "(as config/motor_driver.yaml)", unit="rad",
                                    rules="one entry per motor, in the order of motor_names")
    max_positions: list = parameter(list(DEFAULT_MAX_POSITIONS), "highest position of each motor "
                                    "(as config/motor_driver.yaml)", unit="rad",
                                    rules="one entry per motor, in the order of motor_names; above min_positions")
    limit_margin: float = parameter(0.02, "a motor this close to a limit counts as at the limit", unit="rad",
                                    bounds=(0.0, 1.0), open_low=True)
    move_action: str = parameter(MOVE_MOTORS_ACTION, "the motor driver's MoveMotors action (relative: follows the "
                                                       "node's namespace)")

    def check_rules(self) -> None:
        check_fingers(self.fingers)
        if self.monitored_finger not in self.fingers:
            raise ParameterError("monitored_finger", self.monitored_finger, f"must be one of fingers {self.fingers}")
        if "{finger}" not in self.frame_id_format:
            raise ParameterError("frame_id_format", self.frame_id_format, "must contain {finger}")
        if self.stale_timeout < 4 * self.watchdog_period:
            # a check more than half the stale window after the last counts as the node held up (watchdog.py)
            raise ParameterError("stale_timeout", self.stale_timeout,
                                 f"at least 4 x watchdog_period ({4 * self.watchdog_period:g} s)")
        if self.stale_timeout >= MOVE_LEASE_S:
            # manipulation renews the motor command until its watchdog fires: the window bounds how long
            # after its last data a renewal that a dropped link held back can still run the motors
            raise ParameterError("stale_timeout", self.stale_timeout,
                                 f"must be below the MoveMotors lease {MOVE_LEASE_S:g} s: it bounds how long after "
                                 "its last data a renewal a dropped link held back can still run the motors")
        for name in GOAL_SPEEDS:
            if getattr(self, name) > self.max_speed_rpm:
                raise ParameterError(name, getattr(self, name), f"above max_speed_rpm {self.max_speed_rpm}")
        if self.gripper_thumb_ratio * self.gripper_speed_rpm > self.max_speed_rpm:
            raise ParameterError("gripper_thumb_ratio", self.gripper_thumb_ratio,
                                 f"the thumb would close at {self.gripper_thumb_ratio * self.gripper_speed_rpm:g} rpm, "
                                 f"above max_speed_rpm {self.max_speed_rpm}")
        for name in GOAL_FORCES:
            if getattr(self, name) > self.max_force_n:
                raise ParameterError(name, getattr(self, name), f"above max_force_n {self.max_force_n}")
        if self.force_band_n >= self.force_target_n:
            raise ParameterError("force_band_n", self.force_band_n,
                                 f"must be below force_target_n {self.force_target_n}")
        n = len(self.motor_names)
        if sorted(self.motor_names) != sorted(MOTOR_NAMES):
            raise ParameterError("motor_names", self.motor_names, f"must name {list(MOTOR_NAMES)}")
        for name in ("min_positions", "max_positions"):
            if len(getattr(self, name)) != n:
                raise ParameterError(name, getattr(self, name), f"needs one entry per motor ({n})")
        for name, lo, hi in zip(self.motor_names, self.min_positions, self.max_positions):
            if not lo < hi:
                raise ParameterError("min_positions/max_positions", [lo, hi], f"empty window for {name}")

    def stamp_limits(self) -> StampLimits:
        return StampLimits.of_seconds(self.max_stamp_age, self.max_stamp_ahead)

    def limits_motors(self) -> dict[str, MotorConfig]:
        """MotorConfigs carrying only what the controllers use: the position windows."""
        return MotorMap.from_lists(list(self.motor_names), list(range(1, len(self.motor_names) + 1)),
                                   [float(v) for v in self.min_positions], [float(v) for v in self.max_positions],
                                   [self.max_speed_rpm] * len(self.motor_names)).motors
