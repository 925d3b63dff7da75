"""Inference core: taxel voltages of any number of fingertips -> wrench, in one batch.

Rows with a non-finite voltage are never passed to the network: they come back as NaN rows and
are counted in `rejected`, so one bad sample neither raises nor spoils its neighbours.

Precision ("float16", the default, or "float32"): a network made of 3x3-map convolutions, ReLUs,
Flatten and Linear layers (CNN2) is a chain of dense layers: a padded convolution on a 3x3 map is
a linear map of the 9*Cin inputs to the 9*Cout outputs. "float16" runs that chain with the
weights stored in float16 and packed once at load (fbgemm), activations and accumulation in
float32: 2.2-2.7x less CPU per five-finger call than the frozen TorchScript network when called
once per 10 ms scan (3x in a hot loop), forces within 1.3e-3 N of it on the held-out tests
(docs/force_estimation.md, "Inference precision"). "float32" is the bundle's own network,
frozen and optimised for inference. Networks that are not such a chain (CNN, CNN_T: max-pool;
ANN: sigmoid) and torch builds without fbgemm run in float32; `ForceEstimator.precision` says
which path runs.
"""
from __future__ import annotations

import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from .bundle import DEFAULT_PRECISION, PRECISIONS, BundleMetadata, load_bundle, quiet_jit
from .networks import taxel_image

__all__ = ["DEFAULT_PRECISION", "PRECISIONS", "Float16Chain", "ForceEstimator", "dense_layers", "set_torch_threads"]
# Input map of every network here: one channel, the 3x3 taxel image (networks.taxel_image).
_IMAGE_SHAPE = (1, 3, 3)
# A float16 chain whose outputs differ from the float32 network by more than this (normalised
# units, relative to the largest output) on the load-time probe is not used: a conversion error
# gives differences of order 1; float16 weights give 2e-4 on the default bundle.
_FLOAT16_PROBE_TOLERANCE = 1e-2


def set_torch_threads(threads: int) -> None:
    """Intra-op threads for torch CPU kernels; process-wide (a torch limitation)."""
    if int(threads) < 1:
        raise ValueError(f"torch threads must be >= 1, got {threads}")
    torch.set_num_threads(int(threads))


def _optimised(model: torch.nn.Module) -> torch.nn.Module:
    """Frozen, inference-optimised copy of a TorchScript module (~25% faster per five-finger
    call on one core; outputs agree to ~1e-7). Plain modules and builds where the optimisation
    is unavailable run as they are."""
    if not isinstance(model, torch.jit.ScriptModule):
        return model
    try:
        with quiet_jit():
            return torch.jit.optimize_for_inference(torch.jit.freeze(model))
    except Exception:  # optimisation passes differ between torch builds; correctness does not
        return model


DenseLayer = tuple[torch.Tensor, torch.Tensor, bool]  # weight [out, in], bias [out], ReLU after


def _kind(module: torch.nn.Module) -> str:
    # A loaded TorchScript submodule is a RecursiveScriptModule; original_name is its class.
    return str(getattr(module, "original_name", type(module).__name__))


def _conv_as_dense(conv: Any, shape: tuple[int, int, int]) -> tuple[torch.Tensor, torch.Tensor, tuple[int, int, int]]:
    """The [out, in] matrix and bias of a Conv2d on a `shape` (C, H, W) input, in float64.

    Column j of the matrix is the convolution of the j-th basis image (bias left out), so the
    matrix maps the channel-major flattened input (what Flatten gives) exactly; padding taps that
    fall outside the map are zero entries."""
    if getattr(conv, "padding_mode", "zeros") != "zeros":
        raise ValueError(f"padding mode {conv.padding_mode!r}")
    weight = conv.weight.detach().double()
    basis = torch.eye(int(np.prod(shape)), dtype=torch.float64).reshape(-1, *shape)
    out = F.conv2d(basis, weight, None, conv.stride, conv.padding, conv.dilation, conv.groups)
    out_shape = (int(out.shape[1]), int(out.shape[2]), int(out.shape[3]))
    bias = conv.bias.detach().double() if conv.bias is not None else torch.zeros(out_shape[0], dtype=torch.float64)
    matrix = out.reshape(out.shape[0], -1).T.contiguous()
    return matrix, bias.repeat_interleave(out_shape[1] * out_shape[2]), out_shape


def dense_layers(model: torch.nn.Module) -> list[DenseLayer] | None:
    """The network as a chain of dense layers in float64, or None where it is not one.

    Leaf modules are taken in registration order, which is the call order of the networks here
    (nn.Sequential stacks); ForceEstimator checks the chain against the network before using it,
    so a module whose forward calls them otherwise is caught, not run wrongly."""
    layers: list[DenseLayer] = []
    shape: tuple[int, ...] = _IMAGE_SHAPE
    for leaf in model.modules():
        if any(True for _ in leaf.children()):
            continue  # containers: their leaves follow
        kind = _kind(leaf)
        module: Any = leaf  # Conv2d / Linear / Flatten attributes, also on TorchScript modules
        try:
            if kind == "Conv2d":
                if len(shape) != 3:
                    return None
                weight, bias, shape = _conv_as_dense(module, shape)
                layers.append((weight, bias, False))
            elif kind == "Linear":
                weight = module.weight.detach().double()
                bias = (module.bias.detach().double() if module.bias is not None
                        else torch.zeros(weight.shape[0], dtype=torch.float64))
                layers.append((weight, bias, False))
                shape = (int(weight.shape[0]),)
            elif kind == "ReLU":
                if not layers or layers[-1][2]:
                    return None
                layers[-1] = (layers[-1][0], layers[-1][1], True)
            elif kind == "Flatten":
                # channel-major [C, H, W] -> C*H*W is the order the dense matrices already use
                if (getattr(module, "start_dim", 1), getattr(module, "end_dim", -1)) != (1, -1):
                    return None
                shape = (int(np.prod(shape)),)
            else:
                return None  # max-pool, sigmoid, ...: not a dense chain
        except (AttributeError, RuntimeError, ValueError):
            return None
    return layers or None


class Float16Chain:
    """A dense chain with float16 weights packed for fbgemm; float32 activations and accumulation.

    Its weights take about four times the float32 network's memory (1.9 MB for CNN2: the dense
    form of a padded 3x3 conv has 9x the kernel's entries, float16 halves them), yet a call is
    cheaper, hot or cold (docs/performance.md): one matrix product per layer on weights packed
    once at load.
    """

    def __init__(self, layers: list[DenseLayer]) -> None:
        self._layers: list[tuple[torch.Tensor, torch.Tensor, bool]] = []
        with _quiet_fbgemm():
            for weight, bias, relu in layers:
                packed = torch.fbgemm_pack_gemm_matrix_fp16(weight.float().contiguous())
                self._layers.append((packed, bias.float().contiguous(), relu))
        self.inputs = int(layers[0][0].shape[1])

    def __call__(self, image: torch.Tensor) -> torch.Tensor:
        x = image.reshape(image.shape[0], self.inputs)
        for packed, bias, relu in self._layers:
            x = torch.fbgemm_linear_fp16_weight(x, packed, bias)
            if relu:
                x.relu_()  # x is this layer's fresh output
        return x


@contextmanager
def _quiet_fbgemm() -> Iterator[None]:
    # torch marks the fbgemm float16 functions deprecated (one warning each per process, at the
    # first pack and the first product, both at load); torch 2.1-2.13 all have them, and a build
    # without them runs the float32 network.
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"fbgemm_\w+ is deprecated", category=UserWarning)
        yield


def _float16_chain(model: torch.nn.Module, reference: Callable[[torch.Tensor], torch.Tensor]) -> Float16Chain | None:
    """`model` as a Float16Chain, checked against `reference` (its float32 form) on a fixed probe;
    None where the network is no dense chain, fbgemm is missing or the check fails."""
    layers = dense_layers(model)
    if layers is None or int(layers[0][0].shape[1]) != int(np.prod(_IMAGE_SHAPE)):
        return None
    try:
        chain = Float16Chain(layers)
        probe = taxel_image(torch.from_numpy(np.random.default_rng(0).normal(size=(64, 9)).astype(np.float32)))
        with torch.inference_mode(), _quiet_fbgemm():
            fast = chain(probe)
            expected = reference(probe)
    except (RuntimeError, AttributeError):  # no fbgemm in this build (e.g. ARM) or no such function
        return None
    if fast.shape != expected.shape:
        return None
    scale = max(1.0, float(expected.abs().max()))
    if not float((fast - expected).abs().max()) <= _FLOAT16_PROBE_TOLERANCE * scale:
        return None
    return chain


class ForceEstimator:
    """A loaded bundle; `estimate(voltages [F, 9]) -> [F, len(axes)]` in N and N*m."""

    def __init__(self, model: torch.nn.Module, metadata: BundleMetadata, path: str | Path = "",
                 precision: str = DEFAULT_PRECISION) -> None:
        if precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {list(PRECISIONS)}, got {precision!r}")
        self.model = model.eval()
        self._run: Callable[[torch.Tensor], torch.Tensor] = _optimised(self.model)
        self.precision = "float32"  # the path that runs: float16 only where the network converts
        if precision == "float16":
            chain = _float16_chain(self.model, self._run)
            if chain is not None:
                self._run, self.precision = chain, "float16"
        self.metadata = metadata
        self.path = str(path)
        self.axes: list[str] = list(metadata.axes)
        self._in_mean = metadata.input_normaliser.mean.astype(np.float32)
        self._in_std = metadata.input_normaliser.std.astype(np.float32)
        self._out_mean = np.asarray(metadata.output_normaliser.mean, dtype=np.float64)
        self._out_std = np.asarray(metadata.output_normaliser.std, dtype=np.float64)
        self.estimated = 0  # rows that went through the network
        self.rejected = 0  # rows refused for non-finite input

    @classmethod
    def from_bundle(cls, path: str | Path, threads: int | None = None,
                    precision: str = DEFAULT_PRECISION) -> ForceEstimator:
        """Load and validate a bundle directory (BundleError names the path and the mismatch).

        `threads` sets torch's intra-op thread count; None leaves it as it is. `precision`: see
        the module docstring.
        """
        if threads is not None:
            set_torch_threads(threads)
        model, metadata = load_bundle(path)
        return cls(model, metadata, path, precision)

    @property
    def model_kind(self) -> str:
        return self.metadata.model_kind

    def estimate(self, voltages: np.ndarray) -> np.ndarray:
        """Wrench per row of `voltages` ([F, 9] or [9]); non-finite rows give NaN rows."""
        v = np.asarray(voltages, dtype=np.float32)
        single = v.ndim == 1
        if single:
            v = v[None, :]
        if v.ndim != 2 or v.shape[1] != 9:
            raise ValueError(f"voltages must have shape [F, 9], got {np.shape(voltages)}")
        finite = np.isfinite(v).all(axis=1)
        n_good = int(np.count_nonzero(finite))
        self.rejected += v.shape[0] - n_good
        if n_good == v.shape[0]:
            # every row finite, the usual scan: no NaN array to fill and scatter into (~30 us of
            # a cold five-finger call)
            out = self._network(v)
        else:
            out = np.full((v.shape[0], len(self.axes)), np.nan)
            if n_good:
                out[finite] = self._network(v[finite])
        self.estimated += n_good
        return out[0] if single else out

    def _network(self, v: np.ndarray) -> np.ndarray:
        """Wrenches [N, axes] (float64) of finite voltage rows [N, 9] (float32)."""
        x = torch.from_numpy((v - self._in_mean) / self._in_std)
        with torch.inference_mode():
            y = self._run(taxel_image(x)).numpy()
        return y * self._out_std + self._out_mean
