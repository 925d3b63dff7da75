"""WrenchPipeline: one network call per scan for all fingers, NaN samples rejected and counted."""
import numpy as np
import pytest

from prisma_common.hand import FINGERS
from prisma_force_estimator.bundle import save_untrained_bundle
from prisma_force_estimator.force_estimator_core import TaxelSample, WrenchPipeline, build_estimators
from prisma_force_estimator.inference import ForceEstimator


class CountingEstimator:
    """Wraps a ForceEstimator and records the batch size of every call."""

    def __init__(self, inner):
        self.inner = inner
        self.axes = inner.axes
        self.calls = []

    def estimate(self, voltages):
        self.calls.append(len(voltages))
        return self.inner.estimate(voltages)


@pytest.fixture(scope="module")
def bundles(tmp_path_factory):
    root = tmp_path_factory.mktemp("pipe")
    return {"cnn2": save_untrained_bundle(root / "cnn2", "cnn2", seed=1),
            "cnn": save_untrained_bundle(root / "cnn", "cnn", seed=2)}


_RNG = np.random.default_rng(0)  # one generator for every _scan call: each scan reads new voltages


def _scan(stamp_ns, fingers=FINGERS, rng=_RNG):
    return [TaxelSample(f, stamp_ns, rng.uniform(0.3, 3.0, 9).astype(np.float32), f"{f}_frame") for f in fingers]


def test_a_full_scan_is_one_batch_with_each_input_stamp(bundles):
    counting = CountingEstimator(ForceEstimator.from_bundle(bundles["cnn2"]))
    pipe = WrenchPipeline({f: counting for f in FINGERS})
    scan = _scan(1_000_000_000)
    outputs = []
    for sample in scan:
        outputs += pipe.add(sample)
    assert counting.calls == [5]
    assert [f for f, _ in outputs] == list(FINGERS)
    reference = counting.inner.estimate(np.stack([s.voltages for s in scan]))
    for (finger, wrench), sample, row in zip(outputs, scan, reference):
        assert wrench.stamp_ns == sample.stamp_ns
        assert wrench.frame_id == f"{finger}_frame"
        assert np.allclose(wrench.wrench, row, atol=1e-5)


def test_a_silent_finger_delays_the_others_by_one_scan_at_most(bundles):
    counting = CountingEstimator(ForceEstimator.from_bundle(bundles["cnn2"]))
    pipe = WrenchPipeline({f: counting for f in FINGERS})
    out = []
    for sample in _scan(0, FINGERS[:4]):
        out += pipe.add(sample)
    assert out == []  # waiting for the little finger
    out = pipe.add(_scan(10_000_000, ["thumb"])[0])  # next scan starts: previous one is flushed
    assert [f for f, _ in out] == list(FINGERS[:4]) and all(w.stamp_ns == 0 for _, w in out)
    assert counting.calls == [4]
    assert [f for f, _ in pipe.flush()] == ["thumb"]


def test_stamp_outside_the_window_starts_a_new_batch(bundles):
    est = ForceEstimator.from_bundle(bundles["cnn2"])
    pipe = WrenchPipeline({f: est for f in FINGERS}, batch_window_ns=2_000_000)
    assert pipe.add(_scan(0, ["thumb"])[0]) == []
    assert pipe.add(_scan(1_500_000, ["index"])[0]) == []  # same scan, 1.5 ms later
    out = pipe.add(_scan(5_000_000, ["middle"])[0])
    assert [(f, w.stamp_ns) for f, w in out] == [("thumb", 0), ("index", 1_500_000)]


def test_nan_samples_are_rejected_counted_and_do_not_stop_the_rest(bundles):
    est = ForceEstimator.from_bundle(bundles["cnn2"])
    pipe = WrenchPipeline({f: est for f in FINGERS})
    scan = _scan(0)
    scan[2].voltages[5] = np.nan
    out = []
    for sample in scan:
        out += pipe.add(sample)
    assert [f for f, _ in out] == ["thumb", "index", "ring", "little"]
    assert pipe.counts["middle"].rejected == 1 and pipe.counts["middle"].estimated == 0
    assert pipe.counts["thumb"].estimated == 1
    out = []
    for sample in _scan(10_000_000):
        out += pipe.add(sample)
    assert len(out) == 5  # the next scan of the middle finger goes through again


def test_per_finger_bundles_and_force_only_models(bundles):
    estimators = build_estimators({"thumb": str(bundles["cnn"]), "index": str(bundles["cnn2"]),
                                   "middle": str(bundles["cnn2"])})
    assert estimators["index"] is estimators["middle"]  # one load per distinct bundle
    pipe = WrenchPipeline(estimators, frame_id_template="{finger}_pad")
    out = dict()
    for sample in _scan(0, ["thumb", "index", "middle"]):
        out.update(pipe.add(sample))
    assert np.isnan(out["thumb"].wrench[3:]).all() and np.isfinite(out["thumb"].wrench[:3]).all()
    assert np.isfinite(out["index"].wrench).all()
    assert out["middle"].frame_id == "middle_pad"


def test_unknown_fingers_are_ignored_and_counted(bundles):
    est = ForceEstimator.from_bundle(bundles["cnn2"])
    pipe = WrenchPipeline({"thumb": est})
    assert pipe.add(_scan(0, ["index"])[0]) == []
    assert pipe.ignored == 1
    with pytest.raises(ValueError, match="at least one finger"):
        WrenchPipeline({})
