"""The force_estimator's use of the hand directory: which bundle each finger runs, which saved bias
applies at start, and what ~/bias saves and says."""
from __future__ import annotations

import shutil

import numpy as np
import pytest

from prisma_common.hand_config import FORCE_BIAS_FILE, HandConfig, HandConfigError
from prisma_force_estimator.bias import BiasResult, WrenchBias
from prisma_force_estimator.hand_directory import open_hand_config, plan_start, same_bundle, save_bias


def fake_bundle(path, weights=b"weights"):
    path.mkdir(parents=True)
    (path / "model.pt").write_bytes(weights)
    (path / "metadata.json").write_text('{"kind": "cnn2"}')
    return path


@pytest.fixture
def shipped(tmp_path):
    return fake_bundle(tmp_path / "shipped")


def test_no_hand_directory_is_the_shipped_config(shipped):
    assert open_hand_config("") is None
    plan = plan_start(["thumb", "index"], {"index": ""}, str(shipped), None)
    assert plan.bundles == {"thumb": str(shipped), "index": str(shipped)}
    assert plan.offsets == {} and plan.notes == []


def test_bundle_order_parameter_then_hand_directory_then_model_bundle(tmp_path, shipped):
    hand = HandConfig(tmp_path / "hand")
    pad7 = hand.save_bundle("thumb", fake_bundle(tmp_path / "pad7", b"pad 7"))
    hand.save_bundle("index", fake_bundle(tmp_path / "pad3", b"pad 3"))
    explicit = fake_bundle(tmp_path / "explicit")
    plan = plan_start(["thumb", "index", "ring"], {"index": str(explicit)}, str(shipped), hand)
    assert plan.bundles == {"thumb": str(pad7), "index": str(explicit), "ring": str(shipped)}
    assert plan.notes == [f"thumb: bundle {pad7} (hand directory bundles.yaml)",
                          f"index: bundle from finger_bundles.index, not the hand directory's "
                          f"{hand.root / 'bundles' / 'index'}"]


def test_a_saved_bias_applies_only_to_the_network_it_was_taken_with(tmp_path, shipped):
    hand = HandConfig(tmp_path / "hand")
    copy = tmp_path / "copy_of_shipped"
    shutil.copytree(shipped, copy)
    other = fake_bundle(tmp_path / "other", b"other weights")
    hand.save_force_bias({"thumb": [0, 0, 0.125, 0, 0, 0], "index": [0, 0, -0.5, 0, 0, 0],
                          "ring": [0, 0, 1.0, 0, 0, 0]},
                         {"thumb": str(copy), "index": str(other), "ring": str(shipped)}, samples=100)
    plan = plan_start(["thumb", "index", "middle"], {}, str(shipped), hand)
    assert same_bundle(copy, shipped) and not same_bundle(other, shipped)
    assert list(plan.offsets) == ["thumb"]  # same files in another directory: the same network
    np.testing.assert_array_equal(plan.offsets["thumb"], [0, 0, 0.125, 0, 0, 0])
    assert any(n.startswith("thumb: saved bias Fz +0.1250 N from 20") for n in plan.notes)
    assert (f"index: saved bias not applied: taken with {other}, this run uses {shipped}; take ~/bias again"
            in plan.notes)
    shutil.rmtree(copy)  # a bias whose bundle is gone cannot be shown to match
    assert plan_start(["thumb"], {}, str(shipped), hand).offsets == {}


def test_a_bad_hand_file_stops_the_start_naming_it(tmp_path, shipped):
    hand = HandConfig(tmp_path / "hand")
    hand.root.mkdir()
    (hand.root / FORCE_BIAS_FILE).write_text("force_bias:\n  thumb: {offset: oops, bundle: x, samples: 3}\n")
    with pytest.raises(HandConfigError, match=f"{hand.root / FORCE_BIAS_FILE}: force_bias thumb offset = 'oops'"):
        plan_start(["thumb"], {}, str(shipped), hand)


def taken_bias(fingers, fz):
    bias = WrenchBias(fingers, samples=2)
    for finger in fingers:
        for _ in range(2):
            bias.observe(finger, np.full(9, 0.43), np.array([0, 0, fz, 0, 0, 0], dtype=np.float64))
    return bias, bias.take()


def test_bias_is_saved_where_the_message_says_and_restored(tmp_path, shipped):
    hand = HandConfig(tmp_path / "hand")
    bias, result = taken_bias(["thumb", "index"], 0.25)
    saved = save_bias(hand, bias, result, {"thumb": str(shipped), "index": str(shipped)})
    assert saved.success and not saved.warning
    assert saved.message == f"biased over 2 samples: thumb Fz +0.2500 N; index Fz +0.2500 N; saved to " \
                            f"{hand.root / FORCE_BIAS_FILE}"
    plan = plan_start(["thumb", "index"], {}, str(shipped), HandConfig(hand.root))
    restored = WrenchBias(["thumb"], samples=2)
    restored.restore(plan.offsets)  # a finger this node does not serve is left out
    assert list(restored.offsets) == ["thumb"]
    np.testing.assert_allclose(restored.apply("thumb", np.array([0, 0, 1.0, 0, 0, 0])), [0, 0, 0.75, 0, 0, 0])


def test_refused_or_unsaved_bias(tmp_path, shipped):
    refused = BiasResult(False, "refused: in contact")
    assert save_bias(HandConfig(tmp_path / "hand"), WrenchBias(["thumb"]), refused, {}) is refused
    assert not (tmp_path / "hand").exists()
    bias, result = taken_bias(["thumb"], 0.5)
    assert save_bias(None, bias, result, {"thumb": str(shipped)}) is result
    blocker = tmp_path / "a_file"
    blocker.write_text("not a directory")
    failed = save_bias(HandConfig(blocker / "hand"), bias, result, {"thumb": str(shipped)})
    assert failed.success and failed.warning  # the bias is in use; only the save failed
    assert failed.message.startswith("biased over 2 samples: thumb Fz +0.5000 N; NOT saved: ")
    assert str(blocker) in failed.message and "hand_config:=" in failed.message
