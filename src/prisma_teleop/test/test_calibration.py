"""The operator's calibration: the normalisation it gives, its checks, and its YAML file (round trip,
written whole, every bad file named with the entry and the value)."""
from __future__ import annotations

import math
import os
import re
from pathlib import Path

import pytest
import yaml

from prisma_teleop.calibration import (
    MIN_SPAN_RAD,
    CalibrationError,
    OperatorCalibration,
    load_calibration,
    save_calibration,
    unwritable,
)
from prisma_teleop.retargeting import DEFAULT_JOINTS, nominal_calibration

FLEX, OPPOSE = DEFAULT_JOINTS.flexion(), DEFAULT_JOINTS.thumb_opposition


def operator() -> OperatorCalibration:
    """A calibration unlike the nominal one in every value (so a round trip that lost one shows)."""
    nominal = nominal_calibration()
    return OperatorCalibration(**{pose: {j: a + 0.013 * (i + 1) + 0.001 * k for i, (j, a) in
                                         enumerate(nominal.pose(pose).items())}
                                  for k, pose in enumerate(("open_hand", "fist", "thumb_adducted", "thumb_opposed"))},
                               operator="alice")


def test_flexion_is_0_open_1_fist_linear_between_and_clipped():
    cal = OperatorCalibration(open_hand={"j": 0.2}, fist={"j": 1.2})
    assert [cal.flexion("j", a) for a in (0.2, 0.7, 1.2, -1.0, 5.0)] == pytest.approx([0.0, 0.5, 1.0, 0.0, 1.0],
                                                                                      abs=1e-12)
    reversed_glove = OperatorCalibration(open_hand={"j": 1.0}, fist={"j": -0.5})  # a glove counting the other way
    assert [reversed_glove.flexion("j", a) for a in (1.0, 0.25, -0.5)] == [0.0, 0.5, 1.0]


def test_opposition_is_piecewise_through_adducted_open_and_opposed():
    cal = OperatorCalibration(open_hand={"a": 0.4}, thumb_adducted={"a": 0.0}, thumb_opposed={"a": 1.4})
    assert [cal.opposition("a", x) for x in (0.0, 0.2, 0.4, 0.9, 1.4, -3.0, 3.0)] == pytest.approx(
        [-1.0, -0.5, 0.0, 0.5, 1.0, -1.0, 1.0], abs=1e-12)


def test_check_names_the_joint_and_what_to_capture():
    cal = nominal_calibration()
    cal.check(FLEX, OPPOSE)  # the nominal hand is complete
    too_close = cal.with_pose("fist", cal.fist | {"ring_pip": MIN_SPAN_RAD / 2})
    with pytest.raises(CalibrationError, match=r"ring_pip: fist 0\.050 rad and open hand 0\.000 rad are less than "
                                               r"0\.1 rad apart; capture the open hand and the fist again"):
        too_close.check(FLEX, OPPOSE)
    same_side = cal.with_pose("thumb_adducted", cal.thumb_adducted | {"thumb_cmc_abduction": 0.9})
    with pytest.raises(CalibrationError, match="thumb_cmc_abduction: thumb adducted 0.900 rad and opposed 1.222 rad "
                                               "must lie on either side of the open hand's 0.349 rad"):
        same_side.check(FLEX, OPPOSE)
    missing = cal.with_pose("fist", {j: a for j, a in cal.fist.items() if j != "index_dip"})
    with pytest.raises(CalibrationError, match="index_dip: not in the captured fist"):
        missing.check(FLEX, OPPOSE)


def test_yaml_round_trip(tmp_path):
    cal = operator()
    path = save_calibration(cal, tmp_path / "operators" / "alice.yaml")  # the folder is made
    assert path == tmp_path / "operators" / "alice.yaml"
    back = load_calibration(path)
    assert back == cal
    document = yaml.safe_load(path.read_text())
    assert document["format"] == "prisma_teleop_calibration" and document["version"] == 1
    assert "pid" in document["written_by"] and document["written_at"].endswith("+00:00")
    assert sorted(p.name for p in path.parent.iterdir()) == ["alice.yaml"]  # nothing staged left behind


def test_a_failed_write_leaves_the_old_file(tmp_path, monkeypatch):
    path = save_calibration(operator(), tmp_path / "alice.yaml")
    before = path.read_text()
    write_text = Path.write_text

    def disk_full(self, text, *args, **kwargs):  # half the file reaches the disk, then it is full
        write_text(self, text[:40], *args, **kwargs)
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Path, "write_text", disk_full)
    with pytest.raises(CalibrationError, match=r"alice.yaml: cannot write the calibration \(\[Errno 28\] No space "
                                               r"left on device\); choose a writable calibration_file"):
        save_calibration(nominal_calibration(), path)
    assert path.read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["alice.yaml"]


@pytest.mark.parametrize("text,message", [
    ("format: [", "not valid YAML at line 1"),
    ("format: something_else\n", "not a prisma_teleop_calibration file"),
    ("format: prisma_teleop_calibration\nversion: 7\n", "version 7, this program reads version 1"),
    ("format: prisma_teleop_calibration\nversion: 1\nopen_hand: 3\n", "'open_hand' must map joint names to angles"),
    ("format: prisma_teleop_calibration\nversion: 1\nopen_hand: {a: 0.0}\nfist: {a: .nan}\n",
     r"fist.a = nan is not a finite angle in rad"),
    ("format: prisma_teleop_calibration\nversion: 1\nopen_hand: {a: zero}\n", "open_hand.a = 'zero' is not a finite"),
])
def test_a_bad_file_is_named_with_its_entry_and_value(tmp_path, text, message):
    path = tmp_path / "op.yaml"
    path.write_text(text)
    with pytest.raises(CalibrationError) as err:
        load_calibration(path)
    assert str(err.value).startswith(f"{path}: ")
    assert re.search(message, str(err.value)), str(err.value)


def test_a_missing_file_says_what_to_give(tmp_path):
    with pytest.raises(CalibrationError, match=r"cannot read the calibration \(\[Errno 2\] No such file or directory"
                                               r"\); give an existing calibration_file"):
        load_calibration(tmp_path / "nobody.yaml")


def test_nominal_calibration_of_a_gloves_own_joint_names():
    from prisma_teleop.retargeting import JointGroups

    joints = JointGroups(("f1", "f2"), ("t1",), ("abd",))
    cal = nominal_calibration(joints)
    cal.check(joints.flexion(), joints.thumb_opposition)
    assert cal.fist["f1"] == pytest.approx(math.pi / 2)
    assert (cal.thumb_adducted["abd"], cal.open_hand["abd"], cal.thumb_opposed["abd"]) == pytest.approx(
        (-math.pi / 4, 0.0, math.pi / 4))


def test_a_corrupt_file_says_to_fix_or_delete_it_not_to_capture(tmp_path):
    path = tmp_path / "op.yaml"
    path.write_text("format: [")
    with pytest.raises(CalibrationError) as err:
        load_calibration(path)
    assert str(err.value) == (f"{path}: not valid YAML at line 1; fix or delete {path} (without it the teleop node "
                              "starts with the nominal hand, and the ~/capture_* services write it anew), or give "
                              "another calibration_file")


def test_unwritable_says_why_before_any_capture(tmp_path):
    assert unwritable(tmp_path / "alice.yaml") is None
    assert unwritable(tmp_path / "new" / "dir" / "alice.yaml") is None  # save_calibration makes the folders
    assert not (tmp_path / "new").exists() and list(tmp_path.iterdir()) == []  # the probe leaves nothing
    a_file = tmp_path / "not_a_dir"
    a_file.write_text("")
    assert unwritable(a_file / "alice.yaml") == f"{a_file} is not a directory"
    assert unwritable(tmp_path) == f"{tmp_path} is a directory"
    if os.geteuid() != 0:  # root writes into a read-only folder all the same
        read_only = tmp_path / "ro"
        read_only.mkdir(mode=0o555)
        assert unwritable(read_only / "alice.yaml").startswith(f"cannot create a file in {read_only} ([Errno 13]")
