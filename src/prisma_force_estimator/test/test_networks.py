"""The four networks: architecture as docs/force_estimation.md lists it, shapes, taxel image layout."""
import pytest
import torch
from torch import nn

from prisma_force_estimator.networks import (
    ANN,
    CNN,
    CNN2,
    MODEL_KINDS,
    MODEL_SPECS,
    build_model,
    parameter_count,
    taxel_image,
)


def test_taxel_image_puts_taxel_i_at_row_i_div_3_col_i_mod_3():
    v = torch.arange(9, dtype=torch.float32).reshape(1, 9)
    image = taxel_image(v)
    assert image.shape == (1, 1, 3, 3)
    for i in range(9):
        assert image[0, 0, i // 3, i % 3] == i


@pytest.mark.parametrize("kind,outputs", [("ann", 3), ("cnn", 3), ("cnn_t", 6), ("cnn2", 6)])
def test_output_width_matches_axes(kind, outputs):
    model = build_model(kind)
    assert model(torch.zeros(4, 1, 3, 3)).shape == (4, outputs)
    assert len(MODEL_SPECS[kind].axes) == outputs


def _convs(model):
    return [m for m in model.modules() if isinstance(m, nn.Conv2d)]


def test_cnn_is_conv256_conv64_pool_dense16():
    model = build_model("cnn")
    assert isinstance(model, CNN)
    convs = _convs(model)
    assert [c.out_channels for c in convs] == [256, 64]
    for c in convs:
        assert c.kernel_size == (3, 3) and c.stride == (1, 1) and c.padding == (1, 1)
    pools = [m for m in model.modules() if isinstance(m, nn.MaxPool2d)]
    assert len(pools) == 1 and pools[0].kernel_size == 2 and pools[0].stride == 2 and pools[0].padding == 1
    # the pooled 3x3 map is 2x2
    assert model.features(torch.zeros(1, 1, 3, 3)).shape == (1, 64, 2, 2)
    dense = [m for m in model.modules() if isinstance(m, nn.Linear)]
    assert [d.out_features for d in dense] == [16, 3]
    assert all(isinstance(m, nn.ReLU) for m in model.features if not isinstance(m, (nn.Conv2d, nn.MaxPool2d)))


def test_cnn_t_is_the_cnn_with_six_outputs():
    cnn, cnn_t = build_model("cnn"), build_model("cnn_t")
    assert [c.out_channels for c in _convs(cnn_t)] == [256, 64]
    assert parameter_count(cnn_t) - parameter_count(cnn) == 3 * 16 + 3


def test_cnn2_has_five_convs_then_dense16():
    model = build_model("cnn2")
    assert isinstance(model, CNN2)
    assert [c.out_channels for c in _convs(model)] == [128, 64, 32, 32, 16]
    assert [d.out_features for d in model.modules() if isinstance(d, nn.Linear)] == [16, 6]


def test_ann_uses_sigmoid_hidden_units_only():
    model = build_model("ann")
    assert isinstance(model, ANN)
    activations = [m for m in model.modules() if isinstance(m, (nn.ReLU, nn.Sigmoid, nn.Tanh))]
    assert activations and all(isinstance(a, nn.Sigmoid) for a in activations)
    assert not _convs(model)


def test_unknown_kind_is_named():
    with pytest.raises(ValueError, match="'resnet'"):
        build_model("resnet")
    assert MODEL_KINDS == ("ann", "cnn", "cnn_t", "cnn2")
