"""The synthetic operator: the script's phases, and a glove pose that retargets to its command exactly."""
from __future__ import annotations

import pytest

from prisma_teleop.retargeting import nominal_calibration, retarget
from prisma_teleop.synthetic_glove_core import OperatorScript, Synergies, SyntheticGlove, hand_pose

CAL = nominal_calibration()


def test_the_script_closes_holds_opens_and_sweeps_the_thumb():
    script = OperatorScript(rest_s=1.0, close_s=1.5, hold_s=2.0, open_s=1.5, sweep_s=4.0, closure=0.8)
    assert script.duration_s == 11.0
    assert [(name, start) for name, start in script.phases()] == [
        ("rest", 0.0), ("close", 1.0), ("hold", 2.5), ("open", 4.5), ("rest", 6.0), ("sweep", 7.0)]
    at = script.synergies
    assert at(0.5) == Synergies(0.0, 0.0, 0.0)
    assert at(1.75).fingers == pytest.approx(0.4)  # half way through the closing (raised cosine)
    assert at(3.0) == Synergies(0.8, 0.8, 0.0)
    assert at(6.5) == Synergies(0.0, 0.0, 0.0)
    assert at(8.0).opposition == pytest.approx(-1.0) and at(10.0).opposition == pytest.approx(1.0)
    assert at(8.0).fingers == 0.0
    assert at(11.0 + 3.0) == at(3.0)  # the next cycle


@pytest.mark.parametrize("command", [Synergies(0.0, 0.0, 0.0), Synergies(0.8, 0.8, 0.0), Synergies(0.3, 0.6, -0.4),
                                     Synergies(1.0, 1.0, 1.0)])
def test_the_glove_pose_retargets_to_the_command(command):
    out = retarget(hand_pose(command, CAL), CAL)
    rotation_end = 1.5
    assert out == pytest.approx({"fingers": 9.0 * command.fingers, "thumb_flexion": 7.0 * command.thumb,
                                 "thumb_rotation": rotation_end * command.opposition}, abs=1e-12)


def test_noise_and_the_end_of_a_script():
    glove = SyntheticGlove(OperatorScript(sweep_s=0.0), noise_rad=0.01, seed=4, loop=False)
    a, b = glove.sample(0.5), glove.sample(0.5)
    assert a != b and max(abs(a[j] - b[j]) for j in a) < 0.1  # the same pose, noisy
    assert glove.sample(glove.script.duration_s) is None
