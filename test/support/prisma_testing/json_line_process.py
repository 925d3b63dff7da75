"""A helper process driven over its stdin/stdout one JSON line at a time (host_probe, collector): the
test's end starts it, sends a request and reads the one line that answers it."""
from __future__ import annotations

import json
import os
import select
import subprocess
import threading
from collections.abc import Sequence
from typing import Any


class JsonLineProcess:
    """`argv` in a session of its own; `call` sends {"op", **fields} and returns the answer's object
    (RuntimeError naming `name` with the process's stderr when it exited, did not answer or answered
    {"error"}); `close` ends its input and waits for it."""

    def __init__(self, argv: Sequence[str], name: str, env: dict[str, str] | None = None) -> None:
        self.name = name
        self.proc = subprocess.Popen(list(argv), stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)
        self._stderr: list[str] = []
        self._reader = threading.Thread(target=lambda: self._stderr.extend(self.proc.stderr), daemon=True)
        self._reader.start()

    def stderr_tail(self, chars: int = 2000) -> str:
        return "".join(self._stderr)[-chars:]

    def call(self, op: str, timeout_s: float = 120.0, **fields: Any) -> dict:
        if self.proc.poll() is not None:
            raise RuntimeError(f"the {self.name} exited ({self.proc.returncode}): {self.stderr_tail()}")
        self.proc.stdin.write(json.dumps({"op": op, **fields}) + "\n")
        self.proc.stdin.flush()
        ready, _, _ = select.select([self.proc.stdout], [], [], timeout_s)
        line = self.proc.stdout.readline() if ready else ""
        if not line:
            raise RuntimeError(f"no answer from the {self.name} to {op} within {timeout_s} s: {self.stderr_tail()}")
        answer = json.loads(line)
        if "error" in answer:
            raise RuntimeError(f"{self.name} {op}: {answer['error']}")
        return answer

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.stdin.close()  # the process ends at the end of its input
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, 9)
                self.proc.wait()
        self._reader.join(timeout=5)
