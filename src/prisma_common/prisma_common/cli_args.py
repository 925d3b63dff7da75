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

Imports only the standard library (and no other module of this package): `--help` of every tool
must stay fast, so torch, matplotlib, scipy and rosbags are imported inside the commands.
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


def positive_int(text: str) -> int:
    value = _number(text, int, "a whole number; give one >= 1")
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 1, got {text!r}")
    return value


def non_negative_int(text: str) -> int:
    value = _number(text, int, "a whole number; give one >= 0")
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 0, got {text!r}")
    return value


def positive_float(text: str) -> float:
    value = _number(text, float, "a number; give one > 0")
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
    return value


def non_negative_float(text: str) -> float:
    value = _number(text, float, "a number; give one >= 0")
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text!r}")
    return value


def fraction(text: str) -> float:
    """A number strictly between 0 and 1."""
    value = _number(text, float, "a number; give one between 0 and 1, e.g. 0.2")
    if not 0 < value < 1:
        raise argparse.ArgumentTypeError(f"must be between 0 and 1 (exclusive), e.g. 0.2, got {text!r}")
    return value


def unit_interval(text: str) -> float:
    """A number in [0, 1)."""
    value = _number(text, float, "a number; give one in [0, 1), e.g. 0.999")
    if not 0 <= value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 0 and < 1, e.g. 0.999, got {text!r}")
    return value


# ----------------------------------------------------------------------------------------- paths
def _path(text: str) -> Path:
    if not text:
        raise argparse.ArgumentTypeError("an empty path; give a file or directory name")
    return Path(text).expanduser()


def existing_file(text: str) -> Path:
    path = _path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a directory; give a file")
    if not path.exists():
        raise argparse.ArgumentTypeError(f"{text}: no such file; check the path")
    if not os.access(path, os.R_OK):
        raise argparse.ArgumentTypeError(f"{text}: not readable (permission denied)")
    return path


def existing_dir(text: str) -> Path:
    path = _path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f"{text}: no such directory; check the path")
    if not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a file; give a directory")
    return path


def existing_path(text: str) -> Path:
    path = _path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f"{text}: no such file or directory; check the path")
    return path


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
    """The nearest existing ancestor must be a writable directory (missing ones are created)."""
    parent = path.absolute().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: {parent} is a file, not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"{text}: cannot write in {parent} (permission denied); "
                                         f"choose another location")


def output_file(*suffixes: str) -> Callable[[str], Path]:
    """A file to write (replaced if it exists), with one of `suffixes` when any are given."""
    allowed = tuple(s.lower() for s in suffixes)

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


def output_dir(text: str) -> Path:
    """A directory to write into (created if missing)."""
    path = _path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a file; give a directory")
    if path.exists():
        if not os.access(path, os.W_OK | os.X_OK):
            raise argparse.ArgumentTypeError(f"{text}: cannot write in it (permission denied)")
    else:
        _check_writable_parent(path, text)
    return path


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
    allowed = set(allowed)
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

    UserError, and the exception types named in `user_errors` ('module:Class', e.g. a bundle
    loader's BundleError), print `prog: error: <message>` and return 2; KeyboardInterrupt prints
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
                if isinstance(exc, UserError) or isinstance(exc, _known(user_errors)):
                    print(f"{prog}: error: {exc}", file=sys.stderr)
                    return 2
                raise

        return run

    return wrap
