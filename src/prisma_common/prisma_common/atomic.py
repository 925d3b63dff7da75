"""Outputs written whole or not at all: files and directories staged beside their target, renamed
into place when complete.

    with atomic_output("plots/pad.png") as staged:   # staged = plots/pad.png.partial-<pid>/pad.png
        fig.savefig(staged)
    # plots/pad.png now exists, complete; after an exception or ctrl-C it does not (and an older
    # plots/pad.png is untouched)

The staged path has the target's own name inside a directory `<target>.partial-<pid>` next to the
target (same file system, so the final rename is atomic), so tools that derive something from the
name still see the real one: matplotlib's format from the extension, rosbags' storage file name
from the bag directory's name, scipy's `.mat` suffix. Every temporary thing lives in that one
directory: an error or KeyboardInterrupt removes it, and only a killed process leaves it behind,
named so that it never looks like a finished output, and a rerun (another pid) does not trip over it.
An output that cannot be created there or renamed into place raises `OutputError` (an OSError)
naming the path and the reason; the console scripts' `command` wrapper prints it as one line.

Imports only the standard library: every console script uses this, several before argparse runs.
"""
from __future__ import annotations

import os
import shutil
from pathlib import Path
from types import TracebackType

PARTIAL = ".partial-"


class OutputError(OSError):
    """An output that could not be created or put in place; the message names the path and the reason."""


def _output_error(exc: OSError, path: Path) -> OutputError:
    failed = exc.filename if exc.filename is not None else path
    return OutputError(f"cannot create {failed} ({exc.strerror or exc}); choose another location")


def staging_dir(path: str | Path, pid: int | None = None) -> Path:
    """`<path>.partial-<pid>`: where atomic_output stages `path`."""
    path = _absolute(path)
    return path.with_name(f"{path.name}{PARTIAL}{os.getpid() if pid is None else pid}")


def _absolute(path: str | Path) -> Path:
    # abspath also normalises 'out/.' and 'out/' to 'out', whose name is what gets staged
    return Path(os.path.abspath(os.path.expanduser(str(path))))


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    elif path.exists() or path.is_symlink():
        path.unlink()


class atomic_output:  # noqa: N801 - used like a function: `with atomic_output(path) as staged`
    """Stage a file or directory output and rename it onto `path` when the block ends normally.

    The block writes the output at the yielded path (a file, or a directory it creates there;
    the parent exists). On normal exit the output replaces `path`: an existing file or symlink is
    replaced atomically; an existing directory is swapped out (moved into the staging directory,
    then deleted), so callers must have checked that what is there may go. With `replace=False`
    an existing `path` raises FileExistsError instead, before and after the block. On any
    exception, KeyboardInterrupt included, the staged output is deleted and the exception
    propagates; `path` is left as it was.

    Usable without `with` too: `commit()` and `abort()` (BagWriter keeps one open across calls).
    """

    def __init__(self, path: str | Path, replace: bool = True) -> None:
        self.target = _absolute(path)
        self.replace = replace
        self.stage = staging_dir(self.target)
        self.path = self.stage / self.target.name  # where the caller writes
        self._open = False

    def _check_target(self) -> None:
        if not self.replace and (self.target.exists() or self.target.is_symlink()):
            raise FileExistsError(f"{self.target} already exists; not replacing it")

    def open(self) -> Path:
        self._check_target()
        try:
            self.target.parent.mkdir(parents=True, exist_ok=True)
            if self.stage.exists() or self.stage.is_symlink():
                # only this process uses this pid's name: a leftover of an earlier process that had it
                _remove(self.stage)
            self.stage.mkdir()
        except OSError as exc:
            raise _output_error(exc, self.stage) from exc
        self._open = True
        return self.path

    def commit(self) -> Path:
        """Move the finished output onto the target; returns the target."""
        if not self._open:
            raise RuntimeError(f"{self.target}: output not open")
        try:
            if not (self.path.exists() or self.path.is_symlink()):
                raise FileNotFoundError(f"nothing was written to {self.path}")
            self._check_target()
            staged_dir = self.path.is_dir() and not self.path.is_symlink()
            target_dir = self.target.is_dir() and not self.target.is_symlink()
            if target_dir and not staged_dir:
                raise IsADirectoryError(f"{self.target} is a directory; not replacing it with a file")
            if staged_dir and not target_dir and (self.target.exists() or self.target.is_symlink()):
                raise NotADirectoryError(f"{self.target} is a file; not replacing it with a directory")
            try:
                self._swap(target_dir)
            except OSError as exc:
                raise _output_error(exc, self.target) from exc
        except BaseException:
            self.abort()
            raise
        self._open = False
        shutil.rmtree(self.stage, ignore_errors=True)
        return self.target

    def _swap(self, target_dir: bool) -> None:
        if not target_dir:
            os.replace(self.path, self.target)  # atomic, also over an existing file
            return
        # A directory cannot be renamed over a non-empty one: move the old one aside into the
        # staging directory (deleted with it), then the new one into place; put the old one back
        # if that fails.
        aside = self.stage / f"{self.target.name}.replaced"
        moved = False
        try:
            os.rename(self.target, aside)
            moved = True
            os.rename(self.path, self.target)
        except BaseException:
            if moved and not self.target.exists():
                os.rename(aside, self.target)
            raise

    def abort(self) -> None:
        """Delete everything staged; the target stays as it was."""
        self._open = False
        _remove(self.stage)

    def __enter__(self) -> Path:
        return self.open()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.abort()
