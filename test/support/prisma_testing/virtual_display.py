"""A virtual X server of a test's own, for RViz and rqt under Xvfb (no screen on these machines)."""
from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

GUI_HINT = "PRISMA_ROS_GUI=1 source ../shared/ros2/setup.sh"


def require_rviz() -> None:
    """Skip the calling module where Xvfb or rviz2 is missing (fail under PRISMA_ROS_GUI=1)."""
    missing = [tool for tool in ("Xvfb", "rviz2") if shutil.which(tool) is None]
    if not missing:
        return
    if os.environ.get("PRISMA_ROS_GUI") == "1":
        raise RuntimeError(f"PRISMA_ROS_GUI=1 but {' and '.join(missing)} missing: RViz cannot start")
    pytest.skip(f"RViz needs {' and '.join(missing)}: {GUI_HINT}", allow_module_level=True)


def start_display(width: int = 1280, height: int = 800) -> tuple[str, subprocess.Popen]:
    """Start Xvfb on a free display number (it picks one and says which); returns ':N' and the process."""
    with tempfile.TemporaryFile("w+") as number_file:
        xvfb = subprocess.Popen(["Xvfb", "-displayfd", str(number_file.fileno()), "-screen", "0",
                                 f"{width}x{height}x24", "-nolisten", "tcp"],
                                pass_fds=(number_file.fileno(),), stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            number_file.seek(0)
            number = number_file.read().strip()
            if number:
                return f":{number}", xvfb
            if xvfb.poll() is not None:
                break
            time.sleep(0.1)
    xvfb.kill()
    raise RuntimeError("Xvfb did not start")


def stop_display(xvfb: subprocess.Popen) -> None:
    xvfb.terminate()
    try:
        xvfb.wait(timeout=10)
    except subprocess.TimeoutExpired:
        xvfb.kill()
        xvfb.wait()


@contextmanager
def virtual_display() -> Iterator[dict[str, str]]:
    """The environment for a GUI process on a display of its own (Mesa's software renderer)."""
    display, xvfb = start_display()
    try:
        yield {**os.environ, "DISPLAY": display, "LIBGL_ALWAYS_SOFTWARE": "1"}
    finally:
        stop_display(xvfb)
