"""Synergy retargeting (open hand -> 0, fist -> the closed limits exactly, monotone in every joint)
and the target filter (its stated delay, the deadband, the ends reached exactly, a restart after a
silence)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from prisma_common.hand import MOTOR_NAMES
from prisma_teleop.calibration import OperatorCalibration
from prisma_teleop.retargeting import (
    DEFAULT_JOINTS,
    JointGroups,
    MissingJoints,
    MotorRanges,
    TargetFilter,
    nominal_calibration,
    retarget,
)

CAL = nominal_calibration()
RANGES = MotorRanges()
NS = 1_000_000_000
PERIOD_NS = NS // 60


def operator_calibration() -> OperatorCalibration:
    """Not the nominal hand: every joint with its own open and fist angles."""
    rng = np.random.default_rng(3)
    open_hand = {j: float(rng.uniform(-0.2, 0.2)) for j in DEFAULT_JOINTS.all()}
    fist = {j: a + float(rng.uniform(0.6, 1.8)) for j, a in open_hand.items()}
    centre = open_hand["thumb_cmc_abduction"]
    return OperatorCalibration(open_hand, fist, open_hand | {"thumb_cmc_abduction": centre - 0.4},
                               open_hand | {"thumb_cmc_abduction": centre + 0.9})


@pytest.mark.parametrize("cal", [CAL, operator_calibration()], ids=["nominal", "operator"])
def test_open_hand_is_0_and_fist_is_the_closed_limit_exactly(cal):
    assert retarget(cal.open_hand, cal) == {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}
    fist = retarget(cal.fist, cal)
    assert (fist["fingers"], fist["thumb_flexion"]) == (RANGES.fingers_closed, RANGES.thumb_flexion_closed)
    assert retarget(cal.thumb_opposed, cal)["thumb_rotation"] == RANGES.thumb_rotation_opposed
    assert retarget(cal.thumb_adducted, cal)["thumb_rotation"] == RANGES.thumb_rotation_adducted
    assert list(fist) == list(MOTOR_NAMES)


def test_each_synergy_reads_its_own_joints():
    half = dict(CAL.open_hand)
    for j in DEFAULT_JOINTS.finger_flexion:
        half[j] = (CAL.open_hand[j] + CAL.fist[j]) / 2
    out = retarget(half, CAL)
    assert out["fingers"] == pytest.approx(4.5) and out["thumb_flexion"] == 0.0 and out["thumb_rotation"] == 0.0
    one_joint = CAL.open_hand | {"middle_pip": CAL.fist["middle_pip"]}
    assert retarget(one_joint, CAL)["fingers"] == pytest.approx(9.0 / 12)  # one of twelve finger joints


def test_a_missing_joint_is_named():
    pose = {j: a for j, a in CAL.open_hand.items() if j != "thumb_ip"} | {"wrist": 0.3}
    with pytest.raises(MissingJoints, match="hand pose lacks thumb_ip"):
        retarget(pose, CAL)
    with pytest.raises(MissingJoints, match="index_mcp"):
        retarget(CAL.open_hand | {"index_mcp": math.nan}, CAL)


ANGLES = st.floats(-0.5, 2.5, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(pose=st.fixed_dictionaries({j: ANGLES for j in DEFAULT_JOINTS.all()}),
       joint=st.sampled_from(DEFAULT_JOINTS.all()), step=st.floats(0.0, 2.0))
def test_monotone_in_each_input(pose, joint, step):
    """Flexing any one joint further, or opposing the thumb further, never lowers a target."""
    for cal in (CAL, OPERATOR):
        before = retarget(pose, cal)
        after = retarget(pose | {joint: pose[joint] + step}, cal)
        assert all(after[m] >= before[m] for m in MOTOR_NAMES), (joint, before, after)


OPERATOR = operator_calibration()


def run(filt: TargetFilter, values: list[dict[str, float]], start_ns: int = 0) -> list[dict[str, float]]:
    return [filt.step(start_ns + i * PERIOD_NS, v) for i, v in enumerate(values)]


def target(fingers: float = 0.0, thumb: float = 0.0, rotation: float = 0.0) -> dict[str, float]:
    return {"fingers": fingers, "thumb_flexion": thumb, "thumb_rotation": rotation}


def test_the_stated_delay_is_the_lag_behind_a_ramp():
    """A low-pass trails a ramp by its group delay at 0 Hz once settled: the delay the docs state."""
    filt = TargetFilter(deadband_rad=0.0)
    assert filt.delay_s == pytest.approx(0.03627, abs=1e-5)  # 2nd order Butterworth, 6 Hz, 60 Hz
    slope = 2.0  # rad/s
    out = run(filt, [target(1.0 + slope * i / 60) for i in range(120)])
    lag = (1.0 + slope * 119 / 60 - out[-1]["fingers"]) / slope
    assert lag == pytest.approx(filt.delay_s, abs=1e-6)


def test_the_first_sample_starts_the_filter_at_its_value():
    out = run(TargetFilter(), [target(5.0, 4.0, -1.0)] * 3)
    assert out == [target(5.0, 4.0, -1.0)] * 3


def test_the_deadband_holds_noise_and_passes_moves():
    filt = TargetFilter(deadband_rad=0.05)
    rng = np.random.default_rng(0)
    noisy = [target(4.0 + float(n)) for n in rng.normal(0.0, 0.01, 200)]
    out = run(filt, noisy)
    assert {o["fingers"] for o in out[1:]} == {out[0]["fingers"]}  # never changed
    moved = run(filt, [target(4.5)] * 60, start_ns=200 * PERIOD_NS)
    changes = [b["fingers"] - a["fingers"] for a, b in zip(moved, moved[1:]) if b["fingers"] != a["fingers"]]
    assert changes and all(c >= 0.05 for c in changes[:-1])
    assert moved[-1]["fingers"] == pytest.approx(4.5, abs=0.05)


def test_the_ends_are_reached_exactly():
    filt = TargetFilter()
    closed = run(filt, [target(0.0)] + [target(RANGES.fingers_closed, RANGES.thumb_flexion_closed,
                                                RANGES.thumb_rotation_opposed)] * 60)
    assert closed[-1] == target(9.0, 7.0, 1.5)
    opened = run(filt, [target(0.0)] * 60, start_ns=61 * PERIOD_NS)
    assert opened[-1] == target(0.0, 0.0, 0.0)
    beyond = run(TargetFilter(), [target(12.0, -3.0, 4.0)])  # clamped to the synergy's range
    assert beyond[-1] == target(9.0, 0.0, 1.5)


def test_a_silence_starts_the_filter_again():
    filt = TargetFilter(reset_gap_s=0.1)
    run(filt, [target(1.0)] * 30)
    later = filt.step(30 * PERIOD_NS + NS, target(6.0))  # 1 s of silence: the old pose is forgotten
    assert later == target(6.0)
    resumed = filt.step(30 * PERIOD_NS + NS + PERIOD_NS, target(2.0))  # no silence: filtered
    assert 2.0 < resumed["fingers"] < 6.0


def test_joint_groups_are_checked():
    with pytest.raises(ValueError, match="finger_flexion: at least one joint"):
        JointGroups((), ("t",), ("a",))
    with pytest.raises(ValueError, match=r"a joint drives one synergy only: \['x'\]"):
        JointGroups(("x",), ("x",), ("a",))
    with pytest.raises(ValueError, match="cutoff 31.0 Hz must lie between 0 and half the glove rate 60.0 Hz"):
        TargetFilter(cutoff_hz=31.0)
