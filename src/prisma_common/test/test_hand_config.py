"""HandConfig: the per-hand directory's files round-trip, merge by motor/finger, report a bad file
by name and value, and are written whole or not at all."""
from __future__ import annotations

import errno
import math
import os
from pathlib import Path

import numpy as np
import pytest
import yaml

from prisma_common.hand_config import (
    FORCE_BIAS_FILE,
    MOTOR_ZEROS_FILE,
    HandConfig,
    HandConfigError,
    default_hand_config_dir,
    launch_hand_config,
)


def leftovers(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir() if ".partial-" in p.name)


@pytest.fixture
def hand(tmp_path):
    return HandConfig(tmp_path / "hand", writer="test-writer")


def test_default_directory_follows_xdg_and_the_namespace(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "xdg"))
    assert default_hand_config_dir() == tmp_path / "xdg" / "prisma_hand" / "default"
    assert default_hand_config_dir("/left") == tmp_path / "xdg" / "prisma_hand" / "left"
    assert default_hand_config_dir("right/") == tmp_path / "xdg" / "prisma_hand" / "right"
    # parts joined with a character no ROS name has: never another hand's subdirectory
    assert default_hand_config_dir("/lab/left") == tmp_path / "xdg" / "prisma_hand" / "lab.left"
    monkeypatch.setenv("XDG_CONFIG_HOME", "relative/dir")  # ignored, as the XDG spec says
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert default_hand_config_dir("left") == tmp_path / "home" / ".config" / "prisma_hand" / "left"
    monkeypatch.delenv("XDG_CONFIG_HOME")
    assert default_hand_config_dir() == tmp_path / "home" / ".config" / "prisma_hand" / "default"


def test_launch_argument_auto_is_the_default_directory_on_hardware_only(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "xdg"))
    assert launch_hand_config("auto", "/left", simulated=False) == str(tmp_path / "xdg" / "prisma_hand" / "left")
    assert launch_hand_config("auto", "", simulated=False) == str(tmp_path / "xdg" / "prisma_hand" / "default")
    assert launch_hand_config("auto", "left", simulated=True) == ""  # sim runs start from the shipped config
    assert launch_hand_config("none", "left", simulated=False) == ""
    assert launch_hand_config("", "", simulated=False) == ""
    monkeypatch.chdir(tmp_path)
    assert launch_hand_config("hands/pad7", "left", simulated=True) == str(tmp_path / "hands" / "pad7")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert launch_hand_config("~/hand", "", simulated=False) == str(tmp_path / "home" / "hand")


def test_nothing_saved_reads_empty_and_creates_nothing(hand):
    assert hand.motor_zeros() == {}
    assert hand.force_bias() == {}
    assert hand.bundles() == {}
    assert not hand.root.exists()
    with pytest.raises(HandConfigError, match="empty"):
        HandConfig("  ")


def test_motor_zeros_round_trip_with_who_and_when(hand):
    path = hand.save_motor_zeros({"fingers": 2071, "thumb_flexion": np.int32(-312), "thumb_rotation": 1_048_000},
                                 note="homing")
    assert path == hand.root / MOTOR_ZEROS_FILE
    assert HandConfig(hand.root).motor_zeros() == {"fingers": 2071, "thumb_flexion": -312,
                                                   "thumb_rotation": 1_048_000}
    document = yaml.safe_load(path.read_text())
    assert document["written_by"] == "test-writer"
    assert document["written_at"].endswith("+00:00")
    assert document["motor_zeros"]["fingers"]["note"] == "homing"
    assert document["motor_zeros"]["fingers"]["written_by"] == "test-writer"


def test_saves_merge_by_motor_and_keep_the_other_motors_entries(hand):
    hand.save_motor_zeros({"fingers": 2071, "thumb_flexion": -312}, note="first homing")
    before = yaml.safe_load((hand.root / MOTOR_ZEROS_FILE).read_text())["motor_zeros"]["thumb_flexion"]
    HandConfig(hand.root, writer="second").save_motor_zeros({"fingers": 2080}, note="rehomed fingers")
    assert hand.motor_zeros() == {"fingers": 2080, "thumb_flexion": -312}
    entries = yaml.safe_load((hand.root / MOTOR_ZEROS_FILE).read_text())["motor_zeros"]
    assert entries["thumb_flexion"] == before  # untouched: its own note, writer and date
    assert entries["fingers"]["note"] == "rehomed fingers"
    assert entries["fingers"]["written_by"] == "second"


@pytest.mark.parametrize("zeros, named", [({"pinky": 10}, "'pinky'"), ({"fingers": 20.5}, "20.5"),
                                          ({"fingers": True}, "True"), ({"fingers": 2**31}, "2147483648")])
def test_bad_zeros_are_refused_before_anything_is_written(hand, zeros, named):
    with pytest.raises(HandConfigError, match=named):
        hand.save_motor_zeros(zeros)
    assert not hand.root.exists()


@pytest.mark.parametrize("text, named", [
    ("motor_zeros: {fingers: {ticks: 2071}\n", "not valid YAML"),
    ("motor_zeros:\n  fingers: {ticks: twenty}\n", "motor_zeros fingers = 'twenty'"),
    ("motor_zeros:\n  fingers: 2071\n", "motor_zeros fingers must be a mapping, got 2071"),
    ("motor_zeros:\n  middle_finger: {ticks: 3}\n", "'middle_finger' is not one of fingers"),
    ("motor_zeros:\n  fingers: {note: x}\n", "fingers has no 'ticks'"),
    ("- 1\n- 2\n", "expected a mapping"),
])
def test_a_corrupt_file_is_reported_by_name_and_value_and_not_overwritten(hand, text, named):
    hand.root.mkdir()
    path = hand.root / MOTOR_ZEROS_FILE
    path.write_text(text)
    for attempt in (hand.motor_zeros, lambda: hand.save_motor_zeros({"thumb_rotation": 5})):
        with pytest.raises(HandConfigError) as caught:
            attempt()
        assert str(path) in str(caught.value)
        assert named in str(caught.value)
    assert path.read_text() == text  # the damaged file stays for the operator to look at


def test_bad_yaml_error_names_the_line(hand):
    hand.root.mkdir()
    (hand.root / MOTOR_ZEROS_FILE).write_text("written_by: x\nmotor_zeros:\n  fingers: {ticks: [1, 2}\n")
    with pytest.raises(HandConfigError, match="not valid YAML at line 3"):
        hand.motor_zeros()


@pytest.mark.parametrize("fail", ["write", "rename"])
def test_a_failed_write_leaves_the_old_file_whole_and_nothing_half_written(hand, monkeypatch, fail):
    hand.save_motor_zeros({"fingers": 2071})
    old = (hand.root / MOTOR_ZEROS_FILE).read_text()
    if fail == "write":
        real_write = Path.write_text

        def disk_full(self, data, *args, **kwargs):
            real_write(self, data[: len(data) // 2], *args, **kwargs)  # half of it reaches the disk
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        monkeypatch.setattr(Path, "write_text", disk_full)
    else:
        def no_rename(src, dst):
            raise OSError(errno.EACCES, os.strerror(errno.EACCES))
        monkeypatch.setattr(os, "replace", no_rename)
    with pytest.raises(HandConfigError) as caught:
        hand.save_motor_zeros({"fingers": 9999, "thumb_rotation": 7})
    monkeypatch.undo()
    assert str(hand.root / MOTOR_ZEROS_FILE) in str(caught.value) or "cannot" in str(caught.value)
    assert "hand_config:=" in str(caught.value)
    assert (hand.root / MOTOR_ZEROS_FILE).read_text() == old
    assert hand.motor_zeros() == {"fingers": 2071}
    assert leftovers(hand.root) == []


def test_force_bias_round_trip_merges_by_finger_and_keeps_nan_axes(hand):
    cnn2 = "/opt/bundles/cnn2"
    hand.save_force_bias({"thumb": [0.1, -0.02, 0.35, math.nan, math.nan, math.nan],
                          "index": np.array([0.0, 0.0, -0.125, 0.0, 0.0, 0.0])},
                         {"thumb": cnn2, "index": cnn2}, samples=100, note="bench")
    hand.save_force_bias({"index": [0.0, 0.0, -0.25, 0.0, 0.0, 0.0]}, {"index": "/other"}, samples=50)
    bias = HandConfig(hand.root).force_bias()
    assert sorted(bias) == ["index", "thumb"]
    assert bias["thumb"].offset[:3] == (0.1, -0.02, 0.35)
    assert all(math.isnan(v) for v in bias["thumb"].offset[3:])
    assert (bias["thumb"].bundle, bias["thumb"].samples) == (cnn2, 100)
    assert bias["index"].offset[2] == -0.25
    assert (bias["index"].bundle, bias["index"].samples) == ("/other", 50)


@pytest.mark.parametrize("entry, named", [
    ("{offset: [1, 2, 3], bundle: b, samples: 100}", "offset = [1, 2, 3] is not 6 numbers"),
    ("{offset: [0, 0, .inf, 0, 0, 0], bundle: b, samples: 100}", "offset = [0, 0, inf"),
    ("{offset: [0, 0, 0, 0, 0, 0], samples: 100}", "bundle = None"),
    ("{offset: [0, 0, 0, 0, 0, 0], bundle: b, samples: 0}", "samples = 0"),
])
def test_a_bad_bias_entry_is_reported_by_name_and_value(hand, entry, named):
    hand.root.mkdir()
    (hand.root / FORCE_BIAS_FILE).write_text(f"force_bias:\n  ring: {entry}\n")
    with pytest.raises(HandConfigError, match="force_bias ring") as caught:
        hand.force_bias()
    assert named in str(caught.value)


def test_a_bundle_is_copied_in_whole_or_referenced(hand, tmp_path):
    source = tmp_path / "trained" / "cnn2_pad7"
    source.mkdir(parents=True)
    (source / "model.pt").write_bytes(b"weights")
    (source / "metadata.json").write_text("{}")
    copied = hand.save_bundle("thumb", source, note="pad 7")
    assert copied == hand.root / "bundles" / "thumb"
    assert (copied / "model.pt").read_bytes() == b"weights"
    (source / "model.pt").write_bytes(b"retrained")  # the copy does not follow the source
    assert hand.save_bundle("index", source, copy=False) == source
    assert HandConfig(hand.root).bundles() == {"thumb": copied, "index": source}
    assert (copied / "model.pt").read_bytes() == b"weights"
    # the directory moves as a whole: relative entries follow it
    moved = tmp_path / "moved"
    hand.root.rename(moved)
    assert HandConfig(moved).bundles()["thumb"] == moved / "bundles" / "thumb"
    with pytest.raises(HandConfigError, match="'nowhere' is not a directory"):
        HandConfig(moved).save_bundle("ring", "nowhere")
    with pytest.raises(HandConfigError, match="'palm' is not one of"):
        HandConfig(moved).save_bundle("palm", source)
