"""prisma-train-force, prisma-eval-force, prisma-estimate-bag end to end (a handful of steps)."""
import json

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from prisma_common.bag import BagWriter, read_bag
from prisma_common.hand import FINGERS
from prisma_common.typestore import get_typestore, types
from prisma_force_estimator.bundle import load_bundle, save_untrained_bundle
from prisma_force_estimator.cli import estimate_bag_main, eval_main, train_main
from prisma_force_estimator.inference import ForceEstimator
from prisma_force_estimator.ros_conversions import wrench_to_msg
from prisma_force_estimator.wrench import WrenchSample
from prisma_tactile_driver.ros_conversions import taxel_frame_to_msg
from prisma_tactile_driver.taxels import TaxelFrame

T0 = 1_700_000_000_000_000_000


def _taxel(finger, stamp, voltages):
    counts = np.rint(np.nan_to_num(voltages) / 3.3 * 4096).astype(np.uint16)
    return taxel_frame_to_msg(types, TaxelFrame(finger, stamp, counts, np.asarray(voltages, np.float32)),
                              f"prisma_{finger}_pad")


def test_train_on_synthetic_writes_a_loadable_bundle(tmp_path, capsys):
    out = tmp_path / "cnn2"
    assert train_main(["--model", "cnn2", "--samples", "6000", "--epochs", "2", "--max-steps-per-epoch", "5",
                       "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "epoch   1/2" in text and "epoch   2/2" in text and f"wrote bundle {out}" in text
    _, meta = load_bundle(out)
    assert meta.model_kind == "cnn2" and meta.training["data"] == "synthetic(n=6000, seed=0)"
    assert meta.training["epochs_run"] == 2 and set(meta.validation_mse) == set(meta.axes)


def test_train_variance_options_reach_the_bundle(tmp_path, capsys):
    out = tmp_path / "cnn2_reg"
    assert train_main(["--model", "cnn2", "--samples", "6000", "--epochs", "1", "--max-steps-per-epoch", "4",
                       "--weight-decay", "0.05", "--ema-decay", "0.99", "--loss-weights", "tz=0.25, tx=0.5",
                       "--out", str(out)]) == 0
    t = load_bundle(out)[1].training
    assert t["optimiser"] == "AdamW" and t["weight_decay"] == 0.05
    assert t["ema_decay"] == 0.99 and t["weight_averaging"] == "EMA, decay 0.99 per step"
    assert t["loss_weights"] == {"tz": 0.25, "tx": 0.5}
    capsys.readouterr()
    with pytest.raises(SystemExit):
        train_main(["--model", "cnn2", "--loss-weights", "tz:0.25"])
    assert "'tz:0.25' is not AXIS=WEIGHT" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        train_main(["--model", "cnn", "--loss-weights", "tz=0.25"])
    assert "axes ['tz'] are not outputs of cnn" in capsys.readouterr().err


def test_train_on_a_calibration_bag(tmp_path, capsys):
    from prisma_hand_sim.calibration import generate_calibration_set

    cs = generate_calibration_set(n_samples=1500, seed=3)
    with BagWriter(tmp_path / "cal") as bag:
        for k in range(len(cs)):
            stamp = T0 + int(cs.stamp_ns[k])
            bag.write("/prisma/index/taxels", _taxel("index", stamp, cs.voltages[k]))
            bag.write("/ati/wrench", wrench_to_msg(types, WrenchSample(stamp + 700_000, cs.wrench[k], "ati")))
    out = tmp_path / "bag_cnn"
    assert train_main(["--model", "cnn", "--data", str(tmp_path / "cal"), "--finger", "index",
                       "--reference-topic", "/ati/wrench", "--epochs", "1", "--max-steps-per-epoch", "3",
                       "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "1500 pairs from 1500 taxel and 1500 wrench messages" in text
    _, meta = load_bundle(out)
    assert meta.training["samples_train"] + meta.training["samples_validation"] + \
        meta.training["samples_guard_dropped"] == 1500
    assert meta.training["samples_guard_dropped"] > 0  # one recording: chunks with guard gaps


def test_eval_prints_the_table_and_writes_plots_and_json(tmp_path, capsys):
    a = save_untrained_bundle(tmp_path / "cnn2", "cnn2")
    b = save_untrained_bundle(tmp_path / "ann", "ann")
    assert eval_main([str(a), str(b), "--push-samples", "400", "--slide-samples", "400",
                      "--plots", str(tmp_path / "img"), "--json", str(tmp_path / "r.json")]) == 0
    text = capsys.readouterr().out
    assert "| cnn2 |" in text and "| ann |" in text and "push Fz MSE" in text
    rows = json.loads((tmp_path / "r.json").read_text())
    assert [r["name"] for r in rows] == ["cnn2", "ann"]
    assert set(rows[0]["meets_targets"]) == {"push_fz", "slide_fx", "slide_fy", "low_force_mae"}
    assert sorted(p.name for p in (tmp_path / "img").iterdir()) == [
        "force_error_vs_force.png", "force_push_fz.png", "force_slide_fxfy.png"]


def test_eval_reports_a_bad_bundle_by_path(tmp_path, capsys):
    assert eval_main([str(tmp_path / "nope")]) == 2
    assert f"model bundle {tmp_path / 'nope'}: directory does not exist" in capsys.readouterr().err


@pytest.fixture
def five_finger_bag(tmp_path):
    """Scans at 100 Hz; fingers stamped 0.4 ms apart within a scan; the ring finger skips every
    7th scan; one thumb sample carries NaN voltages."""
    rng = np.random.default_rng(1)
    sent = {f: [] for f in FINGERS}
    with BagWriter(tmp_path / "in") as bag:
        for k in range(60):
            for j, finger in enumerate(FINGERS):
                if finger == "ring" and k % 7 == 3:
                    continue
                stamp = T0 + k * 10_000_000 + j * 400_000
                v = rng.uniform(0.4, 2.8, 9)
                if finger == "thumb" and k == 10:
                    v[2] = np.nan
                bag.write(f"/prisma/{finger}/taxels", _taxel(finger, stamp, v))
                sent[finger].append((stamp, v.astype(np.float32)))
        bag.write("/other/wrench", wrench_to_msg(types, WrenchSample(T0, np.zeros(6), "x")))
    return tmp_path / "in", sent


def test_estimate_bag_writes_one_wrench_per_taxel_message_with_its_stamp(tmp_path, five_finger_bag, capsys):
    bag_in, sent = five_finger_bag
    bundle = save_untrained_bundle(tmp_path / "cnn2", "cnn2", seed=9)
    assert estimate_bag_main([str(bag_in), str(tmp_path / "out"), "--bundle", str(bundle)]) == 0
    text = capsys.readouterr().out
    assert "thumb: 60 taxel messages -> 59 wrenches (1 rejected)" in text
    assert "ring: 51 taxel messages -> 51 wrenches (0 rejected)" in text
    got = {f: [] for f in FINGERS}
    with AnyReader([tmp_path / "out"], default_typestore=get_typestore()) as reader:
        assert {c.topic for c in reader.connections} == {f"/prisma/{f}/wrench" for f in FINGERS}
        assert {c.msgtype for c in reader.connections} == {"geometry_msgs/msg/WrenchStamped"}
        for connection, _, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            got[connection.topic.split("/")[2]].append(msg)
    estimator = ForceEstimator.from_bundle(bundle)
    for finger in FINGERS:
        expected = [(s, v) for s, v in sent[finger] if np.isfinite(v).all()]
        stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in got[finger]]
        assert stamps == [s for s, _ in expected]
        assert all(m.header.frame_id == f"prisma_{finger}_pad" for m in got[finger])
        w = np.array([[m.wrench.force.x, m.wrench.force.y, m.wrench.force.z,
                       m.wrench.torque.x, m.wrench.torque.y, m.wrench.torque.z] for m in got[finger]])
        np.testing.assert_allclose(w, estimator.estimate(np.stack([v for _, v in expected])), atol=1e-5)


def test_estimate_bag_refuses_a_bad_bundle_and_existing_output(tmp_path, five_finger_bag, capsys):
    bag_in, _ = five_finger_bag
    assert estimate_bag_main([str(bag_in), str(tmp_path / "out"), "--bundle", str(tmp_path / "missing")]) == 2
    assert "missing: directory does not exist" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
    with pytest.raises(SystemExit):
        estimate_bag_main([str(bag_in), str(bag_in)])


def test_estimate_bag_names_the_missing_taxel_topics_and_writes_nothing(tmp_path, capsys):
    """Like `prisma-estimate-bag prisma_sim_out/bags/glove out`: a bag without fingertip topics."""
    String = types("std_msgs/msg/String")
    with BagWriter(tmp_path / "glove") as bag:
        bag.write("/stag/object", String(data="mug"), timestamp_ns=T0)
        bag.write("/prisma/thumb/taxels", _taxel("thumb", T0, np.full(9, 1.0)))
    assert estimate_bag_main([str(tmp_path / "glove"), str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("prisma-estimate-bag: error: bag ") and err.count("\n") == 1
    assert ("has no topics '/prisma/index/taxels', '/prisma/middle/taxels', '/prisma/ring/taxels', "
            "'/prisma/little/taxels'; it has: /prisma/thumb/taxels (prisma_msgs/msg/TaxelArray), "
            "/stag/object (std_msgs/msg/String)") in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["glove"]
    # the fingers it has are fine
    bundle = save_untrained_bundle(tmp_path / "b", "ann")
    assert estimate_bag_main([str(tmp_path / "glove"), str(tmp_path / "out"), "--fingers", "thumb",
                              "--bundle", str(bundle)]) == 0
    assert "thumb: 1 taxel messages -> 1 wrenches" in capsys.readouterr().out


def test_estimate_bag_interrupted_leaves_no_bag_and_the_rerun_works(tmp_path, five_finger_bag, monkeypatch, capsys):
    from prisma_force_estimator import estimate_bag as module

    bag_in, _ = five_finger_bag
    bundle = save_untrained_bundle(tmp_path / "cnn2", "cnn2", seed=9)
    written = []

    def interrupted(types_, sample):
        if len(written) == 100:
            raise KeyboardInterrupt
        written.append(sample)
        return wrench_to_msg(types_, sample)

    monkeypatch.setattr(module, "wrench_to_msg", interrupted)
    assert estimate_bag_main([str(bag_in), str(tmp_path / "out"), "--bundle", str(bundle)]) == 130
    assert capsys.readouterr().err == "prisma-estimate-bag: interrupted\n"
    assert len(written) == 100
    assert not (tmp_path / "out").exists() and not [p for p in tmp_path.iterdir() if ".partial-" in p.name]
    monkeypatch.undo()
    assert estimate_bag_main([str(bag_in), str(tmp_path / "out"), "--bundle", str(bundle)]) == 0
    assert sum(1 for _ in read_bag(tmp_path / "out")) == 59 + 4 * 60 - 9  # thumb NaN sample, ring gaps


def test_train_from_a_bag_without_the_reference_topic_names_it_before_training(tmp_path, capsys):
    with BagWriter(tmp_path / "cal") as bag:
        for k in range(20):
            bag.write("/prisma/index/taxels", _taxel("index", T0 + k * 10_000_000, np.full(9, 1.2)))
    assert train_main(["--model", "cnn", "--data", str(tmp_path / "cal"), "--finger", "index",
                       "--out", str(tmp_path / "b")]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""  # no data generated, nothing trained
    assert (f"prisma-train-force: error: --data bag {tmp_path / 'cal'} has no topic '/ft_sensor/wrench'; "
            "it has: /prisma/index/taxels (prisma_msgs/msg/TaxelArray); choose the topics") in captured.err
    assert not (tmp_path / "b").exists()


def test_train_checks_out_before_training_and_replaces_only_a_bundle(tmp_path, capsys):
    mine = tmp_path / "thesis"
    mine.mkdir()
    (mine / "chapter1.tex").write_text("mine")
    assert train_main(["--model", "cnn2", "--samples", "6000", "--epochs", "1", "--out", str(mine)]) == 2
    captured = capsys.readouterr()
    assert "epoch" not in captured.out and "training" not in captured.out
    assert f"--out {mine} holds files that are not a model bundle (chapter1.tex)" in captured.err
    assert [p.name for p in mine.iterdir()] == ["chapter1.tex"]
    # an earlier bundle at --out is replaced by the new one
    old = save_untrained_bundle(tmp_path / "cnn2", "ann")
    assert train_main(["--model", "cnn2", "--samples", "6000", "--epochs", "1", "--max-steps-per-epoch", "2",
                       "--out", str(old)]) == 0
    _, meta = load_bundle(old)
    assert meta.model_kind == "cnn2" and meta.training["epochs_run"] == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cnn2", "thesis"]
