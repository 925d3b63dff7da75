"""Commands a test starts in their own process group, as an operator starts them in a terminal: a node
(`ros2 run`, `python3 -m`), a launch (`ros2 launch`), a long-running ros2 verb (`ros2 bag record`);
their output collected, stopped as Ctrl-C stops them, their exit status and output returned."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

if TYPE_CHECKING:
    from .ros_harness import RosHarness


@dataclass
class ProcessResult:
    returncode: int
    output: str  # stdout and stderr together, in order


class NodeProcess:
    """A command (`ros2 run pkg exe ...`, `python3 -m module`) in its own session, its stdout and
    stderr collected: `wait_for_output` a line it prints, `interrupt` it as Ctrl-C in its terminal
    does (SIGINT to the whole process group: `ros2 run` and the node under it), `wait` for its exit.
    As a context manager it kills whatever still runs at the end. The environment is inherited
    (the test process's ROS_DOMAIN_ID included), with unbuffered Python and uncoloured ROS logs.
    Each one started is kept in `started` (its output for the file a failing test names, launch_case)."""

    started: ClassVar[list[NodeProcess]] = []

    def __init__(self, args: Sequence[str], env: dict[str, str] | None = None, cwd: str | Path | None = None,
                 preexec: Callable[[], None] | None = None) -> None:
        full_env = {**os.environ, "PYTHONUNBUFFERED": "1", "RCUTILS_COLORIZED_OUTPUT": "0", **(env or {})}
        self.args = list(args)
        self.proc = subprocess.Popen(self.args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     env=full_env, cwd=cwd, start_new_session=True, preexec_fn=preexec)
        self._lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        NodeProcess.started.append(self)

    def _read(self) -> None:
        for line in self.proc.stdout:
            self._lines.append(line)

    @property
    def output(self) -> str:
        return "".join(self._lines)

    def wait_for_output(self, text: str, timeout_sec: float = 60.0) -> bool:
        """True once `text` appears in the output; False at the timeout or when the process exits first."""
        deadline = time.monotonic() + timeout_sec
        while time.monotonic() < deadline:
            if text in self.output:
                return True
            if self.proc.poll() is not None:
                self._reader.join(timeout=5.0)
                return text in self.output
            time.sleep(0.05)
        return False

    def wait_until_spinning(self, ros: RosHarness, node_name: str, timeout_sec: float = 60.0) -> None:
        """Return once `node_name` answers its ~/list_parameters service, i.e. its executor spins.
        (A SIGINT before that lands in rclpy's executor set-up inside rclpy.spin, not in the node.)"""
        from rcl_interfaces.srv import ListParameters

        ros.call(ListParameters, f"{node_name}/list_parameters", ListParameters.Request(), timeout_sec)

    def wait(self, timeout_sec: float = 60.0) -> ProcessResult:
        """Wait for the process to exit by itself; TimeoutError (with its output) if it does not."""
        try:
            self.proc.wait(timeout=timeout_sec)
        except subprocess.TimeoutExpired:
            self.kill()
            raise TimeoutError(f"{' '.join(self.args)} still ran after {timeout_sec} s; "
                               f"output:\n{self.output}") from None
        self._reader.join(timeout=5.0)
        return ProcessResult(self.proc.returncode, self.output)

    def interrupt(self, timeout_sec: float = 30.0, sig: int = signal.SIGINT) -> ProcessResult:
        """Ctrl-C (SIGINT, or `sig`: SIGTERM as `ros2 launch` escalates) to the process group, then
        wait for the exit."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, sig)
        return self.wait(timeout_sec)

    def kill(self) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
        self._reader.join(timeout=5.0)

    def __enter__(self) -> NodeProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.kill()


def run_process(args: Sequence[str], timeout_sec: float = 60.0, env: dict[str, str] | None = None) -> ProcessResult:
    """Run a command that should exit by itself (a node refusing its parameters) and collect its output."""
    with NodeProcess(args, env=env) as proc:
        return proc.wait(timeout_sec)


def start_and_interrupt(args: Sequence[str], ready: str, ros: RosHarness | None = None, node_name: str | None = None,
                        sig: int = signal.SIGINT, timeout_sec: float = 60.0) -> ProcessResult:
    """Start a node process, wait until it printed `ready` (and, given `ros` and `node_name`, until
    it spins), send it `sig` as Ctrl-C would, and return its exit status and output."""
    with NodeProcess(args) as proc:
        if not proc.wait_for_output(ready, timeout_sec):
            raise AssertionError(f"{' '.join(args)} never printed {ready!r}; output:\n{proc.output}")
        if ros is not None and node_name is not None:
            proc.wait_until_spinning(ros, node_name, timeout_sec)
        return proc.interrupt(timeout_sec, sig)


_EXTERNAL_SHUTDOWN = """
import importlib, sys, threading, time
import rclpy
from prisma_node_wiring.executor import process_executor
main = importlib.import_module(sys.argv[1]).main
def shut_down_when_spinning():
    while not rclpy.ok():
        time.sleep(0.05)
    executor = process_executor()  # the one run_node spins
    while not executor.get_nodes():
        time.sleep(0.05)
    time.sleep(0.5)
    rclpy.get_default_context().handle.shutdown()  # rcl only, as rclpy's signal handler does
    executor.wake()
threading.Thread(target=shut_down_when_spinning, daemon=True).start()
main([sys.argv[0], *sys.argv[2:]])
"""


def external_shutdown_command(module: str, *args: str) -> list[str]:
    """A command running `module`'s main(args) whose rclpy context is shut down from outside its
    executor once the node spins (as rclpy's SIGINT/SIGTERM handler and `ros2 launch` do): rclpy.spin
    then raises ExternalShutdownException, which main() must take as a normal stop (exit 0)."""
    return [sys.executable, "-c", _EXTERNAL_SHUTDOWN, module, *args]


# ---- launch files and long-running ros2 verbs in their own process group ----------------------------
def ros2_launch(package: str, launch_file: str, *arguments: str, env: dict[str, str] | None = None,
                cwd: str | Path | None = None, preexec: Callable[[], None] | None = None) -> NodeProcess:
    """`ros2 launch <package> <launch_file> name:=value ...` in its own process group, as an operator
    starts it in a terminal; stop it with `stop_process` (the environment, ROS_DOMAIN_ID included,
    is the test process's; `cwd` and `preexec` as NodeProcess takes them)."""
    return NodeProcess(["ros2", "launch", package, launch_file, *arguments], env=env, cwd=cwd, preexec=preexec)


def stop_process(proc: NodeProcess, timeout_sec: float = 30.0) -> ProcessResult:
    """Stop a launch or a `ros2 bag record` as Ctrl-C in its terminal does (SIGINT to its process
    group), then SIGTERM (what `ros2 launch` escalates to) and SIGKILL if it is still running after
    `timeout_sec` each; returns the exit status and output. A process that already ended is only
    waited for."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        if proc.proc.poll() is not None:
            break
        os.killpg(proc.proc.pid, sig)
        try:
            proc.proc.wait(timeout=timeout_sec)
        except subprocess.TimeoutExpired:
            continue
    proc.kill()  # SIGKILL only if both signals were ignored; joins the output reader
    return ProcessResult(proc.proc.returncode, proc.output)


# Python 3.11's asyncio child watcher reports 255 for a child that another waitpid reaped first. Ctrl-C
# reaches every node of a launch twice, from the terminal's SIGINT to the process group and from
# launch's own SIGINT; the second goes through Popen.send_signal, whose poll() reaps a node that the first
# had already ended, and the watcher's waitpid then finds no child. The node's own exit status is lost.
_EXIT_LOST = re.compile(r"Unknown child process pid (\d+), will report returncode 255")
_DIED = re.compile(r"process has died \[pid (\d+), exit code (-?\d+)")


def process_deaths(output: str) -> list[str]:
    """The `process has died` lines of a launch's output, less those whose exit code 255 asyncio's
    child watcher made up for a pid it found already reaped (its warning names the pid)."""
    lost = set(_EXIT_LOST.findall(output))
    return [line for line in output.splitlines()
            if (died := _DIED.search(line)) and not (died[2] == "255" and died[1] in lost)]


def console_script(name: str) -> str:
    """This interpreter's own console script `name` where it has one, else `name` from PATH: a version
    manager's shim on PATH forks a chain of shells first, seconds on a loaded machine."""
    script = Path(sys.executable).with_name(name)
    return str(script) if script.exists() else name

