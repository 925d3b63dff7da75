"""Where each hand node's CPU goes: py-spy of each node in turn on the 100 Hz graph with pinch
grasps running, its samples summed per category and per function."""
from __future__ import annotations

import subprocess
import threading
import time
from pathlib import Path
from typing import Any

from graph_bench.cpu import CpuSampler
from graph_bench.facts import HAND_NODES
from graph_bench.hand import start_hand
from graph_bench.processes import check_alive, stop
from prisma_common.hand import FINGERS

# A sample's category: the first rule, from the innermost frame outwards, that matches a frame
# "function (file)" of py-spy's raw output. Samples of threads waiting (in rcl_wait) are not counted.
CATEGORIES = (
    ("torch", lambda fn, path: path.startswith("torch/")),
    ("sim pad model", lambda fn, path: path.endswith("pad_model.py")),
    ("sim backends, hand/world", lambda fn, path: path.endswith(("hand_world.py", "sim_backend.py"))),
    ("publish (serialise + DDS write)",
     lambda fn, path: fn in ("Publisher.publish", "ServerGoalHandle.publish_feedback")),
    ("message classes (construct/convert)",
     lambda fn, path: any(part in path for part in ("/msg/_", "/action/_", "/srv/_"))),
    ("converters (ros_conversions)", lambda fn, path: path.endswith("ros_conversions.py")),
    ("node callbacks (*_node.py)", lambda fn, path: path.endswith("_node.py")),
    ("project cores", lambda fn, path: path.startswith(("prisma_", "stag_glove/"))),
    ("rclpy actions", lambda fn, path: path.startswith("rclpy/action/")),
    ("rclpy executor + other rclpy", lambda fn, path: path.startswith("rclpy/")),
)


def _frame(text: str) -> tuple[str, str, int]:
    fn, _, rest = text.rpartition(" (")
    path, _, line = rest.rstrip(")").rpartition(":")
    return (fn, path, int(line)) if line.isdigit() else (fn, rest.rstrip(")"), 0)


def _wait_line() -> int:
    """The line of rclpy's executor that blocks in rcl_wait (py-spy counts a thread blocked there as
    active: its samples are set aside as waiting, so only CPU work is attributed)."""
    import inspect

    import rclpy.executors

    # read from the module's source: the method is private to rclpy, its name only py-spy's
    lines = inspect.getsource(rclpy.executors).splitlines()
    method = next(i for i, line in enumerate(lines) if "def _wait_for_ready_callbacks(" in line)
    return 1 + next(i for i in range(method, len(lines)) if "wait_set.wait(" in lines[i])


def _read_stacks(raw: Path) -> tuple[list[tuple[list[tuple[str, str]], int]], int]:
    """(stacks as (frames, count), samples waiting in rcl_wait) of py-spy's raw output."""
    wait_line = _wait_line()
    stacks, waiting = [], 0
    for line in raw.read_text().splitlines():
        stack, _, count = line.rpartition(" ")
        if not stack or not count.isdigit():
            continue
        frames = [_frame(f) for f in stack.split(";")]
        leaf = frames[-1]
        if leaf[0] == "Executor._wait_for_ready_callbacks" and leaf[2] == wait_line:
            waiting += int(count)
            continue
        stacks.append(([(fn, path) for fn, path, _ in frames], int(count)))
    return stacks, waiting


def summarise_profile(raw: Path, cpu_pct: float, top: int = 12) -> dict:
    """Per category and per function (self and inclusive): % of the working samples and the share
    of the process's measured CPU (% of one core) that this makes."""
    stacks, waiting = _read_stacks(raw)
    total = sum(c for _, c in stacks) or 1
    cats: dict[str, int] = {}
    self_t: dict[str, int] = {}
    incl: dict[str, int] = {}
    for frames, count in stacks:
        category = "other (numpy, stdlib, ...)"
        for fn, path in reversed(frames):
            hit = next((name for name, rule in CATEGORIES if rule(fn, path)), None)
            if hit:
                category = hit
                break
        cats[category] = cats.get(category, 0) + count
        leaf = f"{frames[-1][0]} ({frames[-1][1]})"
        self_t[leaf] = self_t.get(leaf, 0) + count
        for key in {f"{fn} ({path})" for fn, path in frames}:
            incl[key] = incl.get(key, 0) + count

    def table(d: dict[str, int], n: int) -> list:
        return [{"what": k, "samples_pct": round(100 * v / total, 1), "core_pct": round(cpu_pct * v / total, 1)}
                for k, v in sorted(d.items(), key=lambda kv: -kv[1])[:n]]

    return {"working_samples": total, "waiting_samples": waiting, "cpu_pct": cpu_pct,
            "categories": table(cats, len(cats)), "self": table(self_t, top), "inclusive": table(incl, top * 2)}


def profile_hand(control: Any, out: Path, seconds: float = 8.0, rate: int = 200, settle_s: float = 3.0) -> dict:
    """py-spy of each hand node in turn (the 100 Hz graph of hand.launch.py, pinch grasps running)."""
    logdir = out / f"profile_{time.strftime('%H%M%S')}"
    logdir.mkdir(parents=True, exist_ok=True)
    procs, pids = start_hand("real", 100.0, logdir, launch=True)
    stop_grasps = threading.Event()
    cycles: list[dict] = []

    def grasping() -> None:
        while not stop_grasps.is_set():
            cycles.append(control.grasp_cycle())

    worker = threading.Thread(target=grasping, daemon=True)
    result: dict = {}
    try:
        control.wait_publishers([f"/prisma/{f}/contact" for f in FINGERS] + ["/prisma/little/wrench"], 90.0, procs)
        time.sleep(settle_s)
        worker.start()
        time.sleep(2.0)
        for node in HAND_NODES:
            raw = logdir / f"{node}.raw.txt"
            sampler = CpuSampler({node: pids[node]})
            subprocess.run(["py-spy", "record", "-p", str(pids[node]), "-d", f"{seconds:g}", "-r", str(rate),
                            "-f", "raw", "-o", str(raw)], check=True, capture_output=True)
            result[node] = summarise_profile(raw, sampler.done()[node])
            check_alive(procs)
    finally:
        stop_grasps.set()
        worker.join(timeout=30.0)
        stop(procs)
    result["grasps"] = [f"{g['reason']}" for g in cycles]
    return result
