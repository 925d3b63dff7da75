"""ForceDataset and the contiguous-block train/validation split."""
import numpy as np
import pytest

from prisma_force_estimator.dataset import ForceDataset, contiguous_block_split
from prisma_force_estimator.normalisation import Normaliser


def _runs_of(mask):
    return np.flatnonzero(np.diff(mask.astype(int))) + 1


def test_split_keeps_each_trajectory_on_one_side():
    lengths = np.random.default_rng(1).integers(50, 400, size=60)
    block = np.repeat(np.arange(60), lengths)
    split = contiguous_block_split(block, 0.2, seed=3)
    assert split.dropped == 0
    assert len(split.train) + len(split.validation) == len(block)
    assert not set(block[split.train]) & set(block[split.validation])
    assert 0.18 <= len(split.validation) / len(block) <= 0.27


def test_split_is_seeded():
    block = np.repeat(np.arange(40), 100)
    a = contiguous_block_split(block, seed=5)
    b = contiguous_block_split(block, seed=5)
    c = contiguous_block_split(block, seed=6)
    assert np.array_equal(a.validation, b.validation)
    assert not np.array_equal(a.validation, c.validation)


def test_single_recording_is_cut_into_chunks_with_guard_gaps():
    n = 10_000
    split = contiguous_block_split(np.zeros(n, dtype=int), 0.2, seed=0, min_chunks=20, guard=10)
    side = np.full(n, -1)
    side[split.train] = 0
    side[split.validation] = 1
    assert 0.19 <= len(split.validation) / n <= 0.21
    # validation is made of whole contiguous chunks (about n/20 samples each)
    val = np.zeros(n, dtype=bool)
    val[split.validation] = True
    assert len(_runs_of(val)) <= 2 * 4 + 1
    # no training sample is the direct neighbour of a validation sample
    neighbours = (side[:-1] >= 0) & (side[1:] >= 0) & (side[:-1] != side[1:])
    assert not neighbours.any()
    assert split.dropped > 0


@pytest.mark.parametrize("fraction", [0.0, 1.0, -0.1])
def test_split_rejects_bad_fraction(fraction):
    with pytest.raises(ValueError, match="val_fraction"):
        contiguous_block_split(np.zeros(100), fraction)


def test_dataset_validates_shapes_and_selects_axes():
    n = 5
    wrench = np.arange(n * 6, dtype=np.float32).reshape(n, 6)
    ds = ForceDataset(np.zeros((n, 9)), wrench, np.arange(n), np.zeros(n))
    assert ds.targets(["fz", "fx"]).tolist() == wrench[:, [2, 0]].tolist()
    assert len(ds.subset(np.array([0, 2]))) == 2
    with pytest.raises(ValueError, match=r"voltages must have shape \[N, 9\]"):
        ForceDataset(np.zeros((n, 8)), wrench, np.arange(n), np.zeros(n))
    with pytest.raises(ValueError, match="wrench"):
        ForceDataset(np.zeros((n, 9)), wrench[:, :3], np.arange(n), np.zeros(n))


def test_dataset_from_calibration_set_uses_trajectories_as_blocks():
    from prisma_hand_sim.calibration import generate_calibration_set

    cs = generate_calibration_set(n_samples=3000, seed=4)
    ds = ForceDataset.from_calibration_set(cs)
    assert np.array_equal(ds.block, cs.trajectory)
    assert ds.voltages.shape == (3000, 9) and ds.wrench.shape == (3000, 6)


def test_normaliser_round_trip_and_constant_channels():
    values = np.array([[1.0, 5.0], [3.0, 5.0], [5.0, 5.0]])
    norm = Normaliser.fit(values)
    z = norm.apply(values)
    assert np.allclose(z[:, 0].mean(), 0) and np.allclose(z[:, 0].std(), 1)
    assert np.allclose(z[:, 1], 0)  # constant channel: centred, not divided by zero
    assert np.allclose(norm.invert(z), values)
    assert Normaliser.from_dict(norm.to_dict()).std.tolist() == norm.std.tolist()
    with pytest.raises(ValueError, match="positive"):
        Normaliser.from_dict({"mean": [0.0], "std": [0.0]})
