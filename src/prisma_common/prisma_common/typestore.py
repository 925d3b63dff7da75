"""rosbags typestore for ROS 2 Jazzy with every prisma_msgs interface registered.

The .msg/.action files are read from the directory named by PRISMA_MSGS_DIR, else from the
source tree, share/prisma_msgs of a colcon install or of the wheel's prefix (share_data).
`types(name)` is the message-class lookup the converters take (docs/architecture.md, Pure core, thin node).
rosbags is imported when a typestore is built, not with this module, so that the CLIs importing
the bag layer keep `--help` light.
"""
from __future__ import annotations

import functools
import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from . import share_data

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

PACKAGE = "prisma_msgs"

# A field line: type (optionally array), name, optional default; or a constant TYPE NAME=value.
_FIELD = re.compile(
    r"^(?P<type>[A-Za-z][\w/]*(?:<=\d+)?(?:\[(?:<=)?\d*\])?)\s+"
    r"(?P<name>[A-Za-z]\w*)(?:\s*=\s*\S.*|\s+\S.*)?$"
)


class InterfaceParseError(ValueError):
    """A .msg/.action file that cannot be parsed; the message names file and line."""


@dataclass(frozen=True)
class InterfaceFile:
    path: Path
    kind: str  # "msg" or "action"

    @property
    def name(self) -> str:
        return self.path.stem


def find_interface_dir() -> Path:
    """Directory holding msg/ and action/ of prisma_msgs."""
    candidates: list[Path] = []
    if os.environ.get("PRISMA_MSGS_DIR"):
        candidates.append(Path(os.environ["PRISMA_MSGS_DIR"]))
    candidates += share_data.package_directories(PACKAGE)
    for candidate in candidates:
        if (candidate / "msg").is_dir():
            return candidate
    raise FileNotFoundError(
        f"prisma_msgs interface files not found; looked in {', '.join(map(str, candidates))}"
    )


def interface_files(root: Path) -> list[InterfaceFile]:
    files = [InterfaceFile(p, "msg") for p in sorted((root / "msg").glob("*.msg"))]
    files += [InterfaceFile(p, "action") for p in sorted((root / "action").glob("*.action"))]
    return files


def _check_lines(path: Path, lines: list[str], first_line: int) -> None:
    for offset, raw in enumerate(lines):
        line = raw.split("#", 1)[0].strip()
        if line and not _FIELD.match(line):
            raise InterfaceParseError(f"{path}:{first_line + offset}: cannot parse {raw.strip()!r}")


def _parse(text: str, typename: str, path: Path, first_line: int) -> dict:
    lines = text.splitlines()
    _check_lines(path, lines, first_line)
    from rosbags.typesys import get_types_from_msg

    try:
        return get_types_from_msg(text, typename)
    except Exception as exc:  # rosbags raises several parser exception types
        raise InterfaceParseError(f"{path}:{first_line}: {typename}: {exc}") from exc


def parse_msg_file(path: Path) -> dict:
    return _parse(path.read_text(), f"{PACKAGE}/msg/{path.stem}", path, 1)


def parse_action_file(path: Path) -> dict:
    """Goal, Result, Feedback, FeedbackMessage and the SendGoal/GetResult service parts."""
    from rosbags.typesys import get_types_from_msg

    name = path.stem
    sections: list[tuple[int, list[str]]] = [(1, [])]
    for number, line in enumerate(path.read_text().splitlines(), start=1):
        if line.strip() == "---":
            sections.append((number + 1, []))
        else:
            sections[-1][1].append(line)
    if len(sections) != 3:
        raise InterfaceParseError(
            f"{path}:1: an action needs goal, result and feedback sections separated by '---', "
            f"found {len(sections)} section(s)"
        )
    base = f"{PACKAGE}/action/{name}"
    types: dict = {}
    for suffix, (first_line, lines) in zip(("Goal", "Result", "Feedback"), sections):
        types.update(_parse("\n".join(lines), f"{base}_{suffix}", path, first_line))
    derived = {
        "FeedbackMessage": f"unique_identifier_msgs/msg/UUID goal_id\n{base}_Feedback feedback",
        "SendGoal_Request": f"unique_identifier_msgs/msg/UUID goal_id\n{base}_Goal goal",
        "SendGoal_Response": "bool accepted\nbuiltin_interfaces/msg/Time stamp",
        "GetResult_Request": "unique_identifier_msgs/msg/UUID goal_id",
        "GetResult_Response": f"int8 status\n{base}_Result result",
    }
    for suffix, text in derived.items():
        types.update(get_types_from_msg(text, f"{base}_{suffix}"))
    return types


def prisma_types(root: Path | None = None) -> dict:
    root = root or find_interface_dir()
    types: dict = {}
    for item in interface_files(root):
        parser = parse_msg_file if item.kind == "msg" else parse_action_file
        types.update(parser(item.path))
    return types


@functools.cache
def get_typestore() -> Typestore:
    """The Jazzy typestore with prisma_msgs registered (cached; do not mutate)."""
    from rosbags.typesys import Stores
    from rosbags.typesys import get_typestore as _rosbags_typestore

    store = _rosbags_typestore(Stores.ROS2_JAZZY)
    store.register(prisma_types())
    return store


def types(name: str) -> type:
    """Message class for 'pkg/msg/Name' (or 'pkg/action/Name_Goal'...), for converters."""
    store = get_typestore()
    try:
        return store.types[name]
    except KeyError:
        raise KeyError(f"unknown message type {name!r}") from None


MessageLookup = Callable[[str], type]


def _as_msg_name(value):
    """Rename interface-derived types (pkg/action/X, pkg/srv/X) to pkg/msg/X, recursively."""
    if isinstance(value, str):
        package, sep, rest = value.partition("/")
        kind, sep2, name = rest.partition("/")
        return f"{package}/msg/{name}" if sep and sep2 and kind in ("action", "srv") else value
    if isinstance(value, (list, tuple)):
        return type(value)(_as_msg_name(v) for v in value)
    return value


@functools.cache
def _msg_alias_typestore() -> Typestore:
    """The typestore with action/service-derived types also registered under msg names."""
    from rosbags.typesys import Stores
    from rosbags.typesys import get_typestore as _rosbags_typestore

    store = _rosbags_typestore(Stores.ROS2_JAZZY)
    source = get_typestore().fielddefs
    store.register({_as_msg_name(name): _as_msg_name(definition) for name, definition in source.items()
                    if name != _as_msg_name(name) or name.startswith(f"{PACKAGE}/")})
    return store


@functools.cache
def message_definition(msgtype: str) -> tuple[str, str]:
    """(ros2msg definition text, RIHS01 hash) of `msgtype` as bags store it.

    rosbags cannot write the definition of action-derived types (e.g. the feedback topic's
    `prisma_msgs/action/Grasp_FeedbackMessage`): nested action types are written here under
    `pkg/Name` like any message, so rosbags' AnyReader and mcap_ros2's reader can decode the topic.
    The hash is that of the definition as a reader rebuilds it from the text."""
    from rosbags.typesys import Stores, get_types_from_msg
    from rosbags.typesys import get_typestore as _rosbags_typestore

    store = get_typestore()
    if _as_msg_name(msgtype) == msgtype:
        return store.generate_msgdef(msgtype, ros_version=2)[0], store.hash_rihs01(msgtype)
    text = _msg_alias_typestore().generate_msgdef(_as_msg_name(msgtype), ros_version=2)[0]
    rebuilt = _rosbags_typestore(Stores.EMPTY)
    rebuilt.register(get_types_from_msg(text, msgtype))
    return text, rebuilt.hash_rihs01(msgtype)


def registered_prisma_types() -> list[str]:
    return sorted(name for name in get_typestore().types if name.startswith(f"{PACKAGE}/"))
