"""Node parameters: `ParameterError` (names the parameter and the bad value), the finger-list check,
and `Params`, the base of the nodes' parameter dataclasses (defaults, ROS parameter values, validation)."""
from __future__ import annotations

import math
from dataclasses import asdict, fields
from typing import Any, ClassVar

from .hand import FINGERS


class ParameterError(ValueError):
    """An invalid parameter; the message names the parameter and the bad value."""

    def __init__(self, name: str, value: Any, expected: str) -> None:
        super().__init__(f"invalid parameter '{name}' = {value!r}: {expected}")
        self.name, self.value = name, value


def check_fingers(fingers: list[str], name: str = "fingers") -> None:
    """A non-empty list of distinct finger names (ParameterError naming `name` otherwise)."""
    if not fingers:
        raise ParameterError(name, fingers, "at least one finger")
    for finger in fingers:
        if finger not in FINGERS:
            raise ParameterError(name, fingers, f"{finger!r} is not one of {FINGERS}")
    if len(set(fingers)) != len(fingers):
        raise ParameterError(name, fingers, "each finger at most once")


def check_positive(name: str, value: Any) -> None:
    """ParameterError naming `name` unless `value` is a finite number > 0."""
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise ParameterError(name, value, "must be a finite number > 0")


class Params:
    """Base of the parameter dataclasses below."""

    __dataclass_fields__: ClassVar[dict[str, Any]]  # (each subclass is a dataclass)

    def validate(self) -> None:
        """Check the values; raise ParameterError naming the first bad one."""
        raise NotImplementedError

    def as_parameters(self) -> dict:
        """name -> default value, in the types ROS parameters take (lists, not tuples)."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}

    @classmethod
    def from_parameters(cls, values: dict):
        known = {f.name for f in fields(cls)}
        unknown = set(values) - known
        if unknown:
            raise ValueError(f"unknown parameter(s) {sorted(unknown)}")
        converted = {}
        for f in fields(cls):
            if f.name in values:
                value = values[f.name]
                default = getattr(cls(), f.name)
                if isinstance(default, list) or isinstance(default, tuple):
                    value = list(value)
                elif isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
                    value = float(value)
                converted[f.name] = value
        config = cls(**converted)
        config.validate()
        return config
