"""Core dumps of the processes a test starts, and their backtraces when one crashed.

A third-party GUI (RViz) that dies of a signal in a launch test leaves only `exit code -11` in the
launch's output; its own stderr says nothing. With `allow_core_dumps` as the process's preexec and a
folder of the test's own as its working directory, a crash leaves a core there wherever the kernel's
core_pattern writes cores into the crashing process's directory (`core`, `core.<pid>`); where it
pipes them to a handler (systemd-coredump, apport) nothing lands and `backtraces` says so.
"""
from __future__ import annotations

import resource
import shutil
import subprocess
from pathlib import Path

GDB_TIMEOUT_S = 120.0


def allow_core_dumps() -> None:
    """As a Popen preexec_fn: this process and its children may dump a core up to the hard limit."""
    _, hard = resource.getrlimit(resource.RLIMIT_CORE)
    resource.setrlimit(resource.RLIMIT_CORE, (hard, hard))


def core_pattern() -> str:
    try:
        return Path("/proc/sys/kernel/core_pattern").read_text().strip()
    except OSError as exc:
        return f"unreadable ({exc.strerror})"


def backtraces(folder: str | Path, executable: str, max_chars: int = 20000) -> str:
    """Every thread's backtrace of each core file of `executable` in `folder` (gdb, batch mode), or
    why there is none."""
    cores = sorted(p for p in Path(folder).iterdir() if p.is_file() and p.name.split(".")[0] == "core")
    if not cores:
        _, hard = resource.getrlimit(resource.RLIMIT_CORE)
        return (f"no core in {folder} (core_pattern {core_pattern()!r}, core size hard limit "
                f"{'unlimited' if hard == resource.RLIM_INFINITY else hard})")
    gdb = shutil.which("gdb")
    if gdb is None:
        return f"cores {[c.name for c in cores]} in {folder}, but no gdb to read them: apt install gdb"
    out = []
    for core in cores:
        done = subprocess.run([gdb, "--batch", "-ex", "thread apply all bt 30", executable, str(core)],
                              capture_output=True, text=True, timeout=GDB_TIMEOUT_S)
        lines = [line for line in (done.stdout + done.stderr).splitlines() if not line.startswith("[New LWP")]
        out.append(f"===== {core.name} =====\n" + "\n".join(lines))
    text = "\n".join(out)
    return text if len(text) <= max_chars else text[:max_chars] + f"\n... ({len(text) - max_chars} more characters)"
