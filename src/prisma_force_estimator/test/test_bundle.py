"""Bundle format: round trip, and every mismatch fails with the path and the problem."""
import json
import shutil

import numpy as np
import pytest
import torch

from prisma_force_estimator.bundle import (
    FORMAT_VERSION,
    METADATA_FILE,
    MODEL_FILE,
    BundleError,
    BundleMetadata,
    load_bundle,
    save_bundle,
    save_untrained_bundle,
)
from prisma_force_estimator.inference import ForceEstimator
from prisma_force_estimator.networks import build_model
from prisma_force_estimator.normalisation import Normaliser


@pytest.fixture(scope="module")
def cnn2_bundle(tmp_path_factory):
    return save_untrained_bundle(tmp_path_factory.mktemp("b") / "cnn2", "cnn2", seed=1)


def _copy(bundle, tmp_path):
    target = tmp_path / "copy"
    shutil.copytree(bundle, target)
    return target


def _edit_metadata(path, **changes):
    data = json.loads((path / METADATA_FILE).read_text())
    for key, value in changes.items():
        if value is None:
            data.pop(key)
        else:
            data[key] = value
    (path / METADATA_FILE).write_text(json.dumps(data))


def test_round_trip_keeps_weights_normalisation_and_metadata(tmp_path):
    torch.manual_seed(0)
    model = build_model("cnn_t")
    rng = np.random.default_rng(0)
    in_norm = Normaliser(rng.uniform(0.3, 1.0, 9), rng.uniform(0.1, 0.5, 9))
    out_norm = Normaliser(rng.normal(size=6), rng.uniform(0.01, 1.0, 6))
    meta = BundleMetadata("cnn_t", ["fx", "fy", "fz", "tx", "ty", "tz"], in_norm, out_norm,
                          training={"epochs": 3, "batch": 64}, validation_mse={"fx": 0.1})
    path = save_bundle(tmp_path / "b", model, meta)
    loaded, meta2 = load_bundle(path)
    assert meta2.model_kind == "cnn_t" and meta2.axes == meta.axes
    assert meta2.training == {"epochs": 3, "batch": 64} and meta2.validation_mse == {"fx": 0.1}
    assert np.allclose(meta2.input_normaliser.mean, in_norm.mean)
    x = torch.randn(7, 1, 3, 3)
    with torch.inference_mode():
        assert torch.allclose(loaded(x), model.eval()(x))
    data = json.loads((path / METADATA_FILE).read_text())
    assert data["format_version"] == FORMAT_VERSION
    assert data["units"]["fz"] == "N" and data["units"]["tx"] == "N*m"


def test_missing_directory_is_named(tmp_path):
    missing = tmp_path / "nowhere"
    with pytest.raises(BundleError) as err:
        ForceEstimator.from_bundle(missing)
    assert str(missing) in str(err.value) and "does not exist" in str(err.value)


@pytest.mark.parametrize("name", [MODEL_FILE, METADATA_FILE])
def test_missing_file_is_named(cnn2_bundle, tmp_path, name):
    path = _copy(cnn2_bundle, tmp_path)
    (path / name).unlink()
    with pytest.raises(BundleError, match=f"{name} is missing") as err:
        load_bundle(path)
    assert str(path) in str(err.value)


def test_bad_json(cnn2_bundle, tmp_path):
    path = _copy(cnn2_bundle, tmp_path)
    (path / METADATA_FILE).write_text("{not json")
    with pytest.raises(BundleError, match="not valid JSON"):
        load_bundle(path)


@pytest.mark.parametrize("changes,problem", [
    ({"format_version": 99}, "format_version 99 is not supported, expected 1"),
    ({"format_version": None}, "lacks the key 'format_version'"),
    ({"format": "onnx"}, "format is 'onnx'"),
    ({"model_kind": "lstm"}, "model_kind 'lstm' is unknown"),
    ({"axes": ["fx", "fy", "fz"]}, r"axes \['fx', 'fy', 'fz'\] do not match model_kind 'cnn2'"),
    ({"axes": ["fx", "fx", "fz", "tx", "ty", "tz"]}, "must be distinct"),
    ({"input": {"shape": [9]}}, r"input shape \[9\] does not match the 3x3 taxel image"),
    ({"normalisation": {"input": {"mean": [0] * 8, "std": [1] * 8}, "output": {"mean": [0] * 6, "std": [1] * 6}}},
     "normalisation.input has 8 channels, expected 9"),
    ({"normalisation": {"input": {"mean": [0] * 9, "std": [1] * 9}, "output": {"mean": [0] * 6}}},
     "normalisation.output is invalid"),
])
def test_metadata_mismatch_names_path_and_problem(cnn2_bundle, tmp_path, changes, problem):
    path = _copy(cnn2_bundle, tmp_path)
    _edit_metadata(path, **changes)
    with pytest.raises(BundleError, match=problem) as err:
        load_bundle(path)
    assert str(path) in str(err.value)


def test_network_output_width_must_match_axes(tmp_path):
    """A CNN (3 outputs) saved under CNN_T metadata (6 axes) is refused at load."""
    meta = BundleMetadata("cnn_t", ["fx", "fy", "fz", "tx", "ty", "tz"], Normaliser.identity(9),
                          Normaliser.identity(6))
    path = save_bundle(tmp_path / "mixed", build_model("cnn"), meta)
    with pytest.raises(BundleError, match=r"outputs shape \[2, 3\] for 2 samples, expected \[2, 6\]") as err:
        load_bundle(path)
    assert str(path) in str(err.value)


def test_corrupt_model_file(cnn2_bundle, tmp_path):
    path = _copy(cnn2_bundle, tmp_path)
    (path / MODEL_FILE).write_bytes(b"\x00garbage" * 10)
    with pytest.raises(BundleError, match="not a loadable TorchScript file"):
        load_bundle(path)


def test_bundle_error_is_a_value_error(tmp_path):
    assert issubclass(BundleError, ValueError)
    err = BundleError(tmp_path, "something")
    assert err.path == str(tmp_path) and err.problem == "something"
