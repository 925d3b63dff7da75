"""The teleop node's parameters: defaults that agree with the hand's shipped limits, the filter delay
the docs state, and each bad value refused with the parameter's name."""
from __future__ import annotations

import pytest

from prisma_common.hand import MOTOR_NAMES
from prisma_common.parameters import ParameterError
from prisma_teleop import retargeting
from prisma_teleop.node_config import SyntheticGloveConfig, TeleopConfig
from prisma_testing.repo_paths import CONFIG, ROOT, node_parameters


def test_defaults_validate():
    TeleopConfig().validate()
    SyntheticGloveConfig().validate()


def test_the_motor_ranges_lie_within_the_motors_limits():
    """The fist and the thumb's extremes ask for no more than the motor driver's limits allow (the
    manipulation node would clamp them: the fist would not be the closed limit)."""
    motors = node_parameters(CONFIG / "motor_driver.yaml", "motor_driver")
    low = dict(zip(motors["motor_names"], motors["min_positions"]))
    high = dict(zip(motors["motor_names"], motors["max_positions"]))
    ranges = TeleopConfig().motor_ranges()
    for motor in MOTOR_NAMES:
        lo, hi = ranges.span(motor)
        assert low[motor] <= lo and hi <= high[motor], motor
    assert ranges.fingers_closed == high["fingers"]  # the fist closes the fingers fully


def test_the_grasp_forces_lie_within_the_hands_limit():
    manipulation = node_parameters(CONFIG / "manipulation.yaml", "manipulation")
    c = TeleopConfig()
    assert c.max_grasp_force * c.thumb_force_ratio <= manipulation["max_force_n"]


def test_the_docs_state_the_default_filter_delay():
    delay = f"{TeleopConfig().target_filter().delay_s * 1e3:.1f} ms"
    assert delay == "36.3 ms"
    assert delay in retargeting.__doc__
    assert delay in (CONFIG / "teleop.yaml").read_text()
    assert delay in (ROOT / "docs" / "teleoperation.md").read_text()


@pytest.mark.parametrize("values,message", [
    ({"input": "mocap"}, "expected one of joint_states|stag"),
    ({"filter_cutoff_hz": 30.0}, "'filter_cutoff_hz' = 30.0: must be below half the glove rate, 30.0 Hz"),
    ({"thumb_rotation_opposed": -0.5}, "must lie on the other side of 0 than thumb_rotation_adducted -1.5"),
    ({"thumb_flexion_joints": ["index_mcp"]}, r"a joint drives one synergy only: \['index_mcp'\]"),
    ({"thumb_opposition_joints": []}, "thumb_opposition: at least one joint"),
    ({"pressure_high": 5.0}, "'pressure_high' = 5.0: must be above pressure_low 5.0"),
    ({"max_grasp_force": 0.3}, "must be at least min_grasp_force 0.4"),
    ({"deadband": -0.1}, "'deadband' = -0.1: must be >= 0.0"),
])
def test_a_bad_value_is_named(values, message):
    with pytest.raises(ParameterError, match=message):
        TeleopConfig.from_parameters(values)
