"""A launch test's emulated hand (`hardware:=emulated`, prisma-hand-emulator's devices in a folder):
homed at start, read from the motor driver's /diagnostics, and faults sent to its emulator as
`prisma-hand-fault` sends them."""
from __future__ import annotations

import subprocess
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .node_process import console_script
from .ros_harness import stamp_ns

if TYPE_CHECKING:
    from .ros_harness import RosHarness


def diagnostic_values(diagnostics: Sequence[Any], name_end: str, since_ns: int = 0) -> dict[str, str] | None:
    """The key/values of the newest /diagnostics status named `...<name_end>` in a `collect` list,
    None if there is none stamped at or after `since_ns`."""
    for msg in reversed(diagnostics):
        if stamp_ns(msg) < since_ns:
            return None
        for status in msg.status:
            if status.name.endswith(name_end):
                return {v.key: v.value for v in status.values}
    return None


def wait_until_homed(ros: RosHarness, diagnostics: Sequence[Any], motors: Sequence[str],
                     timeout_sec: float = 60.0) -> None:
    """Spin until the motor driver's newest /diagnostics say every one of `motors` is homed (a launch
    with home:=true homes at start; goals before that are refused not_homed)."""
    def homed() -> bool:
        return all((diagnostic_values(diagnostics, f"motor_driver: {m}") or {}).get("homed") == "True" for m in motors)

    if not ros.spin_until(homed, timeout_sec):
        raise AssertionError(f"not homed within {timeout_sec} s: "
                             f"{[diagnostic_values(diagnostics, f'motor_driver: {m}') for m in motors]}")


def _fault_cli_priority() -> None:
    # the fault CLI acts when the test says, not when a busy machine gets round to starting it (the
    # ladder in prisma_common/scheduling.py): a default-priority start took 4-15 s on a loaded 2-core
    # machine, longer than the slow goal a fault is meant to interrupt
    from prisma_common.scheduling import try_rt_priority

    from .priorities import FAULT_CLI_RT_PRIORITY

    try_rt_priority(FAULT_CLI_RT_PRIORITY)


def run_hand_fault(emulator_dir: str | Path, *args: str) -> subprocess.CompletedProcess:
    """Run `prisma-hand-fault --dir <emulator_dir> <args>` (the emulated hand's fault CLI, its
    `console_script`) at FAULT_CLI_RT_PRIORITY."""
    command = [console_script("prisma-hand-fault"), "--dir", str(emulator_dir), *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=30, preexec_fn=_fault_cli_priority)


def hand_fault(emulator_dir: str | Path, *args: str) -> str:
    """What `prisma-hand-fault --dir <emulator_dir> <args>` prints, sent from this process (the CLI's
    parser and request, prisma_hand_emulator.emulator_cli.fault_request): a CLI process started per
    fault took seconds on a 2-core machine whose control path runs at real-time priority, and a push
    meant for 0.5 s into a 3 s hold came after the hold ended. AssertionError naming the command
    when the emulator refuses it or cannot be reached."""
    from prisma_common.cli_args import UserError
    from prisma_hand_emulator.emulator_cli import fault_request

    try:
        return fault_request(["--dir", str(emulator_dir), *args])
    except UserError as exc:
        raise AssertionError(f"prisma-hand-fault {' '.join(args)}: {exc}") from None
