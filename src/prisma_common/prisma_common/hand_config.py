"""One directory per physical hand: what belongs to that hand and not to the hand model, written by
the services that find it and loaded from it at start.

The shipped config/ describes the PRISMA Hand II model; two built hands differ in where homing put
each motor's zero, in each fingertip's no-load wrench and in which network fits each pad best.
Those facts live in a hand directory, by default `default_hand_config_dir(namespace)`:
`$XDG_CONFIG_HOME/prisma_hand/<namespace>` (~/.config when XDG_CONFIG_HOME is unset), `default`
for a hand without a namespace, `left`/`right` for the hands of a bimanual launch. Anything the
directory does not hold comes from the shipped config/, as before. Nothing is written into the
install space or the source tree.

Layout (one YAML file per kind, so each service rewrites only its own file and a damaged file
costs only its own kind):

    <hand dir>/
      motor_zeros.yaml   homing (motor_driver): motor -> zero ticks (Present Position at 0 rad)
      force_bias.yaml    ~/bias (force_estimator): finger -> no-load wrench offset and its bundle
      bundles.yaml       finger -> model bundle directory (relative = inside the hand directory)
      bundles/<finger>/  bundles copied in by save_bundle (model.pt + metadata.json)

Every file has `written_by`/`written_at` (the last save: program, pid, user@host; UTC ISO 8601)
and one entry per motor or finger with its own `written_at`, `written_by` and `note`: saves merge by
motor or finger, so the entry of the thumb homed last week keeps its date when the fingers are
rehomed today.

    written_by: prisma-motor-driver pid 4242 (alice@hand-pc)
    written_at: '2025-01-31T14:02:11+00:00'
    motor_zeros:
      fingers: {ticks: 2071, written_at: '2025-01-31T14:02:11+00:00', written_by: ..., note: homing}

Bundles are copied in rather than referenced: a bundle is small (~0.5 MB), the bias saved with it
is only valid for that exact network, and a reference into a workspace or install space breaks
when that is rebuilt or moved. A bundle elsewhere can still be named (save_bundle(copy=False)).

A file that cannot be read or holds a bad value raises HandConfigError naming the file, the entry
and the value; writes go through prisma_common.atomic (whole or not at all).
"""
from __future__ import annotations

import getpass
import math
import os
import shutil
import socket
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import yaml

from .atomic import atomic_output
from .hand import FINGERS, MOTOR_NAMES
from .os_errors import describe_os_error

APP_DIR = "prisma_hand"
DEFAULT_HAND = "default"
MOTOR_ZEROS_FILE = "motor_zeros.yaml"
FORCE_BIAS_FILE = "force_bias.yaml"
BUNDLES_FILE = "bundles.yaml"
BUNDLES_DIR = "bundles"
WRENCH_AXES = ("fx", "fy", "fz", "tx", "ty", "tz")  # N, N*m: geometry_msgs/Wrench order
TICKS_LIMIT = 2**31  # Present Position is a signed 4-byte register


class HandConfigError(ValueError):
    """A hand directory file that cannot be read or written, or holds a bad value; the message
    names the file, the entry and the value, and what to do."""


def config_home() -> Path:
    """$XDG_CONFIG_HOME, or ~/.config when it is unset, empty or relative (the XDG spec ignores
    relative values)."""
    xdg = os.environ.get("XDG_CONFIG_HOME", "")
    return Path(xdg) if xdg and os.path.isabs(xdg) else Path.home() / ".config"


def default_hand_config_dir(namespace: str = "") -> Path:
    """~/.config/prisma_hand/<namespace> ('/left' -> left, '' -> default). A nested namespace
    joins its parts with '.', which a ROS name cannot contain, so no two namespaces share a
    directory and none is a subdirectory of another hand's."""
    parts = [p for p in namespace.strip().split("/") if p]
    return config_home() / APP_DIR / (".".join(parts) or DEFAULT_HAND)


def launch_hand_config(given: str, namespace: str, simulated: bool) -> str:
    """The launch argument hand_config:= -> the nodes' `hand_config` parameter. 'auto' (the default)
    is default_hand_config_dir(namespace) on the hardware and none ('') for sim:=true or
    hardware:=emulated: a simulated hand's zeros and bias are not the real hand's, and a run that
    starts from what an earlier one saved is not reproducible (hand_config:=<dir> still gives a
    simulated hand a directory). 'none' or '' = none; a path is used as given, made absolute."""
    given = given.strip()
    if given == "auto":
        return "" if simulated else str(default_hand_config_dir(namespace))
    if given in ("", "none"):
        return ""
    return os.path.abspath(os.path.expanduser(given))


def default_writer() -> str:
    """Who writes: the program, its pid and user@host (what `written_by` records)."""
    program = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else "python"
    try:
        user = getpass.getuser()
    except (KeyError, OSError):  # no passwd entry and no LOGNAME/USER (containers)
        user = str(os.getuid())
    return f"{program} pid {os.getpid()} ({user}@{socket.gethostname()})"


def now_iso() -> str:
    return datetime.now(timezone.utc).replace(microsecond=0).isoformat()


@dataclass(frozen=True)
class FingerBias:
    """A finger's saved no-load wrench: `offset` [fx fy fz tx ty tz] (N, N*m; NaN for axes its
    network lacks), the bundle directory it was taken with, and how many samples it averaged."""

    offset: tuple[float, ...]
    bundle: str
    samples: int
    written_at: str = ""


class HandConfig:
    """The hand directory at `root` (created on the first save). Reads return {} for a file not
    saved yet; every read and save raises HandConfigError on a bad file."""

    def __init__(self, root: Path | str, writer: str | None = None) -> None:
        text = str(root)
        if not text.strip():
            raise HandConfigError("hand config directory is empty; give a directory path")
        self.root = Path(os.path.abspath(os.path.expanduser(text)))
        self.writer = writer or default_writer()

    def __repr__(self) -> str:
        return f"HandConfig({str(self.root)!r})"

    def path(self, name: str) -> Path:
        return self.root / name

    # --- motor zeros -------------------------------------------------------------------------
    def motor_zeros(self) -> dict[str, int]:
        """motor name -> zero ticks (the Present Position that means 0 rad); {} when none saved."""
        return {motor: entry["ticks"] for motor, entry in self._entries(MOTOR_ZEROS_FILE, "motor_zeros").items()}

    def save_motor_zeros(self, zeros: Mapping[str, int], note: str = "") -> Path:
        """Merge `zeros` (motor -> ticks) into motor_zeros.yaml; other motors keep their entries.
        Returns the file's path."""
        path = self.path(MOTOR_ZEROS_FILE)
        checked = {motor: _check_ticks(path, motor, ticks) for motor, ticks in zeros.items()}
        stamp = self._stamp(note)
        return self._merge(MOTOR_ZEROS_FILE, "motor_zeros", {m: {"ticks": t, **stamp} for m, t in checked.items()})

    # --- force bias --------------------------------------------------------------------------
    def force_bias(self) -> dict[str, FingerBias]:
        """finger -> its saved no-load wrench offset; {} when none saved."""
        return {finger: FingerBias(tuple(entry["offset"]), entry["bundle"], entry["samples"], entry["written_at"])
                for finger, entry in self._entries(FORCE_BIAS_FILE, "force_bias").items()}

    def save_force_bias(self, offsets: Mapping[str, Iterable[float]], bundles: Mapping[str, str | Path],
                        samples: int, note: str = "") -> Path:
        """Merge each finger's offset [fx fy fz tx ty tz] (taken with the bundle directory in
        `bundles`, averaged over `samples` estimates) into force_bias.yaml; returns its path."""
        path = self.path(FORCE_BIAS_FILE)
        stamp = self._stamp(note)
        entries = {}
        for finger, offset in offsets.items():
            values = [float(v) for v in offset]
            entry = {"offset": values, "bundle": str(bundles[finger]), "samples": int(samples), **stamp}
            entries[finger] = _check_bias(path, finger, entry)
        return self._merge(FORCE_BIAS_FILE, "force_bias", entries)

    # --- model bundles -----------------------------------------------------------------------
    def bundles(self) -> dict[str, Path]:
        """finger -> model bundle directory (a relative one is inside the hand directory); {} when
        none saved. Whether the directory holds a usable bundle is the loader's check."""
        return {finger: self.root / entry["bundle"]
                for finger, entry in self._entries(BUNDLES_FILE, "bundles").items()}

    def save_bundle(self, finger: str, source: Path | str, copy: bool = True, note: str = "") -> Path:
        """Make `source` (a bundle directory) the finger's bundle: copied to bundles/<finger>/
        (replacing the one there, atomically) or, with copy=False, referenced by its absolute path.
        Returns the bundle directory the hand directory now names."""
        path = self.path(BUNDLES_FILE)
        _check_key(path, "bundles", finger, FINGERS)
        src = Path(os.path.abspath(os.path.expanduser(str(source))))
        if not src.is_dir():
            raise HandConfigError(f"{path}: bundle for {finger} {str(source)!r} is not a directory; give the bundle "
                                  "directory (model.pt + metadata.json)")
        if copy:
            target = self.root / BUNDLES_DIR / finger
            if src != target:
                try:
                    with atomic_output(target) as staged:
                        shutil.copytree(src, staged, symlinks=False)
                except OSError as exc:
                    raise HandConfigError(f"{target}: cannot copy bundle {src} ({describe_os_error(exc)})") from None
            recorded = f"{BUNDLES_DIR}/{finger}"
        else:
            target, recorded = src, str(src)
        self._merge(BUNDLES_FILE, "bundles", {finger: {"bundle": recorded, "source": str(src), **self._stamp(note)}})
        return target

    # --- files -------------------------------------------------------------------------------
    def _stamp(self, note: str) -> dict[str, str]:
        return {"written_at": now_iso(), "written_by": self.writer, "note": str(note)}

    def _read(self, name: str) -> dict[str, Any] | None:
        path = self.path(name)
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            return None
        except (OSError, UnicodeDecodeError) as exc:
            raise HandConfigError(f"{path}: cannot read ({describe_os_error(exc)}); fix the hand directory's "
                                  "permissions or choose another with hand_config:=<dir>") from None
        try:
            document = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            where = getattr(exc, "problem_mark", None)
            line = f" at line {where.line + 1}" if where is not None else ""
            raise HandConfigError(f"{path}: not valid YAML{line} ({getattr(exc, 'problem', None) or exc}); fix "
                                  "or remove the file (it is rewritten by the next save)") from None
        if document is None:
            return {}
        if not isinstance(document, dict):
            raise HandConfigError(f"{path}: expected a mapping of keys, got {_show(document)}; fix or remove the file")
        return document

    def _entries(self, name: str, key: str) -> dict[str, dict[str, Any]]:
        """The checked entries of the file's `key` mapping; {} when the file does not exist."""
        document = self._read(name)
        if not document:
            return {}
        path = self.path(name)
        raw = document.get(key, {})
        if raw is None:
            return {}
        if not isinstance(raw, dict):
            raise HandConfigError(f"{path}: '{key}' must be a mapping, got {_show(raw)}; fix or remove the file")
        return {str(k): _CHECKS[key](path, str(k), v) for k, v in raw.items()}

    def _merge(self, name: str, key: str, entries: dict[str, dict[str, Any]]) -> Path:
        # reading checks the file: a damaged one is reported, not silently overwritten
        merged = self._entries(name, key)
        merged.update(entries)
        document = {"written_by": self.writer, "written_at": now_iso(), key: dict(sorted(merged.items()))}
        target = self.path(name)
        text = yaml.safe_dump(document, sort_keys=False, default_flow_style=False, width=120)
        try:
            with atomic_output(target) as staged:
                staged.write_text(text, encoding="utf-8")
        except OSError as exc:
            raise HandConfigError(f"{target}: cannot write ({describe_os_error(exc)}); check that the hand "
                                  "directory is writable or choose another with hand_config:=<dir>") from None
        return target


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _check_key(path: Path, kind: str, key: str, allowed: tuple[str, ...]) -> str:
    if key not in allowed:
        raise HandConfigError(f"{path}: {kind} entry {key!r} is not one of {', '.join(allowed)}; remove or rename it")
    return key


def _check_ticks(path: Path, motor: str, ticks: Any) -> int:
    _check_key(path, "motor_zeros", motor, MOTOR_NAMES)
    if not isinstance(ticks, bool) and hasattr(ticks, "__index__"):
        ticks = int(ticks.__index__())  # numpy integers from the driver convert exactly; floats have no __index__
    if not isinstance(ticks, int) or isinstance(ticks, bool) or not -TICKS_LIMIT <= ticks < TICKS_LIMIT:
        raise HandConfigError(f"{path}: motor_zeros {motor} = {_show(ticks)} is not a whole number of ticks in "
                              f"[{-TICKS_LIMIT}, {TICKS_LIMIT - 1}]; rehome the motor or fix the value")
    return ticks


def _entry(path: Path, kind: str, key: str, value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise HandConfigError(f"{path}: {kind} {key} must be a mapping, got {_show(value)}; fix or remove the file")
    return value


def _provenance(path: Path, kind: str, key: str, entry: dict[str, Any]) -> dict[str, str]:
    out = {}
    for field in ("written_at", "written_by", "note"):
        value = entry.get(field, "")
        if not isinstance(value, str):
            raise HandConfigError(f"{path}: {kind} {key} {field} = {_show(value)} must be text; fix or remove it")
        out[field] = value
    return out


def _motor_entry(path: Path, motor: str, value: Any) -> dict[str, Any]:
    entry = _entry(path, "motor_zeros", motor, value)
    if "ticks" not in entry:
        raise HandConfigError(f"{path}: motor_zeros {motor} has no 'ticks'; rehome the motor or fix the file")
    return {"ticks": _check_ticks(path, motor, entry["ticks"]), **_provenance(path, "motor_zeros", motor, entry)}


def _check_bias(path: Path, finger: str, value: Any) -> dict[str, Any]:
    _check_key(path, "force_bias", finger, FINGERS)
    entry = _entry(path, "force_bias", finger, value)
    offset = entry.get("offset")
    if (not isinstance(offset, list) or len(offset) != len(WRENCH_AXES)
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in offset)
            or any(math.isinf(v) for v in offset)):
        raise HandConfigError(f"{path}: force_bias {finger} offset = {_show(offset)} is not {len(WRENCH_AXES)} "
                              f"numbers [{' '.join(WRENCH_AXES)}] (N, N*m; .nan for an axis the network lacks); "
                              "take the bias again (~/bias) or fix the file")
    bundle, samples = entry.get("bundle"), entry.get("samples")
    if not isinstance(bundle, str) or not bundle:
        raise HandConfigError(f"{path}: force_bias {finger} bundle = {_show(bundle)} must name the bundle directory "
                              "the bias was taken with; take the bias again (~/bias)")
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise HandConfigError(f"{path}: force_bias {finger} samples = {_show(samples)} must be a whole number >= 1; "
                              "take the bias again (~/bias)")
    return {"offset": [float(v) for v in offset], "bundle": bundle, "samples": samples,
            **_provenance(path, "force_bias", finger, entry)}


def _bundle_entry(path: Path, finger: str, value: Any) -> dict[str, Any]:
    _check_key(path, "bundles", finger, FINGERS)
    entry = _entry(path, "bundles", finger, value)
    bundle = entry.get("bundle")
    if not isinstance(bundle, str) or not bundle.strip():
        raise HandConfigError(f"{path}: bundles {finger} bundle = {_show(bundle)} must be a bundle directory "
                              "(relative = inside the hand directory); fix the file or save the bundle again")
    source = entry.get("source", "")
    return {"bundle": bundle, "source": source if isinstance(source, str) else str(source),
            **_provenance(path, "bundles", finger, entry)}


_CHECKS = {"motor_zeros": _motor_entry, "force_bias": _check_bias, "bundles": _bundle_entry}
