"""ForceEstimator: batch inference, normalisation, NaN rows refused per sample."""
import numpy as np
import pytest
import torch

from prisma_force_estimator.bundle import BundleMetadata, save_bundle, save_untrained_bundle
from prisma_force_estimator.inference import ForceEstimator, set_torch_threads
from prisma_force_estimator.networks import build_model, taxel_image
from prisma_force_estimator.normalisation import Normaliser


@pytest.fixture(scope="module")
def estimator(tmp_path_factory):
    torch.manual_seed(3)
    model = build_model("cnn2")
    rng = np.random.default_rng(3)
    meta = BundleMetadata("cnn2", ["fx", "fy", "fz", "tx", "ty", "tz"],
                          Normaliser(rng.uniform(0.3, 0.6, 9), rng.uniform(0.2, 0.4, 9)),
                          Normaliser(rng.normal(size=6), rng.uniform(0.01, 2.0, 6)))
    path = save_bundle(tmp_path_factory.mktemp("inf") / "cnn2", model, meta)
    return ForceEstimator.from_bundle(path, threads=1), model.eval(), meta


def test_estimate_applies_normalisation_both_ways(estimator):
    est, model, meta = estimator
    v = np.random.default_rng(0).uniform(0.3, 3.0, (5, 9)).astype(np.float32)
    x = torch.from_numpy(meta.input_normaliser.apply(v))
    with torch.inference_mode():
        expected = meta.output_normaliser.invert(model(taxel_image(x)).numpy())
    got = est.estimate(v)
    assert got.shape == (5, 6)
    assert np.allclose(got, expected, atol=1e-5)
    assert est.axes == ["fx", "fy", "fz", "tx", "ty", "tz"]


def test_batch_equals_rows_one_by_one(estimator):
    est = estimator[0]
    v = np.random.default_rng(1).uniform(0.3, 3.0, (5, 9))
    batch = est.estimate(v)
    rows = np.stack([est.estimate(row) for row in v])
    assert np.allclose(batch, rows, atol=1e-5)


def test_nan_rows_come_back_nan_and_are_counted(estimator):
    est = estimator[0]
    v = np.random.default_rng(2).uniform(0.3, 3.0, (5, 9))
    clean = est.estimate(v)
    before_rejected, before_estimated = est.rejected, est.estimated
    v[1, 4] = np.nan
    v[3, 0] = np.inf
    out = est.estimate(v)
    assert np.isnan(out[[1, 3]]).all()
    assert np.allclose(out[[0, 2, 4]], clean[[0, 2, 4]], atol=1e-5)  # neighbours unaffected
    assert est.rejected - before_rejected == 2
    assert est.estimated - before_estimated == 3
    all_bad = est.estimate(np.full((2, 9), np.nan))
    assert all_bad.shape == (2, 6) and np.isnan(all_bad).all()


def test_wrong_shape_is_refused(estimator):
    with pytest.raises(ValueError, match=r"shape \[F, 9\]"):
        estimator[0].estimate(np.zeros((2, 8)))


def test_threads_are_configurable(tmp_path):
    path = save_untrained_bundle(tmp_path / "ann", "ann")
    previous = torch.get_num_threads()
    try:
        est = ForceEstimator.from_bundle(path, threads=1)
        assert torch.get_num_threads() == 1
        assert est.estimate(np.zeros((5, 9))).shape == (5, 3)
        with pytest.raises(ValueError, match="threads must be >= 1, got 0"):
            set_torch_threads(0)
    finally:
        torch.set_num_threads(previous)
