"""Parameters of the motor_driver and manipulation nodes: validation against their config/*.yaml
(src/prisma_bringup/config), equal limits."""
from __future__ import annotations

import pytest
import yaml

from prisma_manipulation.node_config import ManipulationConfig
from prisma_motor_driver.node_config import MotorDriverConfig
from prisma_testing.repo_paths import CONFIG


@pytest.mark.parametrize("cls, path, node", [
    (MotorDriverConfig, "motor_driver.yaml", "motor_driver"),
    (ManipulationConfig, "manipulation.yaml", "manipulation"),
])
def test_yaml_matches_the_declared_defaults(cls, path, node):
    params = yaml.safe_load((CONFIG / path).read_text())[f"/**/{node}"]["ros__parameters"]
    assert params == cls().as_parameters()
    cls.from_parameters(params)


def test_manipulation_limits_equal_the_motor_driver_limits():
    driver = yaml.safe_load((CONFIG / "motor_driver.yaml").read_text())["/**/motor_driver"]["ros__parameters"]
    manip = yaml.safe_load((CONFIG / "manipulation.yaml").read_text())["/**/manipulation"]["ros__parameters"]
    for key in ("motor_names", "min_positions", "max_positions"):
        assert manip[key] == driver[key]


@pytest.mark.parametrize("cls, values, message", [
    (MotorDriverConfig, {"backend": "can"}, "invalid parameter 'backend' = 'can'"),
    (MotorDriverConfig, {"rate_hz": 0.0}, "invalid parameter 'rate_hz' = 0.0"),
    (MotorDriverConfig, {"motor_ids": [1, 2]}, "invalid parameter 'motor_ids' = [1, 2]"),
    (MotorDriverConfig, {"max_positions": [9.0, 7.0, -4.0]}, "position limits"),
    (ManipulationConfig, {"grasp_speed_rpm": 80.0}, "invalid parameter 'grasp_speed_rpm' = 80.0: above max_speed_rpm"),
    (ManipulationConfig, {"monitored_finger": "wrist"}, "invalid parameter 'monitored_finger' = 'wrist'"),
    (ManipulationConfig, {"frame_id_format": "pad"}, "invalid parameter 'frame_id_format' = 'pad'"),
    (ManipulationConfig, {"stale_timeout": 0.06}, "invalid parameter 'stale_timeout' = 0.06: at least 4 x "
                                                  "watchdog_period"),
    (ManipulationConfig, {"stale_timeout": 0.3}, "invalid parameter 'stale_timeout' = 0.3: must be below the "
                                                 "MoveMotors lease 0.3 s"),
])
def test_bad_parameters_name_themselves(cls, values, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        cls.from_parameters(values)
