"""Message, service and action classes with rclpy semantics, generated from the typestore.

Each message class subclasses the rosbags dataclass of the same type from
`prisma_bringup.typestore.get_typestore()`, so `get_typestore().serialize_cdr(msg, msg.__msgtype__)`
works on any stand-in message (a message taken from a stand-in topic can go straight into a bag).

On top of that the classes behave like rosidl_generator_py classes:
- keyword-only construction of any subset of fields; every other field gets its ROS default
  (0, 0.0, False, '', nested message constructed, fixed arrays sized, sequences empty);
  an unknown keyword raises AssertionError naming it, as rclpy does;
- assignments are checked like rclpy's property setters: float fields take `float` only
  (not int, not numpy.float32), integer fields take `int` within range, fixed arrays must have
  their exact length, byte fields take a one-byte `bytes` (use the class constants);
- equality by fields.

Where the storage differs from rclpy (because rosbags' serializer needs it): every numeric or
bool array/sequence is a numpy array of the field's dtype (rclpy uses numpy only for fixed numeric
arrays and array.array / lists otherwise). Assign a list or array; `.append` is not available.
"""
from __future__ import annotations

import copy
import math
import types as pytypes
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore as _rosbags_typestore

from prisma_bringup.typestore import get_typestore

_DTYPES = {
    "bool": np.bool_,
    "byte": np.uint8,
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
_FLOAT32_MAX = 3.402823466e38

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

    def has(self, typename: str) -> bool:
        return typename in self.shared.types or typename in self.extra.types

    def store_of(self, typename: str):
        if typename in self.shared.types:
            return self.shared
        if typename in self.extra.types:
            return self.extra
        raise KeyError(f"unknown interface type {typename!r}")

    def all_typenames(self) -> list[str]:
        return sorted(set(self.shared.types) | set(self.extra.types))


_STORE: _Store | None = None


def _store() -> _Store:
    global _STORE
    if _STORE is None:
        _STORE = _Store()
    return _STORE


# ----------------------------------------------------------------------------------------------
# Field checks (rclpy property-setter semantics)


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
    if basetype in ("float32", "float64"):
        assert isinstance(value, float), f"{where} must be of type 'float'"
        if basetype == "float32":
            assert not (value < -_FLOAT32_MAX or value > _FLOAT32_MAX) or math.isinf(value), (
                f"{where} must be a float in [{-_FLOAT32_MAX}, {_FLOAT32_MAX}]"
            )
        return float(value)
    raise AssertionError(f"{where} has unsupported type {basetype!r}")


def _check_nested(field: str, typename: str, value: Any) -> Any:
    assert getattr(value, "__msgtype__", None) == typename, (
        f"The '{field}' field must be a sub message of type '{typename.replace('/msg/', '/')}'"
    )
    cls = get_class(typename)
    return value if type(value) is cls else convert(value)


def _check_field(cls_name: str, field: str, spec: tuple, value: Any) -> Any:
    kind, detail = spec
    if kind == Nodetype.BASE:
        return _check_base(cls_name, field, detail[0], detail[1], value)
    if kind == Nodetype.NAME:
        return _check_nested(field, detail, value)
    (elem_kind, elem_detail), size = detail
    fixed = kind == Nodetype.ARRAY
    if elem_kind == Nodetype.BASE and elem_detail[0] in _DTYPES:
        dtype = _DTYPES[elem_detail[0]]
        if isinstance(value, (bytes, bytearray)) and elem_detail[0] in ("byte", "uint8", "char"):
            value = np.frombuffer(bytes(value), dtype=np.uint8)
        try:
            array = np.array(value, dtype=dtype, copy=True)
        except (TypeError, ValueError, OverflowError) as exc:
            raise AssertionError(f"The '{field}' field must be a sequence of {elem_detail[0]}: {exc}")
        assert array.ndim == 1, f"The '{field}' field must be a one-dimensional sequence"
        if fixed:
            assert len(array) == size, (
                f"The '{field}' field must be a sequence with length {size}, got {len(array)}"
            )
        elif size:
            assert len(array) <= size, f"The '{field}' field must have at most {size} elements"
        return array
    assert not isinstance(value, (str, bytes)) and hasattr(value, "__iter__"), (
        f"The '{field}' field must be a sequence"
    )
    items = list(value)
    if fixed:
        assert len(items) == size, f"The '{field}' field must be a sequence with length {size}"
    elif size:
        assert len(items) <= size, f"The '{field}' field must have at most {size} elements"
    spec_elem = (elem_kind, elem_detail)
    return [_check_field(cls_name, field, spec_elem, item) for item in items]


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
        if basetype in ("float32", "float64"):
            return 0.0
        return 0
    if kind == Nodetype.NAME:
        return get_class(detail)()
    (elem_kind, elem_detail), size = detail
    if elem_kind == Nodetype.BASE and elem_detail[0] in _DTYPES:
        return np.zeros(size if kind == Nodetype.ARRAY else 0, dtype=_DTYPES[elem_detail[0]])
    if kind == Nodetype.ARRAY:
        return [_default((elem_kind, elem_detail)) for _ in range(size)]
    return []


def _values_equal(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(np.asarray(a), np.asarray(b))
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_values_equal(x, y) for x, y in zip(a, b))
    return a == b


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
                setattr(self, name, kwargs[name])
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
        return all(_values_equal(getattr(self, n), getattr(other, n)) for n in order)

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
    """Copy of any message object (e.g. a rosbags typestore instance) as the stand-in class."""
    cls = get_class(message.__msgtype__)
    _, fields = _store().store_of(message.__msgtype__).fielddefs[message.__msgtype__]
    out = cls.__new__(cls)
    for name, spec in fields:
        object.__setattr__(out, name, _check_field(cls.__qualname__, name, spec, _plain(getattr(message, name), spec)))
    return out


def _plain(value: Any, spec: tuple) -> Any:
    # Values read from a typestore instance: byte fields come as int, turn them into bytes.
    kind, detail = spec
    if kind == Nodetype.BASE and detail[0] == "byte" and isinstance(value, int):
        return _Byte(bytes([value]))
    if kind == Nodetype.BASE and detail[0] in ("float32", "float64") and not isinstance(value, float):
        return float(value)
    if kind == Nodetype.BASE and detail[0] in _INT_RANGES and not isinstance(value, int):
        return int(value)
    if kind == Nodetype.BASE and detail[0] == "bool" and not isinstance(value, bool):
        return bool(value)
    return value


def copy_message(message: Any) -> Any:
    return copy.deepcopy(message)


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
