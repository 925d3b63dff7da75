"""What the force_estimator takes from and gives to the hand directory (prisma_common.hand_config):
the per-finger bundles and the saved no-load bias at start, the bias ~/bias took afterwards.

At start, each finger's bundle is, first to last: a non-empty finger_bundles.<finger> parameter
(an explicit choice for this run), the hand directory's bundles.yaml entry, model_bundle. The
shipped config sets no finger_bundles, so a hand directory's bundle wins over the shipped model.
A saved bias is applied only to a finger that runs the same network it was taken with (the same
directory, or one with identical model.pt and metadata.json, as a copied bundle has): a bias of
another network is meaningless, so it is skipped, with the reason in the start log.

The decisions are returned as data (StartPlan, BiasSave); the node logs and applies them.
"""
from __future__ import annotations

import filecmp
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from prisma_common.hand_config import BUNDLES_FILE, HandConfig, HandConfigError

from .bias import BiasResult, WrenchBias
from .bundle import METADATA_FILE, MODEL_FILE, resolve_bundle_path


@dataclass
class StartPlan:
    bundles: dict[str, str]  # finger -> resolved bundle directory
    offsets: dict[str, np.ndarray] = field(default_factory=dict)  # finger -> saved bias to apply
    notes: list[str] = field(default_factory=list)  # what came from the hand directory, what was skipped


def open_hand_config(root: str) -> HandConfig | None:
    """The hand directory the `hand_config` parameter names; None for ''."""
    return HandConfig(root) if root.strip() else None


def same_bundle(a: str | Path, b: str | Path) -> bool:
    """Whether two bundle directories hold the same network."""
    a, b = Path(a), Path(b)
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return all(filecmp.cmp(a / name, b / name, shallow=False) for name in (MODEL_FILE, METADATA_FILE))
    except OSError:  # either is gone or unreadable: not known to be the same
        return False


def plan_start(fingers: list[str], parameter_bundles: Mapping[str, str], model_bundle: str,
               hand: HandConfig | None) -> StartPlan:
    """Each finger's bundle and saved bias. Raises HandConfigError for a bad hand directory file."""
    saved_bundles = hand.bundles() if hand is not None else {}
    bundles: dict[str, str] = {}
    notes: list[str] = []
    for finger in fingers:
        if parameter_bundles.get(finger):
            bundles[finger] = str(resolve_bundle_path(parameter_bundles[finger]))
            if finger in saved_bundles:
                notes.append(f"{finger}: bundle from finger_bundles.{finger}, not the hand directory's "
                             f"{saved_bundles[finger]}")
        elif finger in saved_bundles:
            bundles[finger] = str(saved_bundles[finger])
            notes.append(f"{finger}: bundle {saved_bundles[finger]} (hand directory {BUNDLES_FILE})")
        else:
            bundles[finger] = str(resolve_bundle_path(model_bundle))
    plan = StartPlan(bundles, notes=notes)
    if hand is None:
        return plan
    for finger, saved in hand.force_bias().items():
        if finger not in bundles:
            continue
        if not same_bundle(saved.bundle, bundles[finger]):
            plan.notes.append(f"{finger}: saved bias not applied: taken with {saved.bundle}, this run uses "
                              f"{bundles[finger]}; take ~/bias again")
            continue
        plan.offsets[finger] = np.asarray(saved.offset, dtype=np.float64)
        plan.notes.append(f"{finger}: saved bias Fz {saved.offset[2]:+.4f} N from {saved.written_at or 'unknown'}")
    return plan


def save_bias(hand: HandConfig | None, bias: WrenchBias, result: BiasResult,
              bundles: Mapping[str, str]) -> BiasResult:
    """After ~/bias: a taken bias saved to the hand directory, the file named in the message. A
    failed save keeps the bias (it is in use) and says so in the message; a refused or unsaved
    bias is returned as it was."""
    if hand is None or not result.success:
        return result
    try:
        path = hand.save_force_bias(bias.offsets, bundles, bias.samples, note="~/bias")
    except HandConfigError as exc:
        return BiasResult(True, f"{result.message}; NOT saved: {exc}", warning=True)
    return BiasResult(True, f"{result.message}; saved to {path}")
