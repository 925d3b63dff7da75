"""Glove datasets: the public STAG metadata.mat format and an HDF5 equivalent.

metadata.mat (docs/glove.md) holds pressure [N, 32, 32] raw counts and per-frame objectId,
recordingId, splitId, hasValidLabel, isBalanced, plus the cell array `objects` of class names.
The public files are MATLAB v5 (scipy.io.loadmat); MATLAB v7.3 files are HDF5 underneath (column
major, so every array comes back with its axes reversed, and strings are cell arrays of object
references to uint16 character arrays), read with h5py. Our own HDF5 files keep the same field names,
row-major, with plain string arrays.

Edge cases the loader handles (src/stag_glove/test/test_dataset.py):
- a v5 file with a single frame: MATLAB keeps the leading 1 of a 1x32x32 array, so the file is read
  without squeezing singleton axes (scipy's squeeze_me would drop the frame axis);
- names stored as a char matrix (MATLAB `char({'cup', 'pen'})`, rows padded with blanks) instead
  of a cell array, in v5 and in v7.3 (HDF5 uint16 array, column-major);
- a v7.3 file written row-major by a tool other than MATLAB (pressure stored [N, 32, 32] instead of
  MATLAB's reversed [32, 32, N]): detected from the per-frame fields' length N. With N = 32 the
  shapes cannot tell, so the orientation is taken from the data: a recording's unconnected cells
  (no sensor) never change, so the reading in which more cells stay constant over the frames is
  the one whose frames are the glove's. A file in which no cell stays constant in either reading
  is read as MATLAB's layout.
h5py and scipy are imported when a file is read or written, not with this module.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from prisma_common.atomic import atomic_output

MAT73_SIGNATURE = b"MATLAB 7.3 MAT-file"
SPLIT_TRAIN, SPLIT_TEST = 0, 1
REQUIRED = ("pressure", "objectId", "recordingId", "splitId", "hasValidLabel", "isBalanced", "objects")


@dataclass
class GloveDataset:
    """Frames and labels in the STAG layout. `object_id` indexes `objects`."""

    pressure: np.ndarray          # [N, rows, cols] raw 10-bit counts (uint16)
    object_id: np.ndarray         # int [N]
    recording_id: np.ndarray      # int [N]
    split_id: np.ndarray          # int [N], 0 train / 1 test
    has_valid_label: np.ndarray   # bool [N]
    is_balanced: np.ndarray       # bool [N]
    objects: list[str]
    weights_g: np.ndarray | None = None   # float [len(objects)], grams, when known
    frame: np.ndarray | None = None       # int [N], frame index inside its recording
    extras: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = self.pressure.shape[0]
        if self.pressure.ndim != 3:
            raise ValueError(f"pressure must be [N, rows, cols], got shape {self.pressure.shape}")
        for name in ("object_id", "recording_id", "split_id", "has_valid_label", "is_balanced"):
            value = np.asarray(getattr(self, name)).reshape(-1)
            if value.shape[0] != n:
                raise ValueError(f"{name} has {value.shape[0]} entries, pressure has {n} frames")
            setattr(self, name, value)
        self.object_id = self.object_id.astype(np.int64)
        self.recording_id = self.recording_id.astype(np.int64)
        self.split_id = self.split_id.astype(np.int64)
        self.has_valid_label = self.has_valid_label.astype(bool)
        self.is_balanced = self.is_balanced.astype(bool)
        self.objects = [str(o) for o in self.objects]
        if n and self.object_id.max() >= len(self.objects):
            raise ValueError(f"objectId {self.object_id.max()} but only {len(self.objects)} objects")
        if self.frame is None:
            self.frame = np.zeros(n, dtype=np.int64)
            for rec in np.unique(self.recording_id):
                idx = np.nonzero(self.recording_id == rec)[0]
                self.frame[idx] = np.arange(idx.size)

    def __len__(self) -> int:
        return int(self.pressure.shape[0])

    def subset(self, index: np.ndarray) -> GloveDataset:
        assert self.frame is not None  # numbered by __post_init__
        return GloveDataset(self.pressure[index], self.object_id[index], self.recording_id[index],
                            self.split_id[index], self.has_valid_label[index], self.is_balanced[index],
                            list(self.objects), self.weights_g, self.frame[index],
                            {k: v[index] for k, v in self.extras.items()})


def balance_mask(object_id: np.ndarray, split: np.ndarray, valid: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """isBalanced: per split, the same number of valid frames for every class (random subset)."""
    balanced = np.zeros(len(object_id), bool)
    for s in np.unique(split):
        counts = [np.sum(valid & (split == s) & (object_id == k)) for k in np.unique(object_id)]
        keep = min(c for c in counts if c > 0) if any(counts) else 0
        for k in np.unique(object_id):
            idx = np.nonzero(valid & (split == s) & (object_id == k))[0]
            if idx.size:
                balanced[rng.choice(idx, size=min(keep, idx.size), replace=False)] = True
    return balanced


# ---------------------------------------------------------------------------------------- reading
def load_dataset(path: str | Path) -> GloveDataset:
    """Read metadata.mat (MATLAB v5 or v7.3) or our HDF5 (.h5/.hdf5).

    FileNotFoundError for a missing file; ValueError naming the file for one that is not a
    readable dataset (damaged, truncated, another format, fields missing)."""
    import h5py
    from scipy.io.matlab import MatReadError

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"dataset {path} does not exist")
    with open(path, "rb") as stream:
        head = stream.read(128)
    if head.startswith(MAT73_SIGNATURE):
        reader, kind = _read_mat73, "a MATLAB v7.3 file"
    elif path.suffix == ".mat":
        reader, kind = _read_mat5, "a MATLAB v5 file"
    elif h5py.is_hdf5(path):
        reader, kind = _read_hdf5, "an HDF5 file"
    else:
        raise ValueError(f"{path}: neither a .mat file nor HDF5")
    try:
        fields = reader(path)
    except (OSError, ValueError, MatReadError) as exc:  # what scipy and h5py raise for a damaged file
        raise ValueError(f"{path}: cannot be read as {kind} ({exc})") from None
    return _from_fields(fields, str(path))


def _from_fields(f: dict, source: str) -> GloveDataset:
    f = dict(f)
    # the public weights set marks valid frames as graspValid and has no balance flag
    if "hasValidLabel" not in f and "graspValid" in f:
        f["hasValidLabel"] = f["graspValid"]
    if "isBalanced" not in f and "pressure" in f:
        f["isBalanced"] = np.ones(np.asarray(f["pressure"]).shape[0], dtype=bool)
    missing = [k for k in REQUIRED if k not in f]
    if missing:
        raise ValueError(f"{source}: missing field(s) {missing}; a STAG metadata file has {list(REQUIRED)}")
    pressure = np.asarray(f["pressure"])
    if pressure.ndim != 3:
        raise ValueError(f"{source}: pressure must be [N, rows, cols], got shape {pressure.shape}")
    split = np.asarray(f["splitId"]).reshape(-1).astype(np.int64)
    if "splits" in f:  # map the file's split names onto 0 = train, 1 = test
        names = [str(s).strip().lower() for s in _strings(f["splits"])]
        if "train" in names and "test" in names:
            lookup = np.full(len(names), -1, dtype=np.int64)
            lookup[names.index("train")], lookup[names.index("test")] = SPLIT_TRAIN, SPLIT_TEST
            split = lookup[split]
    weights = f.get("weights")
    # raw counts are integers even when MATLAB stored them as double
    integral = np.issubdtype(pressure.dtype, np.integer) or bool(np.all(np.mod(pressure, 1) == 0))
    return GloveDataset(
        pressure=pressure.astype(np.uint16 if integral else np.float32),
        object_id=np.asarray(f["objectId"]).reshape(-1),
        recording_id=np.asarray(f["recordingId"]).reshape(-1),
        split_id=split,
        has_valid_label=np.asarray(f["hasValidLabel"]).reshape(-1),
        is_balanced=np.asarray(f["isBalanced"]).reshape(-1),
        objects=_strings(f["objects"]),
        weights_g=None if weights is None else np.asarray(weights, dtype=np.float64).reshape(-1),
        frame=None if "frame" not in f else np.asarray(f["frame"]).reshape(-1).astype(np.int64),
    )


def _strings(value) -> list[str]:
    """Names from a cell array (nested object arrays from scipy, lists from v7.3), a char matrix
    (a string per row) or a single string."""
    if isinstance(value, str):
        return [value]
    out: list[str] = []
    for item in np.asarray(value, dtype=object).reshape(-1):
        while isinstance(item, np.ndarray) and item.dtype == object and item.size == 1:
            item = item.reshape(-1)[0]
        if isinstance(item, np.ndarray) and item.dtype.kind == "U":
            # a cell's 1xL char array reads as one string; a char matrix inside a cell as its rows
            out += [str(s).strip() for s in item.reshape(-1)] if item.size > 1 else [str(item.reshape(-1)[0]).strip()]
            continue
        if isinstance(item, np.ndarray):
            item = str(item.squeeze())
        if isinstance(item, bytes):
            item = item.decode()
        out.append(str(item).strip())
    return out


def _read_mat5(path: Path) -> dict:
    import scipy.io

    # No squeeze_me: it would turn a single frame's 1x32x32 pressure into 32x32 (and the per-frame
    # vectors into scalars); _from_fields flattens the vectors and _strings unwraps the cells.
    raw = scipy.io.loadmat(path, struct_as_record=False)
    return {k: v for k, v in raw.items() if not k.startswith("__")}


def _read_mat73(path: Path) -> dict:
    import h5py

    out: dict = {}
    raw_pressure = None
    with h5py.File(path, "r") as h5:
        for key, node in h5.items():
            if key.startswith("#") or not isinstance(node, h5py.Dataset):
                continue
            out[key] = _mat73_value(h5, node)
            if key == "pressure":
                raw_pressure = np.asarray(node[()])
    if raw_pressure is not None and raw_pressure.ndim == 3:
        out["pressure"] = _orient_pressure(raw_pressure, _frame_count(out))
    return out


def _frame_count(fields: dict) -> int | None:
    """N from the per-frame fields (a vector's length does not depend on its storage order)."""
    for key in ("objectId", "recordingId", "splitId"):
        if key in fields:
            return int(np.asarray(fields[key]).size)
    return None


def _constant_cells(frames: np.ndarray) -> int:
    """Cells whose value never changes over the frames [N, rows, cols]."""
    return int(np.sum(frames.max(axis=0) == frames.min(axis=0)))


def _orient_pressure(stored: np.ndarray, n_frames: int | None) -> np.ndarray:
    """[N, rows, cols] from a v7.3 pressure dataset as stored: MATLAB's column-major [cols, rows, N],
    or row-major [N, rows, cols] from a writer other than MATLAB (see the module docstring)."""
    matlab, row_major = np.transpose(stored), stored
    if n_frames is None:
        return matlab
    fits = [a for a in (matlab, row_major) if a.shape[0] == n_frames]
    if len(fits) == 1:
        return fits[0]
    if len(fits) == 2 and _constant_cells(row_major) > _constant_cells(matlab):
        return row_major  # N == rows == cols (32): decided by the unconnected cells
    return matlab


def _chars(data: np.ndarray) -> str | list[str]:
    """A MATLAB char array as stored in v7.3 (uint16 codes, column-major): one string for a row of
    characters, one per row for a char matrix (MATLAB pads its rows with blanks)."""
    codes = np.transpose(np.atleast_2d(np.asarray(data)))  # back to MATLAB's [rows, cols]
    rows = ["".join(map(chr, row)).rstrip("\x00") for row in codes.reshape(codes.shape[0], -1)]
    return rows[0] if len(rows) == 1 else [row.rstrip(" ") for row in rows]


def _mat73_value(h5, node):
    cls = node.attrs.get("MATLAB_class", b"")
    cls = cls.decode() if isinstance(cls, bytes) else str(cls)
    if node.attrs.get("MATLAB_empty", 0):  # an empty MATLAB value stores its dimensions as data
        return "" if cls == "char" else [] if cls == "cell" else np.zeros(0)
    data = node[()]
    if cls == "cell":
        return [_mat73_value(h5, h5[ref]) for ref in np.asarray(data).T.reshape(-1)]
    if cls == "char":
        return _chars(data)
    array = np.asarray(data)
    # MATLAB is column-major: reverse the axes to get the MATLAB [N, rows, cols] order back
    array = np.transpose(array) if array.ndim > 1 else array
    if cls == "logical":
        array = array.astype(bool)
    return array


def _read_hdf5(path: Path) -> dict:
    import h5py

    out: dict = {}
    with h5py.File(path, "r") as h5:
        for key, node in h5.items():
            value = node[()]
            if isinstance(value, np.ndarray) and value.dtype.kind in "OS":
                value = [v.decode() if isinstance(v, bytes) else str(v) for v in value.reshape(-1)]
            out[key] = value
    return out


# ---------------------------------------------------------------------------------------- writing
def _fields(ds: GloveDataset) -> dict:
    assert ds.frame is not None  # numbered by __post_init__
    out = {
        "pressure": ds.pressure,
        "objectId": ds.object_id.astype(np.int32),
        "recordingId": ds.recording_id.astype(np.int32),
        "splitId": ds.split_id.astype(np.int32),
        "hasValidLabel": ds.has_valid_label.astype(np.uint8),
        "isBalanced": ds.is_balanced.astype(np.uint8),
        "frame": ds.frame.astype(np.int32),
        "objects": list(ds.objects),
        "splits": ["train", "test"],
    }
    if ds.weights_g is not None:
        out["weights"] = np.asarray(ds.weights_g, dtype=np.float64)
    return out


def _write(path: str | Path, writer: Callable[[Path], None]) -> None:
    """Whole or not at all: `writer` writes a staged file, renamed onto `path` when complete."""
    with atomic_output(path) as staged:
        writer(staged)


def save_mat(ds: GloveDataset, path: str | Path) -> None:
    """MATLAB v5 metadata.mat, as the public STAG files are."""
    import scipy.io

    fields = _fields(ds)
    for key in ("objects", "splits"):
        fields[key] = np.array(fields[key], dtype=object)
    for key in ("objectId", "recordingId", "splitId", "hasValidLabel", "isBalanced", "frame"):
        fields[key] = fields[key].reshape(1, -1)  # MATLAB row vectors, as in the public files
    _write(path, lambda staged: scipy.io.savemat(staged, fields, do_compression=True))


def save_mat73(ds: GloveDataset, path: str | Path) -> None:
    """MATLAB v7.3 layout (HDF5 with a 512-byte MATLAB header, column-major arrays, cell arrays of
    uint16 char arrays under #refs#), so the v7.3 reader is tested against the real structure."""
    _write(path, lambda staged: _save_mat73(ds, staged))


def _save_mat73(ds: GloveDataset, path: Path) -> None:
    import h5py

    fields = _fields(ds)
    with h5py.File(path, "w", userblock_size=512) as h5:
        refs = h5.create_group("#refs#")
        counter = 0
        for key, value in fields.items():
            if isinstance(value, list):
                ref_array = np.empty((len(value), 1), dtype=h5py.ref_dtype)
                for i, text in enumerate(value):
                    name = f"s{counter}"
                    counter += 1
                    # a MATLAB 1xL char array is stored as an HDF5 (L, 1) uint16 dataset
                    chars = refs.create_dataset(name, data=np.array([[ord(c)] for c in text] or [[0]],
                                                                    dtype=np.uint16))
                    chars.attrs["MATLAB_class"] = np.bytes_("char")
                    ref_array[i, 0] = chars.ref
                dset = h5.create_dataset(key, data=ref_array)  # MATLAB 1xN cell = HDF5 (N, 1)
                dset.attrs["MATLAB_class"] = np.bytes_("cell")
            else:
                array = np.asarray(value)
                if array.ndim == 1:
                    array = array.reshape(1, -1)
                cls = {"u": "uint", "i": "int", "f": "double" if array.dtype == np.float64 else "single"}
                name = cls[array.dtype.kind]
                if array.dtype.kind in "ui":
                    name += str(array.dtype.itemsize * 8)
                dset = h5.create_dataset(key, data=np.transpose(array))
                dset.attrs["MATLAB_class"] = np.bytes_(name)
    header = (MAT73_SIGNATURE + b", Platform: GLNXA64, Created by: stag_glove").ljust(116, b" ")
    with open(path, "r+b") as stream:
        stream.write(header + b"\x00" * 8 + b"\x00\x02IM")


def save_hdf5(ds: GloveDataset, path: str | Path) -> None:
    """Row-major HDF5 with the metadata.mat field names (compressed pressure)."""
    _write(path, lambda staged: _save_hdf5(ds, staged))


def _save_hdf5(ds: GloveDataset, path: Path) -> None:
    import h5py

    with h5py.File(path, "w") as h5:
        for key, value in _fields(ds).items():
            if isinstance(value, list):
                h5.create_dataset(key, data=np.array(value, dtype=h5py.string_dtype()))
            elif key == "pressure":
                h5.create_dataset(key, data=value, compression="gzip", chunks=(min(256, len(value)) or 1,
                                                                                *value.shape[1:]))
            else:
                h5.create_dataset(key, data=value)
        h5.attrs["format"] = "stag_glove dataset v1 (metadata.mat fields, row-major)"


def save_dataset(ds: GloveDataset, path: str | Path) -> None:
    """By extension: .mat -> MATLAB v5, .h5/.hdf5 -> HDF5."""
    path = Path(path)
    if path.suffix == ".mat":
        save_mat(ds, path)
    elif path.suffix in (".h5", ".hdf5"):
        save_hdf5(ds, path)
    else:
        raise ValueError(f"{path}: use a .mat, .h5 or .hdf5 file name")
