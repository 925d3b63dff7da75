"""Message, service and action classes with rclpy semantics, generated from the typestore.

Each message class subclasses the rosbags dataclass of the same type from
`prisma_bringup.typestore.get_typestore()`, and `get_typestore().serialize_cdr(msg, msg.__msgtype__)`
works on any stand-in message (a message taken from a stand-in topic can go straight into a bag).

The classes behave like rosidl_generator_py classes with their field checks on (always on in
Humble; in Jazzy when ROS_PYTHON_CHECK_FIELDS=1). Jazzy's default skips the checks, and a wrong value
then reaches the C conversion, which e.g. compares each item of a bool[9] with Python's True, so
numpy bools go out as False. A node that passes these checks publishes what it means either way.
- keyword-only construction of any subset of fields; every other field gets its ROS default
  (0, 0.0, False, '', nested message constructed, fixed arrays sized, sequences empty);
  an unknown keyword raises AssertionError naming it;
- scalar setters: float fields take `float` only (not int, not numpy.float32), integer fields take
  `int` within range, byte fields take a one-byte `bytes` (use the class constants);
- numeric sequences (`float64[]`, `uint16[<=8]`, ...) are `array.array` of the element's typecode
  ('d', 'H', ...). The setter takes an array.array of that typecode or a list/tuple/set of Python
  numbers of the element type; a numpy array is not a `collections.abc.Sequence` and raises
  AssertionError. The constructor first wraps the value in `array.array(typecode, value)`, as
  rclpy's `__init__` does, so `JointState(position=ndarray)` works where `msg.position = ndarray`
  fails;
- fixed numeric arrays (`float32[9]`) are numpy arrays: the setter takes an ndarray of exactly that
  dtype and length, or a sequence of that length; the constructor converts with
  `numpy.array(value, dtype)` first;
- bool, byte and string arrays and sequences are lists (`bool[9]` defaults to nine False); their
  elements must be `bool`, `bytes` and `str`, and a numpy array raises AssertionError;
- a message crossing a topic, service or action arrives as rclpy's C conversion builds it: numeric
  sequences as array.array, fixed numeric arrays as numpy arrays, everything else as lists;
- equality by fields (also against a typestore instance of the same type).

rosbags' serializer needs numpy arrays in every non-string array field, so the stand-in wraps
`serialize_cdr`/`serialize_ros1` of the typestore it is built from: a stand-in message is first
turned into the plain typestore dataclass (`to_typestore`); other messages pass through unchanged.
"""
from __future__ import annotations

import array
import math
import types as pytypes
from collections import UserList, UserString
from collections.abc import Sequence, Set
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore as _rosbags_typestore

from prisma_bringup.typestore import get_typestore

# rosidl_generator_py's SPECIAL_NESTED_BASIC_TYPES: element types held in array.array (sequences)
# and numpy arrays (fixed arrays). ROS 2 `char` is uint8.
_TYPECODES = {
    "float32": "f",
    "float64": "d",
    "int8": "b",
    "uint8": "B",
    "char": "B",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "q",
    "uint64": "Q",
}
# numpy dtypes rosbags uses for every non-string base type.
_DTYPES = {
    "bool": np.bool_,
    "byte": np.int8,
    "char": np.uint8,
    "int8": np.int8,
    "uint8": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}
_INT_RANGES = {
    "int8": (-(2**7), 2**7 - 1),
    "uint8": (0, 2**8 - 1),
    "char": (0, 2**8 - 1),
    "int16": (-(2**15), 2**15 - 1),
    "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1),
    "uint64": (0, 2**64 - 1),
}
_FLOAT_MAX = {"float32": 3.402823466e38, "float64": 1.7976931348623157e308}

# Interfaces the Jazzy typestore of rosbags does not carry (it holds messages only) but the
# nodes use: services and the action protocol services. Definitions as in ROS 2 Jazzy.
_EXTRA_DEFINITIONS = {
    "std_srvs/srv/Trigger_Request": "",
    "std_srvs/srv/Trigger_Response": "bool success\nstring message",
    "std_srvs/srv/SetBool_Request": "bool data",
    "std_srvs/srv/SetBool_Response": "bool success\nstring message",
    "std_srvs/srv/Empty_Request": "",
    "std_srvs/srv/Empty_Response": "",
    "action_msgs/srv/CancelGoal_Request": "action_msgs/msg/GoalInfo goal_info",
    "action_msgs/srv/CancelGoal_Response": (
        "int8 ERROR_NONE=0\nint8 ERROR_REJECTED=1\nint8 ERROR_UNKNOWN_GOAL_ID=2\n"
        "int8 ERROR_GOAL_TERMINATED=3\nint8 return_code\naction_msgs/msg/GoalInfo[] goals_canceling"
    ),
    "rcl_interfaces/srv/SetParameters_Request": "rcl_interfaces/msg/Parameter[] parameters",
    "rcl_interfaces/srv/SetParameters_Response": "rcl_interfaces/msg/SetParametersResult[] results",
    "rcl_interfaces/srv/GetParameters_Request": "string[] names",
    "rcl_interfaces/srv/GetParameters_Response": "rcl_interfaces/msg/ParameterValue[] values",
}


class _Byte(bytes):
    """A one-byte `bytes` (what rclpy stores in byte fields) that rosbags can also pack as an int."""

    def __index__(self) -> int:
        return self[0]

    def __int__(self) -> int:
        return self[0]

    def __eq__(self, other: object) -> bool:
        if isinstance(other, int) and not isinstance(other, bool):
            return self[0] == other
        return bytes.__eq__(self, other)

    def __ne__(self, other: object) -> bool:
        return not self.__eq__(other)

    __hash__ = bytes.__hash__

    def __repr__(self) -> str:
        return bytes.__repr__(bytes(self))

    def __deepcopy__(self, memo: dict) -> "_Byte":
        return self


class _Store:
    """Field definitions and base dataclasses: the shared typestore plus the extra services."""

    def __init__(self) -> None:
        self.shared = get_typestore()
        self.extra = _rosbags_typestore(Stores.ROS2_JAZZY)
        extra_types: dict = {}
        for name, text in _EXTRA_DEFINITIONS.items():
            # rosbags files every parsed name under '<pkg>/msg/'; keep the service path.
            (parsed,) = get_types_from_msg(text, name).values()
            extra_types[name] = parsed
        self.extra.register(extra_types)
        self.classes: dict[str, type] = {}
        for store in (self.shared, self.extra):
            _serialise_stand_in_messages(store)

    def has(self, typename: str) -> bool:
        return typename in self.shared.types or typename in self.extra.types

    def store_of(self, typename: str):
        if typename in self.shared.types:
            return self.shared
        if typename in self.extra.types:
            return self.extra
        raise KeyError(f"unknown interface type {typename!r}")

    def fields_of(self, typename: str) -> list:
        return self.store_of(typename).fielddefs[typename][1]

    def all_typenames(self) -> list[str]:
        return sorted(set(self.shared.types) | set(self.extra.types))


_STORE: _Store | None = None


def _store() -> _Store:
    global _STORE
    if _STORE is None:
        _STORE = _Store()
    return _STORE


def _is_stand_in(message: Any) -> bool:
    return getattr(type(message), "__standin__", False)


# ----------------------------------------------------------------------------------------------
# Field checks (rosidl_generator_py property setters with field checks on)


def _check_base(cls_name: str, field: str, basetype: str, bound: int, value: Any) -> Any:
    where = f"The '{field}' field"
    if basetype == "bool":
        assert isinstance(value, bool), f"{where} must be of type 'bool'"
        return value
    if basetype == "byte":
        if isinstance(value, _Byte):
            return value
        assert isinstance(value, (bytes, bytearray)) and len(value) == 1, (
            f"{where} must be of type 'bytes' or 'ByteString' of length 1 "
            f"(use the class constants, e.g. {cls_name}.<CONSTANT>)"
        )
        return _Byte(bytes(value))
    if basetype == "string":
        assert isinstance(value, str), f"{where} must be of type 'str'"
        if bound:
            assert len(value) <= bound, f"{where} must be string with length not greater than {bound}"
        return value
    if basetype in _INT_RANGES:
        assert isinstance(value, int), f"{where} must be of type 'int'"
        low, high = _INT_RANGES[basetype]
        assert low <= value <= high, f"{where} must be an integer in [{low}, {high}]"
        return value
    if basetype in _FLOAT_MAX:
        assert isinstance(value, float), f"{where} must be of type 'float'"
        limit = _FLOAT_MAX[basetype]
        assert not (value < -limit or value > limit) or math.isinf(value), (
            f"{where} must be a float in [{-limit}, {limit}]"
        )
        return float(value)
    raise AssertionError(f"{where} has unsupported type {basetype!r}")


def _check_nested(field: str, typename: str, value: Any) -> Any:
    assert getattr(value, "__msgtype__", None) == typename, (
        f"The '{field}' field must be a sub message of type '{typename.replace('/msg/', '/')}'"
    )
    return value if type(value) is get_class(typename) else convert(value)


def _python_type(elem_kind: Any, elem_detail: Any) -> type | None:
    """The element type rclpy's sequence setter asserts (None: a nested message)."""
    if elem_kind != Nodetype.BASE:
        return None
    basetype = elem_detail[0]
    if basetype in _FLOAT_MAX:
        return float
    if basetype in _INT_RANGES:
        return int
    return {"bool": bool, "byte": bytes, "string": str}[basetype]


def _elements_ok(elem_kind: Any, elem_detail: Any, values: Any) -> tuple[bool, str]:
    """Whether every element has rclpy's element type and range, and the wording of that rule."""
    if elem_kind == Nodetype.NAME:
        name = elem_detail.rsplit("/", 1)[-1]
        return all(getattr(v, "__msgtype__", None) == elem_detail for v in values), f"each value of type '{name}'"
    basetype, bound = elem_detail
    pytype = _python_type(elem_kind, elem_detail)
    rule = f"each value of type '{pytype.__name__}'"
    ok = all(isinstance(v, pytype) for v in values)
    if ok and basetype in _INT_RANGES:
        low, high = _INT_RANGES[basetype]
        rule += f" and each {'unsigned ' if low == 0 else ''}integer in [{low}, {high}]"
        ok = all(low <= v <= high for v in values)
    elif ok and basetype in _FLOAT_MAX:
        limit = _FLOAT_MAX[basetype]
        rule += f" and each {'float' if basetype == 'float32' else 'double'} in [{-limit}, {limit}]"
        ok = all(not (v < -limit or v > limit) or math.isinf(v) for v in values)
    elif ok and basetype == "string" and bound:
        rule += f" and each string value not longer than {bound}"
        ok = all(len(v) <= bound for v in values)
    return ok, rule


def _check_collection(field: str, spec: tuple, value: Any) -> Any:
    kind, ((elem_kind, elem_detail), size) = spec
    fixed = kind == Nodetype.ARRAY
    typecode = _TYPECODES.get(elem_detail[0]) if elem_kind == Nodetype.BASE else None
    if typecode and fixed and isinstance(value, np.ndarray):
        dtype = np.dtype(_DTYPES[elem_detail[0]])
        assert value.dtype == dtype, f"The '{field}' numpy.ndarray() must have the dtype of 'numpy.{dtype.name}'"
        assert value.size == size, f"The '{field}' numpy.ndarray() must have a size of {size}"
        # rclpy's setter stops here; its C conversion then asserts a one-dimensional array.
        assert value.ndim == 1, f"The '{field}' numpy.ndarray() must be one-dimensional"
        return value
    if typecode and not fixed and isinstance(value, array.array):
        assert value.typecode == typecode, f"The '{field}' array.array() must have the type code of '{typecode}'"
        if size:
            assert len(value) <= size, f"The '{field}' array.array() must have a size <= {size}"
        return value
    container = isinstance(value, (Sequence, Set, UserList)) and not isinstance(value, (str, UserString))
    length_rule = f" with length {size}" if fixed else f" with length <= {size}" if size else ""
    length_ok = container and (len(value) == size if fixed else not size or len(value) <= size)
    elements_ok, element_rule = _elements_ok(elem_kind, elem_detail, value) if container else (False, "")
    if not (container and length_ok and elements_ok):
        if not element_rule:
            element_rule = _elements_ok(elem_kind, elem_detail, ())[1]
        hint = ""
        if isinstance(value, np.ndarray):
            wanted = (f"array.array('{typecode}')" if typecode and not fixed else
                      f"a numpy.{np.dtype(_DTYPES[elem_detail[0]]).name} array" if typecode else "a list")
            hint = (f" (got a numpy.ndarray, which is no collections.abc.Sequence: pass {wanted}, e.g. from "
                    f"prisma_tactile_driver.ros_conversions.sequence_field)")
        raise AssertionError(
            f"The '{field}' field must be a set or sequence{length_rule} and {element_rule}{hint}")
    if typecode:
        return np.array(value, dtype=_DTYPES[elem_detail[0]]) if fixed else array.array(typecode, value)
    if elem_kind == Nodetype.NAME and any(type(v) is not get_class(elem_detail) for v in value):
        return [v if type(v) is get_class(elem_detail) else convert(v) for v in value]
    return value


def _check_field(cls_name: str, field: str, spec: tuple, value: Any) -> Any:
    kind, detail = spec
    if kind == Nodetype.BASE:
        return _check_base(cls_name, field, detail[0], detail[1], value)
    if kind == Nodetype.NAME:
        return _check_nested(field, detail, value)
    return _check_collection(field, spec, value)


def _constructor_value(field: str, spec: tuple, value: Any) -> Any:
    """What rclpy's __init__ does to a keyword before the setter sees it (numeric arrays only)."""
    kind, detail = spec
    if kind not in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return value
    (elem_kind, elem_detail), size = detail
    if elem_kind != Nodetype.BASE or elem_detail[0] not in _TYPECODES:
        return value
    if kind == Nodetype.SEQUENCE:
        return array.array(_TYPECODES[elem_detail[0]], value)
    converted = np.array(value, dtype=_DTYPES[elem_detail[0]])
    assert converted.shape == (size,), (
        f"The '{field}' field must be a sequence with length {size}, got shape {converted.shape}")
    return converted


def _default(spec: tuple) -> Any:
    kind, detail = spec
    if kind == Nodetype.BASE:
        basetype = detail[0]
        if basetype == "bool":
            return False
        if basetype == "byte":
            return _Byte(b"\x00")
        if basetype == "string":
            return ""
        if basetype in _FLOAT_MAX:
            return 0.0
        return 0
    if kind == Nodetype.NAME:
        return get_class(detail)()
    (elem_kind, elem_detail), size = detail
    if elem_kind == Nodetype.BASE and elem_detail[0] in _TYPECODES:
        if kind == Nodetype.ARRAY:
            return np.zeros(size, dtype=_DTYPES[elem_detail[0]])
        return array.array(_TYPECODES[elem_detail[0]])
    if kind == Nodetype.ARRAY:
        if elem_kind == Nodetype.BASE and elem_detail[0] == "byte":
            return [bytes([0]) for _ in range(size)]
        return [_default((elem_kind, elem_detail)) for _ in range(size)]
    return []


def _byte_value(value: Any) -> int:
    # rosbags holds byte arrays as int8, rclpy as one-byte bytes: both as 0..255 here.
    return value[0] if isinstance(value, (bytes, bytearray)) else int(value) & 0xFF


def _for_rosbags(spec: tuple, value: Any) -> Any:
    """A field value as the typestore dataclass holds it (numpy arrays, int bytes)."""
    kind, detail = spec
    if kind == Nodetype.BASE:
        return _byte_value(value) if detail[0] == "byte" else value
    if kind == Nodetype.NAME:
        return to_typestore(value)
    (elem_kind, elem_detail), _ = detail
    if elem_kind == Nodetype.NAME:
        return [to_typestore(v) for v in value]
    if elem_detail[0] == "string":
        return list(value)
    if elem_detail[0] == "byte":
        return np.array([_byte_value(v) for v in value], dtype=np.uint8).view(np.int8)
    return np.ascontiguousarray(np.asarray(value, dtype=_DTYPES[elem_detail[0]]).reshape(-1))


def _field_equal(spec: tuple, a: Any, b: Any) -> bool:
    kind, detail = spec
    if kind in (Nodetype.BASE, Nodetype.NAME):
        return bool(a == b)
    (elem_kind, elem_detail), _ = detail
    if elem_kind == Nodetype.BASE and elem_detail[0] != "string":
        return np.array_equal(_for_rosbags(spec, a), _for_rosbags(spec, b))
    return len(a) == len(b) and all(x == y for x, y in zip(a, b))


def _type_string(spec: tuple) -> str:
    """Field type as rclpy's get_fields_and_field_types() spells it."""
    kind, detail = spec
    if kind == Nodetype.BASE:
        name = {"float32": "float", "float64": "double", "byte": "octet"}.get(detail[0], detail[0])
        return f"{name}<{detail[1]}>" if detail[1] else name
    if kind == Nodetype.NAME:
        return detail.replace("/msg/", "/")
    elem, size = detail
    inner = _type_string(elem)
    if kind == Nodetype.ARRAY:
        return f"{inner}[{size}]"
    return f"sequence<{inner}, {size}>" if size else f"sequence<{inner}>"


# ----------------------------------------------------------------------------------------------
# Class generation


def _make_class(typename: str) -> type:
    store = _store().store_of(typename)
    base = store.types[typename]
    consts, fields = store.fielddefs[typename]
    specs = dict(fields)
    order = [name for name, _ in fields]
    short = typename.rsplit("/", 1)[-1]

    def __init__(self, **kwargs: Any) -> None:
        unknown = sorted(key for key in kwargs if key not in specs)
        assert not unknown, "Invalid arguments passed to constructor: %s" % ", ".join(unknown)
        for name in order:
            if name in kwargs:
                setattr(self, name, _constructor_value(name, specs[name], kwargs[name]))
            else:
                object.__setattr__(self, name, _default(specs[name]))

    def __setattr__(self, name: str, value: Any) -> None:
        spec = specs.get(name)
        if spec is None:
            raise AttributeError(f"'{short}' message has no field '{name}'")
        object.__setattr__(self, name, _check_field(short, name, spec, value))

    def __eq__(self, other: object) -> bool:
        if getattr(other, "__msgtype__", None) != typename:
            return NotImplemented if not hasattr(other, "__msgtype__") else False
        return all(_field_equal(specs[n], getattr(self, n), getattr(other, n)) for n in order)

    def __repr__(self) -> str:
        inner = ", ".join(f"{n}={getattr(self, n)!r}" for n in order)
        return f"{typename.replace('/', '.')}({inner})"

    @classmethod
    def get_fields_and_field_types(cls) -> dict[str, str]:
        return {name: _type_string(spec) for name, spec in fields}

    namespace: dict[str, Any] = {
        "__init__": __init__,
        "__setattr__": __setattr__,
        "__eq__": __eq__,
        "__ne__": lambda self, other: not (self == other),
        "__hash__": None,
        "__repr__": __repr__,
        "__msgtype__": typename,
        "__standin__": True,
        "__module__": typename.rsplit("/", 1)[0].replace("/", "."),
        "__qualname__": short,
        "get_fields_and_field_types": get_fields_and_field_types,
        "_fields_and_field_types": {name: _type_string(spec) for name, spec in fields},
        "SLOT_TYPES": tuple(specs.values()),
    }
    for const_name, const_type, const_value in consts:
        if const_type == "byte":
            const_value = _Byte(bytes([const_value]))
        namespace[const_name] = const_value
    return type(short, (base,), namespace)


def get_class(typename: str) -> type:
    """Stand-in class for 'pkg/msg/Name' (also 'pkg/srv/Name_Request', 'pkg/action/Name_Goal')."""
    store = _store()
    cls = store.classes.get(typename)
    if cls is None:
        cls = _make_class(typename)
        store.classes[typename] = cls
    return cls


def convert(message: Any) -> Any:
    """The stand-in message a subscriber gets for `message` (a stand-in or typestore instance).

    Like rclpy's C conversion of a received message: a fresh object whose numeric sequences are
    array.array, fixed numeric arrays numpy arrays and other arrays lists, sharing nothing."""
    typename = message.__msgtype__
    cls = get_class(typename)
    out = cls.__new__(cls)
    for name, spec in _store().fields_of(typename):
        object.__setattr__(out, name, _received(name, spec, getattr(message, name)))
    return out


def copy_message(message: Any) -> Any:
    return convert(message)


def _received(field: str, spec: tuple, value: Any) -> Any:
    kind, detail = spec
    if kind == Nodetype.BASE:
        return _plain(value, spec)
    if kind == Nodetype.NAME:
        return convert(value)
    (elem_kind, elem_detail), size = detail
    if kind == Nodetype.ARRAY:
        assert len(value) == size, f"The '{field}' field must be a sequence with length {size}"
    if elem_kind == Nodetype.NAME:
        return [convert(v) for v in value]
    basetype = elem_detail[0]
    if basetype in _TYPECODES:
        data = np.asarray(value, dtype=_DTYPES[basetype]).reshape(-1)
        return data.copy() if kind == Nodetype.ARRAY else array.array(_TYPECODES[basetype], data.tobytes())
    if basetype == "bool":
        return [bool(v) for v in value]
    if basetype == "byte":
        return [bytes([_byte_value(v)]) for v in value]
    return [str(v) for v in value]


def _plain(value: Any, spec: tuple) -> Any:
    # Values read from a typestore instance: byte fields come as int, turn them into bytes.
    kind, detail = spec
    if kind == Nodetype.BASE and detail[0] == "byte":
        return value if isinstance(value, _Byte) else _Byte(bytes([_byte_value(value)]))
    if kind == Nodetype.BASE and detail[0] in _FLOAT_MAX and not isinstance(value, float):
        return float(value)
    if kind == Nodetype.BASE and detail[0] in _INT_RANGES and not isinstance(value, int):
        return int(value)
    if kind == Nodetype.BASE and detail[0] == "bool" and not isinstance(value, bool):
        return bool(value)
    return value


# ----------------------------------------------------------------------------------------------
# Serialisation through the typestore


def to_typestore(message: Any) -> Any:
    """The typestore dataclass instance of a stand-in message (others are returned unchanged)."""
    if not _is_stand_in(message):
        return message
    typename = message.__msgtype__
    store = _store().store_of(typename)
    fields = store.fielddefs[typename][1]
    return store.types[typename](**{name: _for_rosbags(spec, getattr(message, name)) for name, spec in fields})


def _serialise_stand_in_messages(store: Any) -> None:
    """Let `store.serialize_cdr/serialize_ros1` take stand-in messages, whose arrays rosbags cannot pack."""
    for method in ("serialize_cdr", "serialize_ros1"):
        original = getattr(store, method)
        if getattr(original, "takes_stand_in_messages", False):
            continue

        def serialize(message: Any, typename: str, *args: Any, _original: Any = original, **kwargs: Any) -> Any:
            return _original(to_typestore(message), typename, *args, **kwargs)

        serialize.takes_stand_in_messages = True  # type: ignore[attr-defined]
        serialize.__doc__ = original.__doc__
        setattr(store, method, serialize)


# ----------------------------------------------------------------------------------------------
# Services and actions


def _make_service(typename: str) -> type:
    short = typename.rsplit("/", 1)[-1]
    request = get_class(f"{typename}_Request")
    response = get_class(f"{typename}_Response")
    return type(short, (), {
        "Request": request,
        "Response": response,
        "__srvtype__": typename,
        "__module__": typename.rsplit("/", 1)[0].replace("/", "."),
        "__qualname__": short,
    })


def _make_action(typename: str) -> type:
    short = typename.rsplit("/", 1)[-1]
    impl = type("Impl", (), {
        "SendGoalService": type("SendGoalService", (), {
            "Request": get_class(f"{typename}_SendGoal_Request"),
            "Response": get_class(f"{typename}_SendGoal_Response"),
        }),
        "GetResultService": type("GetResultService", (), {
            "Request": get_class(f"{typename}_GetResult_Request"),
            "Response": get_class(f"{typename}_GetResult_Response"),
        }),
        "FeedbackMessage": get_class(f"{typename}_FeedbackMessage"),
        "CancelGoalService": get_interface("action_msgs/srv/CancelGoal"),
        "GoalStatusMessage": get_class("action_msgs/msg/GoalStatusArray"),
    })
    return type(short, (), {
        "Goal": get_class(f"{typename}_Goal"),
        "Result": get_class(f"{typename}_Result"),
        "Feedback": get_class(f"{typename}_Feedback"),
        "Impl": impl,
        "__actiontype__": typename,
        "__module__": typename.rsplit("/", 1)[0].replace("/", "."),
        "__qualname__": short,
    })


_INTERFACES: dict[str, type] = {}


def get_interface(typename: str) -> type:
    """Message, service or action class for 'pkg/msg|srv|action/Name'."""
    cls = _INTERFACES.get(typename)
    if cls is not None:
        return cls
    kind = typename.split("/")[1]
    if kind == "msg":
        cls = get_class(typename)
    elif kind == "srv":
        cls = _make_service(typename)
    elif kind == "action":
        cls = _make_action(typename)
    else:
        raise ValueError(f"unknown interface kind in {typename!r}")
    _INTERFACES[typename] = cls
    return cls


def interface_names(package: str, kind: str) -> list[str]:
    """Names of the interfaces of one package and kind ('msg', 'srv', 'action')."""
    prefix = f"{package}/{kind}/"
    names = [t[len(prefix):] for t in _store().all_typenames() if t.startswith(prefix)]
    if kind == "msg":
        return names
    if kind == "srv":
        return sorted({n[: -len("_Request")] for n in names if n.endswith("_Request")})
    return sorted({n[: -len("_Goal")] for n in names if n.endswith("_Goal") and "_SendGoal" not in n})


def export_package(namespace: dict, package: str, kind: str) -> None:
    """Fill a module namespace (e.g. std_msgs.msg) with every interface of that package/kind."""
    names = interface_names(package, kind)
    for name in names:
        namespace[name] = get_interface(f"{package}/{kind}/{name}")
    namespace["__all__"] = names


def make_module(package: str, kind: str) -> pytypes.ModuleType:
    module = pytypes.ModuleType(f"{package}.{kind}")
    export_package(module.__dict__, package, kind)
    return module
