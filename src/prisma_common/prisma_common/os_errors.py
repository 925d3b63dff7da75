"""OS errors as an operator reads them: the errno and its meaning, whatever library wrapped it."""
from __future__ import annotations

import os


def describe_os_error(exc: BaseException) -> str:
    """`[Errno 2] No such file or directory` for anything carrying an errno (pyserial wraps the
    OS error of a failed open in a SerialException with the same errno; termios.error carries it
    as its first argument), else the text itself."""
    number = getattr(exc, "errno", None)
    if number is None and len(exc.args) == 2 and isinstance(exc.args[0], int):
        number = exc.args[0]
    if isinstance(number, int) and number > 0:
        return f"[Errno {number}] {os.strerror(number)}"
    return str(exc) or type(exc).__name__
