"""Glove networks: the paper's trunk at width 64, the width multiplier, the N-branch fusion, the
warm start, bundles, and a few training steps."""
import json

import numpy as np
import pytest
import torch

from stag_glove.bundle import BundleError, load_bundle, save_bundle
from stag_glove.models import TouchNet, Trunk, WeightNet, init_combination_from_single, parameter_count
from stag_glove.training import LinearBaseline, TrainConfig, grams_to_target, target_to_grams, train_classifier


def test_paper_trunk_shapes_and_size():
    trunk = Trunk(64)
    out = trunk(torch.zeros(2, 1, 32, 32))
    assert out.shape == (2, 128, 8, 8)  # conv 64, maxpool -> 16x16, layer1 64, layer2 128 stride 2
    # stem conv 576 + BN 128; layer1: 4 convs 64x64x9 + 4 BN; layer2: 128 chans incl. 1x1 downsample
    expected = 576 + 128 + 4 * (64 * 64 * 9 + 128) + (64 * 128 * 9 + 256) + 3 * (128 * 128 * 9 + 256) + (64 * 128 + 256)
    assert parameter_count(trunk) == expected
    assert isinstance(trunk.dropout, torch.nn.Dropout2d) and trunk.dropout.p == 0.2


def test_n_frame_net_concatenates_shared_branches():
    net = TouchNet(n_classes=27, n_frames=8, width=64)
    assert net.combination.in_channels == 8 * 128 and net.combination.out_channels == 128
    assert net.classifier.in_features == 128
    assert net(torch.zeros(3, 8, 32, 32)).shape == (3, 27)
    with pytest.raises(ValueError, match=r"\[batch, 8, 32, 32\]"):
        net(torch.zeros(3, 2, 32, 32))
    small = TouchNet(27, 8, width=16)
    assert small.combination.in_channels == 8 * 32
    assert parameter_count(small) < parameter_count(net) / 10


def test_branches_share_weights_so_frame_order_only_moves_channels():
    torch.manual_seed(0)
    net = TouchNet(5, 2, width=8).eval()
    x = torch.rand(1, 2, 32, 32)
    feats = net.branch_features(x)
    swapped = net.branch_features(x.flip(1))
    torch.testing.assert_close(feats[:, :16], swapped[:, 16:])


def test_warm_start_equals_averaging_the_single_frame_branches():
    torch.manual_seed(0)
    single = TouchNet(6, 1, width=8).eval()
    multi = TouchNet(6, 4, width=8).eval()
    init_combination_from_single(multi, single)
    x = torch.rand(2, 4, 32, 32)
    with torch.no_grad():
        fused = torch.stack([single.combination(single.trunk(x[:, i:i + 1])) for i in range(4)]).mean(0)
        expected = single.classifier(torch.flatten(single.pool(fused), 1))
        torch.testing.assert_close(multi(x), expected, rtol=1e-5, atol=1e-5)


def test_weight_net_and_log_target():
    net = WeightNet(width=8)
    assert net(torch.zeros(4, 32, 32)).shape == (4,)
    np.testing.assert_allclose(target_to_grams(grams_to_target(np.array([15.0, 1000.0]))), [15.0, 1000.0], rtol=1e-6)
    base = LinearBaseline.fit(np.array([1.0, 2.0, 3.0]), np.array([10.0, 20.0, 30.0]))
    assert base.predict(np.array([4.0]))[0] == pytest.approx(40.0)


def test_a_few_training_steps_reduce_the_loss():
    rng = np.random.default_rng(0)
    frames = torch.from_numpy(rng.random((64, 32, 32)).astype(np.float32) * 0.2)
    labels = np.repeat([0, 1], 32)
    frames[labels == 1, 5:10, 5:10] += 0.8  # class 1 presses one spot
    tuples = np.arange(64)[:, None]
    net = TouchNet(2, 1, width=4)
    history = train_classifier(net, frames, lambda e: (tuples, labels), TrainConfig(width=4, epochs=5, batch_size=16))
    assert history[-1]["loss"] < history[0]["loss"]
    assert history[-1]["train_top1"] > 0.75


def test_bundle_round_trip_and_mismatch_errors(tmp_path):
    net = TouchNet(3, 2, width=4)
    meta = {"width": 4, "n_frames": 2, "labels": ["a", "b", "c"]}
    save_bundle(tmp_path / "obj", "object", net, meta)
    bundle = load_bundle(tmp_path / "obj", kind="object")
    assert bundle.labels == ["a", "b", "c"] and bundle.n_frames == 2
    x = torch.rand(1, 2, 32, 32)
    net.eval()
    torch.testing.assert_close(bundle.model(x), net(x))
    with pytest.raises(BundleError, match="expected 'pose'"):
        load_bundle(tmp_path / "obj", kind="pose")
    wrong = json.loads((tmp_path / "obj" / "metadata.json").read_text())
    wrong["n_frames"] = 8
    (tmp_path / "obj" / "metadata.json").write_text(json.dumps(wrong))
    with pytest.raises(BundleError, match=r"model.pt does not match its metadata \(width 4, 8 frames, 3 classes\).*"
                                          r"combination.weight: expected \(8, 64, 1, 1\), file has \(8, 16, 1, 1\)"):
        load_bundle(tmp_path / "obj")
    with pytest.raises(BundleError, match="nothing does not exist"):
        load_bundle(tmp_path / "nothing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(BundleError, match="missing metadata.json"):
        load_bundle(tmp_path / "empty")
    (tmp_path / "obj" / "model.pt").write_bytes(b"not a model")
    with pytest.raises(BundleError, match="cannot be read"):
        load_bundle(tmp_path / "obj")
