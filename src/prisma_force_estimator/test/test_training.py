"""Training loop: a handful of steps only (full training is the documented command)."""
from dataclasses import replace

import numpy as np
import pytest
import torch

from prisma_force_estimator.bundle import load_bundle, save_bundle
from prisma_force_estimator.dataset import ForceDataset
from prisma_force_estimator.inference import ForceEstimator
from prisma_force_estimator.training import TrainConfig, train


@pytest.fixture(scope="module")
def small_set():
    from prisma_hand_sim.calibration import generate_calibration_set

    return ForceDataset.from_calibration_set(generate_calibration_set(n_samples=12_000, seed=7), "synthetic small")


def _config(**kw):
    base = dict(model_kind="cnn2", epochs=2, batch=64, seed=0, threads=1, max_steps_per_epoch=15)
    base.update(kw)
    return TrainConfig(**base)


def test_progress_line_per_epoch_and_metadata(small_set):
    lines = []
    result = train(small_set, _config(epochs=3), progress=lines.append)
    assert len(lines) == 3
    assert lines[0].startswith("epoch   1/3") and "val MSE [fx" in lines[0] and "tz" in lines[0]
    meta = result.metadata
    assert meta.model_kind == "cnn2" and meta.axes == ["fx", "fy", "fz", "tx", "ty", "tz"]
    assert set(meta.validation_mse) == set(meta.axes)
    assert meta.validation_mse == result.history[result.best_epoch - 1].val_mse
    t = meta.training
    assert t["batch"] == 64 and t["epochs"] == 3 and t["seed"] == 0 and t["optimiser"] == "Adam"
    assert t["samples_train"] + t["samples_validation"] + t["samples_guard_dropped"] == len(small_set)
    assert 0.15 < t["samples_validation"] / len(small_set) < 0.35
    assert meta.input_normaliser.channels == 9 and meta.output_normaliser.channels == 6


def test_a_few_steps_reduce_the_validation_loss(small_set):
    result = train(small_set, _config(model_kind="cnn", epochs=3, max_steps_per_epoch=40), progress=None)
    losses = [r.val_loss for r in result.history]
    assert losses[-1] < losses[0]
    assert losses[0] < 1.5  # normalised: an untrained net sits near 1


def test_training_is_seeded(small_set):
    a = train(small_set, _config(model_kind="ann"), progress=None)
    b = train(small_set, _config(model_kind="ann"), progress=None)
    c = train(small_set, _config(model_kind="ann", seed=1), progress=None)
    for (name, pa), pb in zip(a.model.state_dict().items(), b.model.state_dict().values()):
        assert torch.equal(pa, pb), name
    assert a.history[-1].val_loss == b.history[-1].val_loss
    assert a.history[-1].val_loss != c.history[-1].val_loss


def test_early_stopping_keeps_the_best_epoch(small_set):
    # A learning rate this large makes validation worse after the first epochs.
    lines = []
    result = train(small_set, _config(model_kind="ann", epochs=30, learning_rate=0.5, patience=2,
                                      max_steps_per_epoch=5), progress=lines.append)
    assert result.stopped_early
    assert len(result.history) < 30
    assert result.best_epoch == 1 + int(np.argmin([r.val_loss for r in result.history]))
    assert "early stop" in lines[-1]
    assert result.metadata.training["stopped_early"] is True


def test_cosine_schedule_decays_the_learning_rate(small_set):
    result = train(small_set, _config(model_kind="ann", epochs=4, lr_schedule="cosine", max_steps_per_epoch=2),
                   progress=None)
    rates = [r.learning_rate for r in result.history]
    assert rates[0] == pytest.approx(1e-3) and all(b < a for a, b in zip(rates, rates[1:]))


def test_trained_bundle_predicts_what_the_model_predicts(small_set, tmp_path):
    result = train(small_set, _config(model_kind="cnn_t", epochs=1), progress=None)
    path = save_bundle(tmp_path / "cnn_t", result.model, result.metadata)
    est = ForceEstimator.from_bundle(path)
    v = small_set.voltages[:10]
    x = torch.from_numpy(result.metadata.input_normaliser.apply(v)).reshape(-1, 1, 3, 3)
    with torch.inference_mode():
        expected = result.metadata.output_normaliser.invert(result.model(x).numpy())
    assert np.allclose(est.estimate(v), expected, atol=1e-5)
    assert load_bundle(path)[1].training["epochs_run"] == 1


@pytest.mark.parametrize("field,value,message", [
    ("model_kind", "rnn", "model_kind 'rnn' unknown"),
    ("epochs", 0, "epochs must be >= 1, got 0"),
    ("batch", 0, "batch must be >= 1"),
    ("learning_rate", 0.0, "learning_rate must be > 0"),
    ("lr_schedule", "step", "lr_schedule must be"),
])
def test_bad_config_is_named(small_set, field, value, message):
    with pytest.raises(ValueError, match=message):
        train(small_set, _config(**{field: value}), progress=None)


def test_input_noise_augmentation_changes_training_but_not_validation_data(small_set):
    plain = train(small_set, _config(model_kind="ann", epochs=1), progress=None)
    noisy = train(small_set, _config(model_kind="ann", epochs=1, input_noise=0.02), progress=None)
    assert plain.history[0].train_loss != noisy.history[0].train_loss
    assert noisy.metadata.training["input_noise"] == 0.02
    # the normalisation is fitted on the clean training inputs either way
    assert np.array_equal(plain.metadata.input_normaliser.mean, noisy.metadata.input_normaliser.mean)
    with pytest.raises(ValueError, match="input_noise must be >= 0"):
        train(small_set, _config(input_noise=-1.0), progress=None)


def test_weight_decay_trains_with_adamw_and_shrinks_the_weights(small_set):
    plain = train(small_set, _config(model_kind="ann", epochs=1, learning_rate=1e-3), progress=None)
    decayed = train(small_set, _config(model_kind="ann", epochs=1, learning_rate=1e-3, weight_decay=50.0),
                    progress=None)
    # 15 steps of decoupled decay at lr*wd = 0.05 shrink every weight by 1 - 0.95**15 ~ 54% (plus Adam's
    # own step of at most lr per parameter); plain Adam cannot move the norm that far in 15 steps.
    def norm(r):
        return float(torch.sqrt(sum((p.detach() ** 2).sum() for p in r.model.parameters())))

    assert norm(decayed) < 0.6 * norm(plain)
    assert decayed.metadata.training["optimiser"] == "AdamW" and decayed.metadata.training["weight_decay"] == 50.0
    assert plain.metadata.training["optimiser"] == "Adam"
    with pytest.raises(ValueError, match="weight_decay must be >= 0"):
        train(small_set, _config(weight_decay=-0.1), progress=None)


def test_ema_saves_the_average_of_the_weights_along_the_way(small_set):
    # Decay 0.5 over 3 steps: ema = 0.25*w1 + 0.25*w2 + 0.5*w3, where wk are the raw weights after k
    # steps; the same seed gives the same raw trajectory, so runs of 1, 2 and 3 steps provide wk.
    config = _config(model_kind="ann", epochs=1, max_steps_per_epoch=3)
    result = train(small_set, replace(config, ema_decay=0.5), progress=None)
    w = [train(small_set, replace(config, max_steps_per_epoch=k), progress=None).model.state_dict()
         for k in (1, 2, 3)]
    for name, value in result.model.state_dict().items():
        assert torch.allclose(value, 0.25 * w[0][name] + 0.25 * w[1][name] + 0.5 * w[2][name], atol=1e-6), name
    assert not torch.allclose(result.model.state_dict()["net.1.weight"], w[2]["net.1.weight"])
    assert type(result.model).__name__ == "ANN"  # the plain network, not the AveragedModel wrapper
    assert result.metadata.training["weight_averaging"] == "EMA, decay 0.5 per step"
    with pytest.raises(ValueError, match="ema_decay must be in"):
        train(small_set, _config(ema_decay=1.0), progress=None)


def test_loss_weights_scale_each_axis_and_the_selection_loss(small_set):
    from prisma_force_estimator.training import weighted_mse

    pred = torch.zeros(4, 6)
    target = torch.tensor([[1.0, 0, 0, 0, 0, 2.0]] * 4)
    w = torch.tensor([1, 1, 1, 1, 1, 0.25]) * 6 / 5.25
    assert float(weighted_mse(pred, target, w)) == pytest.approx((1 + 0.25 * 4) * 6 / 5.25 / 6)
    assert float(weighted_mse(pred, target, None)) == pytest.approx(5 / 6)
    result = train(small_set, _config(epochs=1, loss_weights={"tz": 0.25}), progress=None)
    assert result.metadata.training["loss_weights"] == {"tz": 0.25}
    assert "tz 0.25" in result.metadata.training["loss"]
    with pytest.raises(ValueError, match=r"axes \['tz'\] are not outputs of cnn"):
        train(small_set, _config(model_kind="cnn", loss_weights={"tz": 0.5}), progress=None)
    with pytest.raises(ValueError, match="finite and >= 0"):
        train(small_set, _config(loss_weights={"fx": -1.0}), progress=None)
