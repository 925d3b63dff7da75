"""The four taxel-to-wrench networks of the PRISMA Hand II sensor paper (docs/force_estimation.md).

Every network takes the 9 taxel voltages of one fingertip as a 1-channel 3x3 image, shape
[B, 1, 3, 3], where image[row, col] is taxel i = 3*row + col (row 0 = bottom, column 0 = right
lateral side). Inputs and outputs are normalised (see normalisation.py); the networks never see
volts or newtons.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from .wrench import WRENCH_AXES

FORCE_AXES = ("fx", "fy", "fz")
@dataclass(frozen=True)
class ModelSpec:
    kind: str
    axes: tuple[str, ...]
    description: str


MODEL_SPECS: dict[str, ModelSpec] = {
    "ann": ModelSpec("ann", FORCE_AXES, "dense 9-64-64-3, sigmoid hidden activations"),
    "cnn": ModelSpec("cnn", FORCE_AXES, "conv 256, conv 64 (3x3 s1 p1, ReLU), maxpool 2 s2 p1, dense 16, 3 outputs"),
    "cnn_t": ModelSpec("cnn_t", WRENCH_AXES, "CNN with 6 outputs (force and torque)"),
    "cnn2": ModelSpec("cnn2", WRENCH_AXES, "conv 128, 64, 32, 32, 16 (3x3 s1 p1, ReLU), dense 16, 6 outputs"),
}
MODEL_KINDS = tuple(MODEL_SPECS)


def taxel_image(voltages: torch.Tensor) -> torch.Tensor:
    """[B, 9] taxel vector -> [B, 1, 3, 3] image; row-major reshape keeps i = 3*row + col."""
    return voltages.reshape(-1, 1, 3, 3)


def _conv_relu(in_channels: int, out_channels: int) -> list[nn.Module]:
    return [nn.Conv2d(in_channels, out_channels, kernel_size=3, stride=1, padding=1), nn.ReLU()]


class ANN(nn.Module):
    """Fully connected network with sigmoid hidden units (the paper's baseline)."""

    def __init__(self, outputs: int = 3, hidden: tuple[int, ...] = (64, 64)) -> None:
        super().__init__()
        layers: list[nn.Module] = [nn.Flatten()]
        width = 9
        for size in hidden:
            layers += [nn.Linear(width, size), nn.Sigmoid()]
            width = size
        layers.append(nn.Linear(width, outputs))
        self.net = nn.Sequential(*layers)

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        return self.net(image)


class CNN(nn.Module):
    """conv 256 -> conv 64 -> max-pool -> dense 16 -> outputs (3 for CNN, 6 for CNN_T).

    Max-pool 2x2 stride 2 with padding 1 turns the 3x3 map into 2x2, so the dense layer sees
    64 * 2 * 2 = 256 features.
    """

    def __init__(self, outputs: int = 3) -> None:
        super().__init__()
        self.features = nn.Sequential(
            *_conv_relu(1, 256),
            *_conv_relu(256, 64),
            nn.MaxPool2d(kernel_size=2, stride=2, padding=1),
        )
        self.head = nn.Sequential(nn.Flatten(), nn.Linear(64 * 2 * 2, 16), nn.ReLU(), nn.Linear(16, outputs))

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(image))


class CNN2(nn.Module):
    """Five 3x3 conv layers (128, 64, 32, 32, 16) -> dense 16 -> 6 outputs.

    No pooling: the 3x3 map is already small and the paper lists none for CNN2, so the dense
    layer sees all 16 * 3 * 3 = 144 features.
    """

    def __init__(self, outputs: int = 6) -> None:
        super().__init__()
        widths = (1, 128, 64, 32, 32, 16)
        layers: list[nn.Module] = []
        for in_channels, out_channels in zip(widths[:-1], widths[1:]):
            layers += _conv_relu(in_channels, out_channels)
        self.features = nn.Sequential(*layers)
        self.head = nn.Sequential(nn.Flatten(), nn.Linear(16 * 3 * 3, 16), nn.ReLU(), nn.Linear(16, outputs))

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(image))


def build_model(kind: str) -> nn.Module:
    """A freshly initialised network of `kind` (one of MODEL_KINDS)."""
    if kind not in MODEL_SPECS:
        raise ValueError(f"unknown model kind {kind!r}; expected one of {list(MODEL_KINDS)}")
    outputs = len(MODEL_SPECS[kind].axes)
    if kind == "ann":
        return ANN(outputs)
    if kind in ("cnn", "cnn_t"):
        return CNN(outputs)
    return CNN2(outputs)


def parameter_count(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
