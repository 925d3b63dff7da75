"""The stag-* command lines end to end on small dataset files (a handful of training steps)."""
import json

import numpy as np
import pytest

from stag_glove import cli
from stag_glove.bundle import load_bundle
from stag_glove.dataset import load_dataset, save_hdf5
from stag_glove.synthetic import SyntheticConfig, SyntheticGlove

TINY = ["--width", "4", "--epochs", "1", "--threads", "1"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    root = tmp_path_factory.mktemp("data")
    glove = SyntheticGlove(SyntheticConfig(n_objects=4, frames_per_session=24, seed=1))
    paths = {}
    for kind, ds in (("object", glove.object_dataset()), ("pose", glove.pose_dataset(frames_per_session=12)),
                     ("weight", glove.weight_dataset(grasps_per_object=2, frames_per_grasp=4))):
        paths[kind] = root / f"{kind}.h5"
        save_hdf5(ds, paths[kind])
    return paths


def test_train_classifier_writes_curve_confusion_json_and_bundle(files, tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main(["train-classifier", "--dataset", str(files["object"]), *TINY, "--frames", "1-3",
                     "--seeds", "0", "--head-epochs", "1", "--curve-png", str(out / "curve.png"),
                     "--confusion-png", str(out / "confusion.png"), "--out-json", str(out / "r.json"),
                     "--bundle-out", str(out / "bundle"), "--bundle-frames", "3"]) == 0
    text = capsys.readouterr().out
    assert "[seed 0 N=1] epoch 1/1" in text and "cluster    3" in text
    result = json.loads((out / "r.json").read_text())
    assert ({(r["selection"], r["n"]) for r in result["summary"]}
            == {(s, n) for s in ("random", "cluster") for n in (1, 2, 3)})
    assert all(0 <= r["top1"] <= r["top3"] <= 1 for r in result["summary"])
    assert (out / "curve.png").stat().st_size < 300_000 and (out / "confusion.png").stat().st_size < 300_000
    bundle = load_bundle(out / "bundle", "object")
    assert bundle.n_frames == 3 and bundle.labels == load_dataset(files["object"]).objects
    assert bundle.metadata["selection"] == "cluster" and "stag-train-classifier" in bundle.metadata["command"]
    assert bundle.metadata["normalisation"] == {"low": 500, "high": 650}  # the counts the frames were scaled from


def test_train_weight_and_pose_and_correlation(files, tmp_path, capsys):
    assert cli.main(["train-weight", "--dataset", str(files["weight"]), *TINY, "--folds", "2",
                     "--out-json", str(tmp_path / "w.json"), "--png", str(tmp_path / "w.png"),
                     "--bundle-out", str(tmp_path / "wb")]) == 0
    weight = json.loads((tmp_path / "w.json").read_text())
    assert weight["folds"] == 2 and len(weight["rows"]) == 2
    assert weight["cnn_mean_error_g"] > 0 and weight["linear_mean_error_g"] > 0
    wb = load_bundle(tmp_path / "wb", "weight")
    assert set(wb.metadata["linear_baseline"]) == {"a", "b"}
    assert wb.metadata["normalisation"] == {"low": 500, "high": 650}
    assert cli.main(["train-pose", "--dataset", str(files["pose"]), *TINY, "--out-json", str(tmp_path / "p.json"),
                     "--bundle-out", str(tmp_path / "pb")]) == 0
    pose = json.loads((tmp_path / "p.json").read_text())
    assert len(pose["labels"]) == 8 and np.array(pose["confusion"]).shape == (8, 8)
    assert load_bundle(tmp_path / "pb", "pose").n_frames == 1
    assert cli.main(["correlation", "--dataset", str(files["object"]), "--threads", "1",
                     "--out-json", str(tmp_path / "c.json")]) == 0
    corr = json.loads((tmp_path / "c.json").read_text())
    assert corr["grasps"] > 0 and len(corr["region_names"]) == 15
    assert "held-out session: top-1" in capsys.readouterr().out


def test_make_dataset_and_bad_arguments(tmp_path, capsys):
    assert cli.main(["make-dataset", str(tmp_path / "pose.mat"), "--kind", "pose"]) == 0
    assert load_dataset(tmp_path / "pose.mat").objects[0] == "empty"
    assert cli.main(["nope"]) == 2
    with pytest.raises(SystemExit):
        cli.main(["train-classifier", "--frames", "0-2"])
