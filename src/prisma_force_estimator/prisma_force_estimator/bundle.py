"""Model bundle: a directory with a TorchScript network (model.pt) and its metadata.json.

torch is imported where a network is saved or loaded, not with this module: the bundle paths
(`DEFAULT_BUNDLE`, `resolve_bundle_path`) serve the torch-free node configuration and CLIs.

metadata.json carries everything needed to use the network without its training code:
format name and version, model kind, output axes, input layout, input/output normalisation,
training settings and per-axis validation MSE in physical units. `load_bundle` checks all of
it and raises `BundleError` naming the bundle path and the mismatch.
"""
from __future__ import annotations

import io
import json
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from prisma_common import share_data
from prisma_common.atomic import atomic_output

from .normalisation import Normaliser
from .wrench import WRENCH_AXES

if TYPE_CHECKING:
    import torch

FORMAT = "prisma_force_bundle"
FORMAT_VERSION = 1
MODEL_FILE = "model.pt"
METADATA_FILE = "metadata.json"
INPUT_SHAPE = (1, 3, 3)


class BundleError(ValueError):
    """A missing or mismatched model bundle; the message names the path and the problem."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"model bundle {self.path}: {problem}")


@dataclass
class BundleMetadata:
    model_kind: str
    axes: list[str]
    input_normaliser: Normaliser
    output_normaliser: Normaliser
    training: dict[str, Any] = field(default_factory=dict)
    validation_mse: dict[str, float] = field(default_factory=dict)
    format_version: int = FORMAT_VERSION

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "format_version": self.format_version,
            "model_kind": self.model_kind,
            "axes": list(self.axes),
            "units": {axis: ("N" if axis.startswith("f") else "N*m") for axis in self.axes},
            "input": {"shape": list(INPUT_SHAPE), "layout": "taxel i = 3*row + col, row 0 bottom, col 0 right",
                      "units": "V"},
            "normalisation": {"input": self.input_normaliser.to_dict(),
                              "output": self.output_normaliser.to_dict()},
            "training": self.training,
            "validation_mse": self.validation_mse,
        }


@contextmanager
def quiet_jit():
    # TorchScript is the bundle format the ROS side loads without Python model code; torch marks
    # it deprecated, which is noise for every user of a bundle.
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=DeprecationWarning, module=r"torch\.jit")
        yield


def save_bundle(directory: str | Path, model: torch.nn.Module, metadata: BundleMetadata) -> Path:
    """Script `model` and write model.pt + metadata.json as the directory `directory`.

    Written whole or not at all: staged beside `directory` and renamed into place when both files
    are complete, replacing an earlier bundle there. A directory holding anything else is refused
    (BundleError) and left alone."""
    import torch

    directory = Path(directory)
    if directory.is_symlink() or (directory.exists() and not directory.is_dir()):
        raise BundleError(directory, "is a file, not a bundle directory; not replacing it")
    if directory.is_dir():
        foreign = sorted(p.name for p in directory.iterdir() if p.name not in (MODEL_FILE, METADATA_FILE))
        if foreign:
            raise BundleError(directory, f"holds {', '.join(foreign[:3])}, which is no part of a bundle; "
                                         f"not replacing it: save to a new or empty directory")
    model = model.eval()
    with quiet_jit():
        scripted = torch.jit.script(model)
    with atomic_output(directory) as staged:
        staged.mkdir()
        with quiet_jit():
            torch.jit.save(scripted, str(staged / MODEL_FILE))
        (staged / METADATA_FILE).write_text(json.dumps(metadata.to_dict(), indent=2) + "\n")
    return directory


def _require(data: dict, key: str, kind: type, path: Path) -> Any:
    if key not in data:
        raise BundleError(path, f"{METADATA_FILE} lacks the key {key!r}")
    value = data[key]
    if not isinstance(value, kind):
        raise BundleError(path, f"{METADATA_FILE} key {key!r} must be {kind.__name__}, got {value!r}")
    return value


def parse_metadata(data: Any, path: Path) -> BundleMetadata:
    from .networks import MODEL_SPECS

    if not isinstance(data, dict):
        raise BundleError(path, f"{METADATA_FILE} must hold a JSON object")
    if data.get("format") != FORMAT:
        raise BundleError(path, f"{METADATA_FILE} format is {data.get('format')!r}, expected {FORMAT!r}")
    version = _require(data, "format_version", int, path)
    if version != FORMAT_VERSION:
        raise BundleError(path, f"format_version {version} is not supported, expected {FORMAT_VERSION}")
    kind = _require(data, "model_kind", str, path)
    if kind not in MODEL_SPECS:
        raise BundleError(path, f"model_kind {kind!r} is unknown, expected one of {list(MODEL_SPECS)}")
    axes = _require(data, "axes", list, path)
    unknown = [a for a in axes if a not in WRENCH_AXES]
    if unknown or len(set(axes)) != len(axes) or not axes:
        raise BundleError(path, f"axes {axes} must be distinct names from {list(WRENCH_AXES)}")
    expected_axes = list(MODEL_SPECS[kind].axes)
    if axes != expected_axes:
        raise BundleError(path, f"axes {axes} do not match model_kind {kind!r}, which outputs {expected_axes}")
    shape = data.get("input", {}).get("shape")
    if shape != list(INPUT_SHAPE):
        raise BundleError(path, f"input shape {shape} does not match the 3x3 taxel image {list(INPUT_SHAPE)}")
    norm = _require(data, "normalisation", dict, path)
    normalisers = {}
    for side, channels in (("input", 9), ("output", len(axes))):
        try:
            normaliser = Normaliser.from_dict(norm[side])
        except (KeyError, TypeError, ValueError) as exc:
            raise BundleError(path, f"normalisation.{side} is invalid: {exc}") from None
        if normaliser.channels != channels:
            raise BundleError(path, f"normalisation.{side} has {normaliser.channels} channels, expected {channels}")
        normalisers[side] = normaliser
    return BundleMetadata(kind, list(axes), normalisers["input"], normalisers["output"],
                          dict(data.get("training", {})), dict(data.get("validation_mse", {})), version)


def load_bundle(directory: str | Path) -> tuple[torch.jit.ScriptModule, BundleMetadata]:
    """Load and validate a bundle; every problem raises BundleError naming the path."""
    import torch

    from .networks import taxel_image

    directory = Path(directory)
    if not directory.is_dir():
        raise BundleError(directory, "directory does not exist" if not directory.exists() else "is not a directory")
    metadata_path = directory / METADATA_FILE
    model_path = directory / MODEL_FILE
    for required in (metadata_path, model_path):
        if not required.is_file():
            raise BundleError(directory, f"{required.name} is missing")
    try:
        data = json.loads(metadata_path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise BundleError(directory, f"{METADATA_FILE} is not valid JSON: {exc}") from None
    metadata = parse_metadata(data, directory)
    try:
        with quiet_jit():
            model = torch.jit.load(io.BytesIO(model_path.read_bytes()), map_location="cpu")
    except Exception as exc:  # torch raises RuntimeError and friends for corrupt archives
        raise BundleError(directory, f"{MODEL_FILE} is not a loadable TorchScript file: {exc}") from None
    model.eval()
    # Probe once: a network whose output width disagrees with the axes would otherwise mislabel
    # every wrench it produces.
    try:
        with torch.inference_mode():
            out = model(taxel_image(torch.zeros(2, 9)))
    except Exception as exc:
        raise BundleError(directory, f"{MODEL_FILE} fails on a [2, 1, 3, 3] taxel image: {exc}") from None
    if tuple(out.shape) != (2, len(metadata.axes)):
        raise BundleError(directory, f"{MODEL_FILE} outputs shape {list(out.shape)} for 2 samples, "
                                     f"expected [2, {len(metadata.axes)}] for axes {metadata.axes}")
    return model, metadata


DEFAULT_BUNDLE = "config/models/cnn2"
# How a loaded network runs (inference.py): float16 weights on its dense-chain form, or the
# bundle's float32 TorchScript network. Here, not in inference.py, so that node parameters are
# checked without importing torch.
PRECISIONS = ("float16", "float32")
DEFAULT_PRECISION = "float16"
# Bundles ship in prisma_bringup's share directory (config/models/); relative bundle paths are
# looked up in the working directory, then there (source tree, colcon install or wheel).
BUNDLE_PACKAGES = ("prisma_bringup",)


def resolve_bundle_path(path: str | Path) -> Path:
    """The bundle directory `path` names; the first existing candidate, else `path` itself."""
    path = Path(path).expanduser()
    if path.is_absolute():
        return path
    for candidate in [Path.cwd() / path, *share_data.candidates(path, BUNDLE_PACKAGES)]:
        if candidate.is_dir():
            return candidate
    return path


def save_untrained_bundle(directory: str | Path, kind: str, seed: int = 0) -> Path:
    """A bundle of a freshly initialised `kind` network with identity normalisation.

    Its wrenches are meaningless; it exists for inference benchmarks and tests of the bundle
    plumbing, where only shapes and timing matter.
    """
    import torch

    from .networks import MODEL_SPECS, build_model

    torch.manual_seed(seed)
    axes = list(MODEL_SPECS[kind].axes)
    metadata = BundleMetadata(kind, axes, Normaliser.identity(9), Normaliser.identity(len(axes)),
                              training={"untrained": True, "seed": seed})
    return save_bundle(directory, build_model(kind), metadata)
