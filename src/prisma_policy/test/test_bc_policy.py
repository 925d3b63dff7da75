"""The behaviour-cloning policy on a small dataset written by prisma_dataset's own writer: training
lowers the loss, a model round-trips, the dataset's stats normalise it, a missing feature is named."""
from __future__ import annotations

import json

import numpy as np
import pytest

from prisma_dataset.bag_export import ACTION, TACTILE, WRENCH
from prisma_policy.bc_policy import (
    PolicyError,
    TrainConfig,
    evaluate_loss,
    grasp_span,
    load,
    load_training_set,
    normalise,
    save,
    shown_balls,
    train,
)


def test_training_lowers_the_loss_and_learns_the_mapping(tmp_path, tiny_dataset):
    data = load_training_set(tiny_dataset(tmp_path / "ds", episodes=5, frames=120), whole_episodes=True)
    assert data.inputs.shape == (600, 81) and data.actions.shape == (600, 3) and data.episodes == 5
    untrained = train(data, TrainConfig(steps=1, seed=1))
    policy = train(data, TrainConfig(steps=800, seed=1))
    before, after = evaluate_loss(untrained, data), evaluate_loss(policy, data)
    assert after < 0.25 * before, (before, after)
    assert policy.losses[-1] < policy.losses[0]
    # the fingers' target follows the state (1.5 x position + 0.5) on a frame it was not trained on
    state = np.array([2.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    fingers = policy.act(np.full((5, 3, 3), 0.5), np.zeros((5, 6)), state)[0]
    assert fingers == pytest.approx(3.5, abs=0.5)


def test_normalisation_is_the_datasets_stats(tmp_path, tiny_dataset):
    root = tiny_dataset(tmp_path / "ds")
    data = load_training_set(root, whole_episodes=True)
    stats = json.loads((root / "meta" / "stats.json").read_text())
    assert data.action_mean == pytest.approx(np.asarray(stats[ACTION]["mean"]))
    assert data.input_std[:45] == pytest.approx(np.asarray(stats[TACTILE]["std"]).reshape(-1))
    # normalised frames have mean 0 and std 1 per element (the rotation target, constant, is only centred)
    z = normalise(data.actions, data.action_mean, data.action_std)
    assert z.mean(axis=0) == pytest.approx([0, 0, 0], abs=1e-5)
    assert z[:, :2].std(axis=0) == pytest.approx([1, 1], abs=1e-4)
    assert np.all(z[:, 2] == pytest.approx(0.0, abs=1e-6))
    # an axis the estimator does not estimate (NaN) counts as the mean
    assert normalise(np.array([np.nan, 3.0]), np.array([np.nan, 1.0]), np.array([np.nan, 2.0])).tolist() == [0.0, 1.0]


def test_a_model_round_trips(tmp_path, tiny_dataset):
    data = load_training_set(tiny_dataset(tmp_path / "ds"), whole_episodes=True)
    policy = train(data, TrainConfig(steps=100, hidden=16, seed=2))
    path = save(policy, tmp_path / "model.pt")
    again = load(path)
    observation = (np.full((5, 3, 3), 0.3), np.full((5, 6), 0.1), np.array([1.0, 2.0, 0.5, 0.0, 0.1, 0.0]))
    assert again.act(*observation) == pytest.approx(policy.act(*observation), abs=1e-6)
    assert again.hidden == 16 and again.fps == 50 and again.episodes == 3 and again.losses == policy.losses
    assert again.shown == {"index_contact_rad": [2.9, pytest.approx(3.1)], "thumb_contact_rad": [2.5, 2.5],
                           "stiffness_n_per_mm": [0.4, 0.4]}
    assert not list(tmp_path.glob("*.partial-*"))


def test_the_grasp_span_is_closing_and_holding():
    # rest 10 frames (noise 0.005 rad), close over 20 to 6 rad, hold 15 (noise), open over 20, rest 10
    rng = np.random.default_rng(0)
    fingers = np.concatenate([np.zeros(10), np.linspace(0.3, 6.0, 20), np.full(15, 6.0), np.linspace(5.7, 0.0, 20),
                              np.zeros(10)]) + rng.normal(0, 0.005, 75)
    actions = np.stack([fingers, 0.8 * fingers, np.full(75, 0.01)], axis=1)
    span = grasp_span(actions)
    assert (span.start, span.stop) == (10, 45)  # the first closing frame .. the last held one
    assert grasp_span(np.zeros((8, 3))) == slice(0, 8)  # an action that never moves: every frame


def test_a_missing_feature_is_named(tmp_path, tiny_dataset):
    root = tiny_dataset(tmp_path / "ds", drop=WRENCH)
    with pytest.raises(PolicyError, match="has no feature observation.wrench"):
        load_training_set(root)


def test_a_file_that_is_not_a_model_is_refused(tmp_path, tiny_dataset):
    path = tmp_path / "model.pt"
    path.write_text("not a model")
    with pytest.raises(PolicyError, match="is not a prisma-policy model"):
        load(path)


def test_shown_balls_without_demonstrations_is_empty(tmp_path, tiny_dataset):
    root = tiny_dataset(tmp_path / "ds")
    notes = json.loads((root / "meta" / "prisma_export.json").read_text())
    for episode in notes["episodes"]:
        episode.pop("demonstration")
    (root / "meta" / "prisma_export.json").write_text(json.dumps(notes))
    assert shown_balls(root) == {}
