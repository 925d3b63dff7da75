"""STAG perception networks (docs/glove.md): the shared per-frame trunk, the N-frame
classifier and the single-frame weight regressor.

The trunk follows the STAG reference code: conv 3x3 s1 p1 -> BN -> ReLU -> maxpool(3, 2, 1) ->
ResNet layer1 (2 basic blocks, `width` channels) -> Dropout2d -> ResNet layer2 (2 basic blocks,
2*width channels, stride 2). `width=64` is the paper's network; smaller widths keep the same
topology with fewer channels so it trains on a CPU (docs/glove.md says which width made which
number).
"""
from __future__ import annotations

import torch
from torch import nn

PAPER_WIDTH = 64
FRAME_SHAPE = (32, 32)


class BasicBlock(nn.Module):
    """ResNet basic block (two 3x3 convs with a residual connection)."""

    def __init__(self, in_channels: int, channels: int, stride: int = 1) -> None:
        super().__init__()
        self.conv1 = nn.Conv2d(in_channels, channels, 3, stride=stride, padding=1, bias=False)
        self.bn1 = nn.BatchNorm2d(channels)
        self.conv2 = nn.Conv2d(channels, channels, 3, stride=1, padding=1, bias=False)
        self.bn2 = nn.BatchNorm2d(channels)
        self.relu = nn.ReLU(inplace=True)
        self.downsample: nn.Module | None = None
        if stride != 1 or in_channels != channels:
            self.downsample = nn.Sequential(
                nn.Conv2d(in_channels, channels, 1, stride=stride, bias=False),
                nn.BatchNorm2d(channels),
            )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        residual = x if self.downsample is None else self.downsample(x)
        out = self.relu(self.bn1(self.conv1(x)))
        out = self.bn2(self.conv2(out))
        return self.relu(out + residual)


def _layer(in_channels: int, channels: int, stride: int) -> nn.Sequential:
    return nn.Sequential(BasicBlock(in_channels, channels, stride), BasicBlock(channels, channels))


class Trunk(nn.Module):
    """Per-frame feature extractor: [B, 1, 32, 32] -> [B, 2*width, 8, 8]."""

    def __init__(self, width: int = PAPER_WIDTH, dropout: float = 0.2) -> None:
        super().__init__()
        if width < 1:
            raise ValueError(f"trunk width must be >= 1, got {width}")
        self.width = width
        self.stem = nn.Sequential(
            nn.Conv2d(1, width, 3, stride=1, padding=1, bias=False),
            nn.BatchNorm2d(width),
            nn.ReLU(inplace=True),
            nn.MaxPool2d(kernel_size=3, stride=2, padding=1),
        )
        self.layer1 = _layer(width, width, 1)
        self.dropout = nn.Dropout2d(dropout)
        self.layer2 = _layer(width, 2 * width, 2)

    @property
    def out_channels(self) -> int:
        return 2 * self.width

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.layer2(self.dropout(self.layer1(self.stem(x))))


class TouchNet(nn.Module):
    """N-frame classifier: N weight-sharing trunk branches, concatenated, 1x1 conv to 2*width,
    global average pool, linear to classes. Input [B, N, 32, 32] -> logits [B, classes]."""

    def __init__(self, n_classes: int, n_frames: int = 1, width: int = PAPER_WIDTH,
                 dropout: float = 0.2) -> None:
        super().__init__()
        if n_frames < 1:
            raise ValueError(f"n_frames must be >= 1, got {n_frames}")
        if n_classes < 2:
            raise ValueError(f"n_classes must be >= 2, got {n_classes}")
        self.n_frames = n_frames
        self.n_classes = n_classes
        self.trunk = Trunk(width, dropout)
        channels = self.trunk.out_channels
        self.combination = nn.Conv2d(channels * n_frames, channels, kernel_size=1)
        self.pool = nn.AdaptiveAvgPool2d(1)
        self.classifier = nn.Linear(channels, n_classes)

    def branch_features(self, frames: torch.Tensor) -> torch.Tensor:
        """Trunk features of every frame: [B, N, 32, 32] -> [B, N*C, 8, 8] (branches share weights,
        so all frames go through the trunk as one batch)."""
        b, n = frames.shape[:2]
        features = self.trunk(frames.reshape(b * n, 1, *frames.shape[2:]))
        return features.reshape(b, n * features.shape[1], *features.shape[2:])

    def head(self, features: torch.Tensor) -> torch.Tensor:
        """Fusion and classification from concatenated branch features [B, N*C, H, W]."""
        return self.classifier(torch.flatten(self.pool(self.combination(features)), 1))

    def forward(self, frames: torch.Tensor) -> torch.Tensor:
        if frames.dim() != 4 or frames.shape[1] != self.n_frames:
            raise ValueError(
                f"expected input [batch, {self.n_frames}, 32, 32], got {list(frames.shape)}")
        return self.head(self.branch_features(frames))


class WeightNet(nn.Module):
    """Single-frame regressor of log(grams): trunk, global average pool, linear to 1."""

    def __init__(self, width: int = PAPER_WIDTH, dropout: float = 0.2) -> None:
        super().__init__()
        self.trunk = Trunk(width, dropout)
        self.pool = nn.AdaptiveAvgPool2d(1)
        self.fc = nn.Linear(self.trunk.out_channels, 1)

    def forward(self, frames: torch.Tensor) -> torch.Tensor:
        if frames.dim() == 3:
            frames = frames.unsqueeze(1)
        if frames.dim() != 4 or frames.shape[1] != 1:
            raise ValueError(f"expected input [batch, 1, 32, 32], got {list(frames.shape)}")
        return self.fc(torch.flatten(self.pool(self.trunk(frames)), 1)).squeeze(1)


def init_combination_from_single(net: TouchNet, single: TouchNet) -> None:
    """Warm start an N-frame net from a trained 1-frame net of the same width: copy the trunk and
    classifier, and make the 1x1 fusion conv the average of the branches passed through the 1-frame
    fusion conv. Before any further training the N-frame net then equals averaging the 1-frame
    net's fused features over its N inputs."""
    net.trunk.load_state_dict(single.trunk.state_dict())
    net.classifier.load_state_dict(single.classifier.state_dict())
    with torch.no_grad():
        w = single.combination.weight  # [C, C, 1, 1]
        net.combination.weight.copy_(torch.cat([w] * net.n_frames, dim=1) / net.n_frames)
        bias, single_bias = net.combination.bias, single.combination.bias
        assert bias is not None and single_bias is not None  # Conv2d with its default bias=True
        bias.copy_(single_bias)


def parameter_count(module: nn.Module) -> int:
    return sum(p.numel() for p in module.parameters())
