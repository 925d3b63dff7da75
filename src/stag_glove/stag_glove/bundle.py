"""Model bundles: a directory with model.pt (state_dict) and metadata.json (architecture, labels,
normalisation, training command and results). Loading checks that the weights match the declared
architecture and fails naming the path and the expected shape (docs/glove.md).
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import torch

from .models import TouchNet, WeightNet
from .paths import resolve

KINDS = ("object", "pose", "weight")
FORMAT = "stag_glove bundle v1"


class BundleError(ValueError):
    """A model bundle that is missing, malformed or does not match its metadata."""


@dataclass
class Bundle:
    path: Path
    kind: str
    model: torch.nn.Module
    metadata: dict

    @property
    def labels(self) -> list[str]:
        return list(self.metadata.get("labels", []))

    @property
    def n_frames(self) -> int:
        return int(self.metadata.get("n_frames", 1))


def build_model(kind: str, metadata: dict) -> torch.nn.Module:
    width = int(metadata["width"])
    if kind == "weight":
        return WeightNet(width=width)
    return TouchNet(n_classes=len(metadata["labels"]), n_frames=int(metadata.get("n_frames", 1)), width=width)


def save_bundle(path: str | Path, kind: str, model: torch.nn.Module, metadata: dict) -> Path:
    if kind not in KINDS:
        raise ValueError(f"bundle kind must be one of {KINDS}, got {kind!r}")
    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    meta = {"format": FORMAT, "kind": kind, **metadata}
    torch.save(model.state_dict(), path / "model.pt")
    (path / "metadata.json").write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
    return path


def load_bundle(path: str | Path, kind: str | None = None) -> Bundle:
    try:
        directory = resolve(path)
    except FileNotFoundError as exc:
        raise BundleError(f"model bundle {path}: {exc}") from None
    meta_path, model_path = directory / "metadata.json", directory / "model.pt"
    for needed in (meta_path, model_path):
        if not needed.exists():
            raise BundleError(f"model bundle {directory}: missing {needed.name}")
    try:
        metadata = json.loads(meta_path.read_text())
    except json.JSONDecodeError as exc:
        raise BundleError(f"{meta_path}: not valid JSON ({exc})") from None
    found = metadata.get("kind")
    if found not in KINDS:
        raise BundleError(f"{meta_path}: kind must be one of {KINDS}, got {found!r}")
    if kind is not None and found != kind:
        raise BundleError(f"model bundle {directory} holds a {found!r} model, expected {kind!r}")
    for key in ("width",) + (() if found == "weight" else ("labels", "n_frames")):
        if key not in metadata:
            raise BundleError(f"{meta_path}: missing {key!r}")
    model = build_model(found, metadata)
    try:
        state = torch.load(model_path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises several types for corrupt files
        raise BundleError(f"{model_path}: cannot be read as a state_dict ({exc})") from None
    expected = {k: tuple(v.shape) for k, v in model.state_dict().items()}
    got = {k: tuple(v.shape) for k, v in state.items()}
    if expected != got:
        missing = sorted(set(expected) - set(got))
        extra = sorted(set(got) - set(expected))
        wrong = [f"{k}: expected {expected[k]}, file has {got[k]}" for k in expected
                 if k in got and expected[k] != got[k]]
        detail = "; ".join(filter(None, [
            f"missing {missing[:3]}" if missing else "", f"unexpected {extra[:3]}" if extra else "",
            ", ".join(wrong[:3])]))
        shape = f"width {metadata['width']}" + ("" if found == "weight" else
                                                 f", {metadata['n_frames']} frames, {len(metadata['labels'])} classes")
        raise BundleError(f"{model_path} does not match its metadata ({shape}): {detail}")
    model.load_state_dict(state)
    model.eval()
    return Bundle(directory, found, model, metadata)
