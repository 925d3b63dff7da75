"""A busy computer to run the graph beside: one CPU hog per core and one memory-bandwidth hog, all at
the default priority, as a recorder, rqt, RViz and a browser load a robot's computer.

    PYTHONPATH=test/support python3 -m prisma_testing.load_harness                 # until ctrl-C
    PYTHONPATH=test/support python3 -m prisma_testing.load_harness --seconds 120   # for two minutes

In tests: `with machine_load(): ...` starts the hogs (separate processes, so they compete with the
nodes for the cores and the memory bus, not for this process's GIL) and stops them on exit.
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager

MEMORY_HOG_BYTES = 256 * 1024 * 1024  # far above any cache: every copy goes to DRAM


def _cpu_hog() -> None:
    x = 0
    while True:  # pure interpreter work: no memory traffic, no syscalls, never sleeps
        x = (x * 1103515245 + 12345) & 0x7FFFFFFF


def _memory_hog() -> None:
    import numpy as np

    src = np.ones(MEMORY_HOG_BYTES // 8)
    dst = np.empty_like(src)
    while True:
        np.copyto(dst, src)
        np.copyto(src, dst)


def start_load(cpu_hogs: int | None = None, memory_hogs: int = 1) -> list[subprocess.Popen]:
    """Start the hogs (default: one CPU hog per core) as processes of their own at the default
    priority, whatever this process's is; returns them."""
    kinds = ["cpu"] * (cpu_hogs if cpu_hogs is not None else os.cpu_count() or 1) + ["memory"] * memory_hogs
    return [subprocess.Popen([sys.executable, os.path.abspath(__file__), "--hog", kind],
                             preexec_fn=lambda: os.setpriority(os.PRIO_PROCESS, 0, 0)) for kind in kinds]


def stop_load(procs: list[subprocess.Popen]) -> None:
    for proc in procs:
        if proc.poll() is None:
            proc.terminate()
    for proc in procs:
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@contextmanager
def machine_load(cpu_hogs: int | None = None, memory_hogs: int = 1) -> Iterator[list[subprocess.Popen]]:
    procs = start_load(cpu_hogs, memory_hogs)
    try:
        yield procs
    finally:
        stop_load(procs)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=None, help="stop after this long (default: until ctrl-C)")
    parser.add_argument("--cpu-hogs", type=int, default=None, help="CPU hogs (default: one per core)")
    parser.add_argument("--memory-hogs", type=int, default=1, help="memory-bandwidth hogs (default 1)")
    parser.add_argument("--hog", choices=["cpu", "memory"], help=argparse.SUPPRESS)  # one hog, in this process
    args = parser.parse_args(argv)
    if args.hog:
        signal.signal(signal.SIGTERM, lambda *_: os._exit(0))
        (_cpu_hog if args.hog == "cpu" else _memory_hog)()
    cpu = args.cpu_hogs if args.cpu_hogs is not None else os.cpu_count() or 1
    procs = start_load(cpu, args.memory_hogs)
    print(f"load: {cpu} CPU hog(s), {args.memory_hogs} memory hog(s) of {MEMORY_HOG_BYTES >> 20} MiB; "
          f"pids {' '.join(str(p.pid) for p in procs)}", flush=True)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    try:
        end = None if args.seconds is None else time.monotonic() + args.seconds
        while end is None or time.monotonic() < end:
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        stop_load(procs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
