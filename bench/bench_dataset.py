"""LeRobot dataset export (python bench/run.py --only dataset_export --only dataset_writer_vs_reading).

Both on prisma-sim's teleop session bag (`prisma-sim --short --scenarios teleop`, made once in a
temporary directory: 12 s of session, ~20 500 messages of the topics the export reads):
dataset_export: frames per second of the whole export, `export_bags` (read, decode with the owning
  packages' converters, sample-and-hold) then `write_dataset`. Needed 50 frames/s: a session
  exports at least as fast as it was recorded at the default 50 fps.
dataset_writer_vs_reading: the time to read the same bag alone (`read_bag` of the same topics,
  deserialised) over the time `write_dataset` takes for its frames. Needed 1: the writer costs less
  than the reading.
dataset_minutes_per_gib: minutes of session one GiB of dataset holds (every file of the written
  dataset, meta/ included; the session's length is its frames over the fps). Needed 60: an hour of
  demonstrations fits in a GiB. The notes give the size per minute in MiB.
"""
from __future__ import annotations

import contextlib
import functools
import io
import tempfile
import time
from pathlib import Path

from prisma_common.bag import read_bag
from prisma_dataset.bag_export import ExportOptions, export_bags, plan_bag
from prisma_dataset.lerobot_format import Dataset, write_dataset
from prisma_sim.sim_cli import main as sim_main
from run import Benchmark

REPEATS = 3


@functools.cache
def _bag() -> Path:
    out = Path(tempfile.mkdtemp(prefix="prisma_dataset_bench_")) / "sim"
    with contextlib.redirect_stdout(io.StringIO()):
        code = sim_main(["--short", "--scenarios", "teleop", "--no-plots", "--out", str(out)])
    if code != 0:
        raise RuntimeError(f"prisma-sim --short --scenarios teleop exited {code}")
    return out / "bags" / "teleop"


def _best(run) -> float:
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return min(times)


@functools.cache
def _figures() -> dict[str, float]:
    bag = _bag()
    options = ExportOptions(whole_bag=True)
    topics = plan_bag(bag, options).topics()
    dataset: list[Dataset] = []
    out = Path(tempfile.mkdtemp(prefix="prisma_dataset_bench_out_"))
    read_s = _best(lambda: sum(1 for _ in read_bag(bag, topics)))
    export_s = _best(lambda: dataset.append(export_bags([bag], options)))
    write_s = _best(lambda: write_dataset(out / "ds", dataset[-1]))
    frames = dataset[-1].total_frames
    size_bytes = sum(f.stat().st_size for f in (out / "ds").rglob("*") if f.is_file())
    minutes = frames / dataset[-1].fps / 60.0
    return {"frames": frames, "read_s": read_s, "export_s": export_s, "write_s": write_s,
            "size_bytes": size_bytes, "minutes": minutes}


def _export_rate() -> float:
    f = _figures()
    EXPORT.notes.update(frames=f["frames"], read_alone_s=round(f["read_s"], 3), export_s=round(f["export_s"], 3),
                        write_s=round(f["write_s"], 3))
    return f["frames"] / (f["export_s"] + f["write_s"])


def _writer_vs_reading() -> float:
    f = _figures()
    return f["read_s"] / f["write_s"]


def _minutes_per_gib() -> float:
    f = _figures()
    SIZE.notes.update(dataset_bytes=f["size_bytes"], session_s=round(f["minutes"] * 60.0, 2),
                      mib_per_minute=round(f["size_bytes"] / 2**20 / f["minutes"], 2))
    return f["minutes"] / (f["size_bytes"] / 2**30)


EXPORT = Benchmark("dataset_export", _export_rate, "frames/s", 50.0)
WRITER = Benchmark("dataset_writer_vs_reading", _writer_vs_reading, "x", 1.0)
SIZE = Benchmark("dataset_minutes_per_gib", _minutes_per_gib, "min/GiB", 60.0)
BENCHMARKS = [EXPORT, WRITER, SIZE]
