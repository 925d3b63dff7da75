"""Argument checks shared by every console script, and the wrapper that turns a user's mistake into
one line and exit status 2.

A mistake in a command line or an input file must fail before any heavy work, with one line that
names the value and says what to do, never a traceback:

    parser = ArgumentParser(prog="prisma-tactile-calset", ...)
    parser.add_argument("--samples", type=positive_int, default=140_000)
    parser.add_argument("--out", type=output_file(".npz"), required=True)

    @command("prisma-tactile-calset")
    def calset_main(argv=None) -> int: ...

`type=` validators raise argparse.ArgumentTypeError, which the parser prints as
`prog: error: argument --samples: ...` (exit 2). Checks that need several arguments raise
UserError; `command` prints it the same way and returns 2, prints `prog: interrupted` and returns
130 on ctrl-C, and lets every other exception through with its traceback (a bug, not a mistake).

An output that cannot be created where it is named (a directory that cannot be made there, a name
too long for the file system, a read-only mount) is found before any work as well: the output
checks make and remove the directories and the staging directory `atomic_output` would write it
in. One that fails later all the same (the disk filled up, the directory went away) comes out of
`atomic_output` as `OutputError`, which `command` prints as one line too.

Imports only the standard library (and of this package only `atomic`, itself standard library
only): `--help` of every tool must stay fast, so torch, matplotlib, scipy and rosbags are imported
inside the commands.
"""
from __future__ import annotations

import argparse
import functools
import importlib
import math
import os
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from .atomic import OutputError, staging_dir

# matplotlib's savefig formats that need nothing beyond matplotlib and Pillow (a matplotlib
# dependency); the extension picks the format.
IMAGE_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".tif", ".tiff", ".eps", ".ps")
BUNDLE_FILES = ("model.pt", "metadata.json")


class UserError(Exception):
    """A mistake in the command line or its input files; the message names the value and what to do."""


class ArgumentParser(argparse.ArgumentParser):
    """argparse with a one-line error message (exit 2); the usage is one `--help` away."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


# --------------------------------------------------------------------------------------- numbers
def _number(text: str, kind: type, what: str):
    try:
        value = kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None
    if kind is float and not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not {what}")
    return value


def _bounded(text: str, kind: type, what: str, accept: Callable[[float], bool], must: str) -> Any:
    value = _number(text, kind, what)
    if not accept(value):
        raise argparse.ArgumentTypeError(f"must be {must}, got {text!r}")
    return value


def positive_int(text: str) -> int:
    return _bounded(text, int, "a whole number; give one >= 1", lambda v: v >= 1, "a whole number >= 1")


def non_negative_int(text: str) -> int:
    return _bounded(text, int, "a whole number; give one >= 0", lambda v: v >= 0, "a whole number >= 0")


def positive_float(text: str) -> float:
    return _bounded(text, float, "a number; give one > 0", lambda v: v > 0, "> 0")


def non_negative_float(text: str) -> float:
    return _bounded(text, float, "a number; give one >= 0", lambda v: v >= 0, ">= 0")


def fraction(text: str) -> float:
    """A number strictly between 0 and 1."""
    return _bounded(text, float, "a number; give one between 0 and 1, e.g. 0.2", lambda v: 0 < v < 1,
                    "between 0 and 1 (exclusive), e.g. 0.2")


def unit_interval(text: str) -> float:
    """A number in [0, 1)."""
    value = _number(text, float, "a number; give one in [0, 1), e.g. 0.999")
    if not 0 <= value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 0 and < 1, e.g. 0.999, got {text!r}")
    return value


def ros_namespace(text: str) -> str:
    """A hand's ROS namespace (`--namespace left`, `/left/`), without its leading and trailing '/';
    '' for none."""
    ns = text.strip("/")
    if ns and not all(part.replace("_", "a").isalnum() and not part[0].isdigit() for part in ns.split("/")):
        raise argparse.ArgumentTypeError(f"{text!r} is not a ROS namespace (letters, digits, _ and /; "
                                         "no part starting with a digit), e.g. left")
    return ns


# ----------------------------------------------------------------------------------------- paths
def _looked_at(check: Callable[[str], Path]) -> Callable[[str], Path]:
    """A path check that says, as its own error, why a path cannot even be looked at (a name too
    long for the file system, a loop of symlinks): stat raises OSError for those."""

    @functools.wraps(check)
    def run(text: str) -> Path:
        try:
            return check(text)
        except OSError as exc:
            raise argparse.ArgumentTypeError(f"{text}: {exc.strerror or exc}; choose another path") from None

    return run


def _path(text: str) -> Path:
    if not text:
        raise argparse.ArgumentTypeError("an empty path; give a file or directory name")
    return Path(text).expanduser()


def _existing(text: str, what: str) -> Path:
    """The path `text` names, which must exist (`what` it should be, for the error)."""
    path = _path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f"{text}: no such {what}; check the path")
    return path


@_looked_at
def existing_file(text: str) -> Path:
    path = _existing(text, "file")
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a directory; give a file")
    if not os.access(path, os.R_OK):
        raise argparse.ArgumentTypeError(f"{text}: not readable (permission denied)")
    return path


@_looked_at
def existing_dir(text: str) -> Path:
    path = _existing(text, "directory")
    if not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a file; give a directory")
    return path


@_looked_at
def existing_path(text: str) -> Path:
    return _existing(text, "file or directory")


def check_bundle_dir(path: Path) -> None:
    """UserError unless `path` is a model bundle directory (model.pt + metadata.json), worded as
    the bundle loaders word it. A relative path that is not in the working directory passes: the
    loaders also look in the installed share directories, and name the path if it is in neither."""
    path = Path(path).expanduser()
    if not path.exists() and not path.is_absolute():
        return
    if not path.exists():
        raise UserError(f"model bundle {path}: directory does not exist")
    if not path.is_dir():
        raise UserError(f"model bundle {path}: is not a directory")
    for name in BUNDLE_FILES:
        if not (path / name).is_file():
            raise UserError(f"model bundle {path}: {name} is missing (a bundle directory holds "
                            f"{' and '.join(BUNDLE_FILES)})")


def _check_writable_parent(path: Path, text: str) -> None:
    """The nearest existing ancestor must be a writable directory (missing ones are created), and
    `path` must be creatable there (`_check_creatable`)."""
    parent = path.absolute().parent
    while not parent.exists() and not parent.is_symlink():
        parent = parent.parent
    if not parent.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: {parent} is a file, not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"{text}: cannot write in {parent} (permission denied); "
                                         f"choose another location")
    _check_creatable(path, text)


def _check_creatable(path: Path, text: str, inside: bool = False) -> None:
    """Make what writing `path` through `atomic_output` makes, then remove it again: the missing
    directories above it, its staging directory and an entry of its name in there (with `inside`,
    a staging directory inside `path`, a directory the tool writes its files into). os.access
    cannot tell that /proc takes no new directory, that a name is too long for the file system or
    that a read-only mount refuses even root; trying can. ArgumentTypeError naming the path that
    could not be made and the reason; nothing is left behind either way."""
    target = path.absolute()
    stage = staging_dir(target / ".probe" if inside else target)
    missing = []
    directory = stage.parent
    while not directory.exists() and not directory.is_symlink():
        missing.append(directory)
        directory = directory.parent
    made: list[Path] = []
    try:
        for directory in reversed(missing):
            directory.mkdir()
            made.append(directory)
        if stage.exists() or stage.is_symlink():
            return  # a killed run's leftover under this pid: atomic_output clears and reuses it
        stage.mkdir()
        made.append(stage)
        entry = stage / target.name
        entry.mkdir()
        made.append(entry)
    except OSError as exc:
        failed = exc.filename if exc.filename is not None else stage
        raise argparse.ArgumentTypeError(f"{text}: cannot create {failed} ({exc.strerror or exc}); "
                                         f"choose another location") from None
    finally:
        for directory in reversed(made):
            try:
                directory.rmdir()
            except OSError:
                pass


def output_file(*suffixes: str) -> Callable[[str], Path]:
    """A file to write (replaced if it exists), with one of `suffixes` when any are given."""
    allowed = tuple(s.lower() for s in suffixes)

    @_looked_at
    def check(text: str) -> Path:
        path = _path(text)
        if path.is_dir():
            raise argparse.ArgumentTypeError(f"{text} is a directory; give a file name")
        if allowed and path.suffix.lower() not in allowed:
            got = f"extension {path.suffix!r}" if path.suffix else "no extension"
            raise argparse.ArgumentTypeError(f"{text} has {got}; use a file name ending in "
                                             f"{', '.join(allowed)}")
        _check_writable_parent(path, text)
        return path

    check.__name__ = "output_file"
    return check


image_file = output_file(*IMAGE_SUFFIXES)


@_looked_at
def output_dir(text: str) -> Path:
    """A directory to write into (created if missing)."""
    path = _path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a file; give a directory")
    if path.exists():
        if not os.access(path, os.W_OK | os.X_OK):
            raise argparse.ArgumentTypeError(f"{text}: cannot write in it (permission denied)")
        _check_creatable(path, text, inside=True)
    else:
        _check_writable_parent(path, text)
    return path


@_looked_at
def new_path(text: str) -> Path:
    """An output that must not exist yet (the tool refuses to replace it)."""
    path = _path(text)
    if path.exists() or path.is_symlink():
        raise argparse.ArgumentTypeError(f"{text} already exists; give a new name or remove it first")
    _check_writable_parent(path, text)
    return path


def check_replaceable_dir(path: Path, allowed: Iterable[str], what: str, option: str) -> None:
    """`path` may be written as a whole (replacing what is there): it is missing, empty, or a
    directory holding only `allowed` entries (an earlier output of the same kind). UserError otherwise."""
    try:
        _check_replaceable_dir(path, set(allowed), what, option)
    except OSError as exc:  # the path cannot even be looked at (a name too long, a loop of symlinks)
        raise UserError(f"{option} {path}: {exc.strerror or exc}; choose another path") from None


def _check_replaceable_dir(path: Path, allowed: set[str], what: str, option: str) -> None:
    if not path.exists() and not path.is_symlink():
        try:
            _check_writable_parent(path, f"{option} {path}")
        except argparse.ArgumentTypeError as exc:
            raise UserError(str(exc)) from None
        return
    if path.is_symlink() or not path.is_dir():
        raise UserError(f"{option} {path} is a file, not {what}; give a new directory name")
    foreign = sorted(p.name for p in path.iterdir() if p.name not in allowed)
    if foreign:
        shown = ", ".join(foreign[:3]) + (", ..." if len(foreign) > 3 else "")
        raise UserError(f"{option} {path} holds files that are not {what} ({shown}); not replacing it: "
                        f"give a new or empty directory")
    if not os.access(path.absolute().parent, os.W_OK | os.X_OK):
        raise UserError(f"{option} {path}: cannot replace it, {path.absolute().parent} is not writable")
    try:
        _check_creatable(path, f"{option} {path}")
    except argparse.ArgumentTypeError as exc:
        raise UserError(str(exc)) from None


def check_bundle_out(path: Path, option: str = "--out") -> None:
    """A model bundle is written to `path`, replacing an earlier bundle there but nothing else."""
    check_replaceable_dir(path, BUNDLE_FILES, "a model bundle", option)


# ------------------------------------------------------------------------------------ the wrapper
def _known(names: Iterable[str]) -> tuple[type[BaseException], ...]:
    """Exception classes named 'module:Class', counted only when their module is loaded (an
    exception of a module that was never imported cannot have been raised; importing it here
    would cost what the lazy imports saved)."""
    found = []
    for name in names:
        module, _, cls = name.partition(":")
        if module in sys.modules:
            found.append(getattr(importlib.import_module(module), cls))
    return tuple(found)


def command(prog: str, *user_errors: str) -> Callable[[Callable[..., int]], Callable[..., int]]:
    """Decorate a console script's main(argv) -> exit status.

    UserError, atomic_output's OutputError (an output that could not be created) and the exception
    types named in `user_errors` ('module:Class', e.g. a bundle loader's BundleError), print
    `prog: error: <message>` and return 2; KeyboardInterrupt prints
    `prog: interrupted` and returns 130. Anything else keeps its traceback."""

    def wrap(main: Callable[..., int]) -> Callable[..., int]:
        @functools.wraps(main)
        def run(*args, **kwargs) -> int:
            try:
                return main(*args, **kwargs)
            except KeyboardInterrupt:
                print(f"{prog}: interrupted", file=sys.stderr)
                return 130
            except Exception as exc:
                if isinstance(exc, (UserError, OutputError)) or isinstance(exc, _known(user_errors)):
                    print(f"{prog}: error: {exc}", file=sys.stderr)
                    return 2
                raise

        return run

    return wrap
