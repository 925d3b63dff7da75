"""STAG metadata.mat loader (MATLAB v5 and v7.3) and the HDF5 equivalent, on small files written
in those formats."""
import h5py
import numpy as np
import pytest
import scipy.io

from stag_glove.dataset import GloveDataset, load_dataset, save_hdf5, save_mat, save_mat73
from stag_glove.layout import load_layout, mask_from_pressure
from stag_glove.synthetic import SyntheticConfig, SyntheticGlove


@pytest.fixture(scope="module")
def small():
    glove = SyntheticGlove(SyntheticConfig(n_objects=3, sessions=2, test_sessions=(1,), frames_per_session=25, seed=3))
    return glove.object_dataset()


def same(a: GloveDataset, b: GloveDataset):
    np.testing.assert_array_equal(a.pressure, b.pressure)
    for name in ("object_id", "recording_id", "split_id", "has_valid_label", "is_balanced", "frame"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.objects == b.objects
    np.testing.assert_allclose(a.weights_g, b.weights_g)


@pytest.mark.parametrize("writer,suffix", [(save_mat, ".mat"), (save_mat73, ".mat"), (save_hdf5, ".h5")])
def test_round_trip_and_mask_recovery(tmp_path, small, writer, suffix):
    path = tmp_path / f"metadata{suffix}"
    writer(small, path)
    back = load_dataset(path)
    same(small, back)
    assert back.pressure.dtype == np.uint16 and back.pressure.shape == (len(small), 32, 32)
    mask = mask_from_pressure(back.pressure)
    assert mask.sum() == 548
    np.testing.assert_array_equal(mask, load_layout().mask)


def test_v73_file_is_hdf5_with_matlab_layout(tmp_path, small):
    path = tmp_path / "metadata.mat"
    save_mat73(small, path)
    assert path.read_bytes()[:19] == b"MATLAB 7.3 MAT-file"
    with h5py.File(path, "r") as h5:
        assert h5["pressure"].shape == (32, 32, len(small))  # column-major: axes reversed
        assert h5["objects"].attrs["MATLAB_class"] == b"cell"


def test_public_style_v5_file_with_double_pressure_and_split_names(tmp_path):
    """The public files store pressure as double and carry split names; only the named fields
    are needed."""
    rng = np.random.default_rng(0)
    n = 12
    pressure = np.zeros((n, 32, 32))
    pressure[:, 3:5, 3:5] = rng.integers(480, 700, (n, 2, 2))
    scipy.io.savemat(tmp_path / "metadata.mat", {
        "pressure": pressure, "objectId": np.arange(n).reshape(1, -1) % 2, "recordingId": np.zeros((1, n)),
        "splitId": np.array([[1] * 6 + [0] * 6]), "splits": np.array(["test", "train"], dtype=object),
        "hasValidLabel": np.ones((1, n)), "isBalanced": np.ones((1, n)),
        "objects": np.array(["empty_hand", "mug"], dtype=object)})
    ds = load_dataset(tmp_path / "metadata.mat")
    assert ds.pressure.dtype == np.uint16
    assert ds.objects == ["empty_hand", "mug"]
    assert ds.split_id.tolist() == [0] * 6 + [1] * 6  # remapped to 0 = train, 1 = test
    assert mask_from_pressure(ds.pressure).sum() == 4


def test_weights_style_file_with_grasp_valid_and_no_balance_flag(tmp_path):
    n = 6
    scipy.io.savemat(tmp_path / "metadata.mat", {
        "pressure": np.full((n, 32, 32), 500.0), "objectId": np.array([[0, 0, 0, 1, 1, 1]]),
        "recordingId": np.array([[0, 0, 0, 1, 1, 1]]), "splitId": np.zeros((1, n)),
        "graspValid": np.array([[1, 0, 1, 1, 1, 0]]), "objects": np.array(["cup", "pen"], dtype=object),
        "weights": np.array([[250.0, 12.0]])})
    ds = load_dataset(tmp_path / "metadata.mat")
    assert ds.has_valid_label.tolist() == [True, False, True, True, True, False]
    assert ds.is_balanced.all() and ds.weights_g.tolist() == [250.0, 12.0]


def test_missing_fields_and_files_are_named(tmp_path):
    scipy.io.savemat(tmp_path / "bad.mat", {"pressure": np.zeros((2, 32, 32))})
    with pytest.raises(ValueError, match="objectId"):
        load_dataset(tmp_path / "bad.mat")
    with pytest.raises(FileNotFoundError, match="nope.mat"):
        load_dataset(tmp_path / "nope.mat")


# ---------------------------------------------------------------------------------- edge cases
def test_single_frame_v5_file_keeps_its_frame_axis(tmp_path, small):
    """scipy's squeeze_me would turn the 1x32x32 pressure into 32x32 and the vectors into scalars."""
    one = small.subset(np.array([7]))
    save_mat(one, tmp_path / "one.mat")
    assert scipy.io.loadmat(tmp_path / "one.mat")["pressure"].shape == (1, 32, 32)
    back = load_dataset(tmp_path / "one.mat")
    same(one, back)
    assert back.pressure.shape == (1, 32, 32) and back.object_id.tolist() == [small.object_id[7]]


def _char_matrix(names: list[str]) -> np.ndarray:
    """MATLAB char(names): one row per name, padded with blanks to the longest."""
    width = max(map(len, names))
    return np.array([[ord(c) for c in name.ljust(width)] for name in names], dtype=np.uint16)


def test_object_names_as_a_char_matrix_in_v73(tmp_path, small):
    path = tmp_path / "metadata.mat"
    save_mat73(small, path)
    names = small.objects
    assert len(set(map(len, names))) > 1  # the rows are padded
    with h5py.File(path, "r+") as h5:  # as MATLAB stores char(objects): [cols, rows] uint16
        del h5["objects"]
        h5.create_dataset("objects", data=_char_matrix(names).T).attrs["MATLAB_class"] = np.bytes_("char")
    assert load_dataset(path).objects == names


def test_object_names_as_a_char_matrix_in_v5(tmp_path, small):
    path = tmp_path / "metadata.mat"
    save_mat(small, path)
    fields = scipy.io.loadmat(path)
    fields = {k: v for k, v in fields.items() if not k.startswith("__")}
    fields["objects"] = np.array(small.objects)  # a char matrix, not a cell array
    scipy.io.savemat(path, fields)
    assert scipy.io.loadmat(path)["objects"].dtype.kind == "U"
    assert load_dataset(path).objects == small.objects


def _row_major_v73(ds: GloveDataset, path):
    """A v7.3 file (MATLAB header, MATLAB class attributes) whose pressure a non-MATLAB writer stored
    row-major, [N, 32, 32], where MATLAB stores [32, 32, N]."""
    save_mat73(ds, path)
    with h5py.File(path, "r+") as h5:
        del h5["pressure"]
        h5.create_dataset("pressure", data=ds.pressure).attrs["MATLAB_class"] = np.bytes_("uint16")


@pytest.mark.parametrize("frames", [32, 20])
def test_row_major_v73_is_detected(tmp_path, small, frames):
    """N = 32 frames make [N, 32, 32] and [32, 32, N] indistinguishable by shape; the unconnected
    cells, constant in every frame, tell which axis holds the frames."""
    part = small.subset(np.arange(frames))
    _row_major_v73(part, tmp_path / "row_major.mat")
    with h5py.File(tmp_path / "row_major.mat", "r") as h5:
        assert h5["pressure"].shape == (frames, 32, 32)
    same(part, load_dataset(tmp_path / "row_major.mat"))
    # MATLAB's own layout with the same frames still reads as before
    save_mat73(part, tmp_path / "matlab.mat")
    same(part, load_dataset(tmp_path / "matlab.mat"))


def test_unreadable_files_are_named(tmp_path, small):
    (tmp_path / "garbage.mat").write_bytes(b"MATLAB? no" * 20)
    with pytest.raises(ValueError, match="garbage.mat: cannot be read as a MATLAB v5 file"):
        load_dataset(tmp_path / "garbage.mat")
    save_mat(small, tmp_path / "whole.mat")
    data = (tmp_path / "whole.mat").read_bytes()
    for size in (10, 300, len(data) // 2):  # truncated copies: scipy raises MatReadError or OSError
        (tmp_path / "cut.mat").write_bytes(data[:size])
        with pytest.raises(ValueError, match="cut.mat: cannot be read as a MATLAB v5 file"):
            load_dataset(tmp_path / "cut.mat")
    save_hdf5(small, tmp_path / "whole.h5")
    (tmp_path / "cut.h5").write_bytes((tmp_path / "whole.h5").read_bytes()[:2000])
    with pytest.raises(ValueError, match="cut.h5: cannot be read as an HDF5 file"):
        load_dataset(tmp_path / "cut.h5")
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(ValueError, match="notes.txt: neither a .mat file nor HDF5"):
        load_dataset(tmp_path / "notes.txt")
