"""Node parameters: `ParameterError` (names the parameter and the bad value), the finger-list check,
and `Params`, the base of the nodes' parameter dataclasses.

One source of truth per parameter: each field of a node's config dataclass is declared with
`parameter(default, description, unit=, bounds=, choices=, live=)`, which puts a `ParameterSpec` in
the field's metadata. `Params.validate()` checks every value against its spec (type, bounds, choices)
before the config's own `check_rules()` (list contents, relations between parameters), and the
nodes' rclpy wiring (`prisma_node_wiring.node_parameters`) turns the same specs into the
ParameterDescriptors `ros2 param describe` and rqt_reconfigure show: description and unit, a
FloatingPointRange / IntegerRange from `bounds`, the choices and open ends in
`additional_constraints`, and `read_only` unless `live`. Plain data here, no ROS.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar, TypeVar

from .hand import FINGERS

SPEC = "prisma_parameter"  # dataclass field metadata key of a ParameterSpec


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


@dataclass(frozen=True)
class ParameterSpec:
    """What a parameter is and which values it takes: the one place its description, unit, bounds,
    choices and run-time changeability are written."""

    description: str  # one line, what the value does
    unit: str = ""  # SI unit ("s", "N", "rad", "rpm", "Hz", "V"), "" for counts and names
    bounds: tuple[float, float] | None = None  # numeric parameters: lowest and highest value
    open_low: bool = False  # the lowest value itself is excluded (e.g. a period: > 0)
    open_high: bool = False
    choices: tuple[str, ...] = ()  # string parameters that name one of a fixed set
    live: bool = False  # may change while the node runs (else read-only after start)
    rules: str = ""  # in words, what bounds and choices cannot say (list contents, other parameters)

    def __post_init__(self) -> None:
        if self.bounds is not None and not self.bounds[0] < self.bounds[1]:
            raise ValueError(f"bounds {self.bounds}: the low end must be below the high end")

    def interval(self) -> str:
        """The bounds as an interval, `(0.0, 1.5]`; "" without bounds."""
        if self.bounds is None:
            return ""
        low, high = self.bounds
        return f"{'(' if self.open_low else '['}{low}, {high}{')' if self.open_high else ']'}"

    def constraints(self) -> str:
        """What a ParameterDescriptor's ranges cannot carry, in words: the choices, an excluded end
        of the range, the rules."""
        parts = []
        if self.choices:
            parts.append(f"one of: {', '.join(self.choices)}")
        if self.open_low or self.open_high:
            parts.append(f"in {self.interval()}")
        if self.rules:
            parts.append(self.rules)
        return "; ".join(parts)

    def check(self, name: str, value: Any, default: Any) -> None:
        """ParameterError naming `name` unless `value` has the type of `default` (a float parameter
        also takes an int), lies within the bounds and is one of the choices."""
        if isinstance(default, bool):
            if not isinstance(value, bool):
                raise ParameterError(name, value, "must be true or false")
        elif isinstance(default, int):
            if isinstance(value, bool) or not isinstance(value, int):
                raise ParameterError(name, value, "must be an integer")
        elif isinstance(default, float):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ParameterError(name, value, "must be a finite number")
        elif isinstance(default, str):
            if not isinstance(value, str):
                raise ParameterError(name, value, "must be a string")
        elif isinstance(default, list) and not isinstance(value, (list, tuple)):
            raise ParameterError(name, value, "must be a list")
        if self.bounds is not None:
            low, high = self.bounds
            below = value <= low if self.open_low else value < low
            above = value >= high if self.open_high else value > high
            if below or above:
                raise ParameterError(name, value, f"must be {'>' if self.open_low else '>='} {low} "
                                                  f"and {'<' if self.open_high else '<='} {high}")
        if self.choices and value not in self.choices:
            raise ParameterError(name, value, f"expected one of {'|'.join(self.choices)}")


def parameter(default: Any, description: str, *, unit: str = "", bounds: tuple[float, float] | None = None,
              open_low: bool = False, open_high: bool = False, choices: tuple[str, ...] | list[str] = (),
              live: bool = False, rules: str = "") -> Any:
    """A config dataclass field: its default and its ParameterSpec (see the module docstring)."""
    spec = ParameterSpec(description, unit, bounds, open_low, open_high, tuple(choices), live, rules)
    if spec.bounds is not None and not isinstance(default, (int, float)):
        raise TypeError(f"bounds on a {type(default).__name__} parameter: only numbers have a range")
    metadata = {SPEC: spec}
    if isinstance(default, (list, dict)):
        return field(default_factory=lambda: copy.deepcopy(default), metadata=metadata)
    return field(default=default, metadata=metadata)


def backoff_initial(default: float, lost: str) -> Any:
    """The `reconnect_backoff_initial` field of a driver that reopens a lost port or bus (`lost`):
    the first wait, doubled after each failed reopen up to `reconnect_backoff_max`."""
    return parameter(default, f"wait before reopening a lost {lost}, doubled after each failure", unit="s",
                     bounds=(0.0, 60.0), open_low=True)


def backoff_max(default: float) -> Any:
    """The `reconnect_backoff_max` field beside `reconnect_backoff_initial`; its rule is
    `check_backoff`."""
    return parameter(default, "longest wait between reopening attempts", unit="s", bounds=(0.0, 600.0),
                     open_low=True, rules="at least reconnect_backoff_initial")


def check_backoff(initial: float, maximum: float) -> None:
    """The backoff doubles from `initial` up to `maximum`: ParameterError when it could not start."""
    if maximum < initial:
        raise ParameterError("reconnect_backoff_max", maximum, f"must be >= reconnect_backoff_initial ({initial})")


ParamsT = TypeVar("ParamsT", bound="Params")


class Params:
    """Base of the node parameter dataclasses: ROS parameter names and values, the specs, validation."""

    __dataclass_fields__: ClassVar[dict[str, Any]]  # (each subclass is a dataclass)

    @classmethod
    def parameter_specs(cls) -> dict[str, ParameterSpec]:
        """ROS parameter name -> its spec, in declaration order (one per field)."""
        specs = {}
        for f in fields(cls):
            if SPEC not in f.metadata:
                raise TypeError(f"{cls.__name__}.{f.name} is declared without parameter(...): no description")
            specs[f.name] = f.metadata[SPEC]
        return specs

    @classmethod
    def live_parameters(cls) -> list[str]:
        """The parameters that may change while the node runs."""
        return [name for name, spec in cls.parameter_specs().items() if spec.live]

    def as_parameters(self) -> dict[str, Any]:
        """ROS parameter name -> value, in the types ROS parameters take (lists, not tuples)."""
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v) for f in fields(self)}

    @classmethod
    def from_parameters(cls: type[ParamsT], values: dict[str, Any]) -> ParamsT:
        """The validated config with `values` (ROS parameter name -> value) over the defaults;
        ParameterError naming the first bad or unknown one."""
        defaults = cls().as_parameters()
        unknown = sorted(set(values) - set(defaults))
        if unknown:
            raise ParameterError(unknown[0], values[unknown[0]], f"not a parameter of {cls.__name__}")
        return cls._from_flat({name: _plain(defaults[name], value) for name, value in values.items()}).validate()

    @classmethod
    def _from_flat(cls: type[ParamsT], values: dict[str, Any]) -> ParamsT:
        """The config holding `values` (ROS names, plain values); a config whose parameters are not
        its fields one to one overrides this and `as_parameters`."""
        return cls(**values)

    def validate(self: ParamsT) -> ParamsT:
        """Check every value against its spec, then the config's own rules; ParameterError naming
        the first bad one. Returns the config."""
        specs = self.parameter_specs()
        defaults = type(self)().as_parameters()
        for name, value in self.as_parameters().items():
            specs[name].check(name, value, defaults[name])
        self.check_rules()
        return self

    def check_rules(self) -> None:
        """What the specs cannot say (list contents, patterns, relations between parameters):
        ParameterError naming the parameter. Nothing by default."""


def _plain(default: Any, value: Any) -> Any:
    """A ROS parameter value in the type of the config field: rclpy hands integer and double arrays
    over as array.array, and a float parameter may have been given as an integer."""
    if isinstance(default, list) and not isinstance(value, (str, bytes)) and hasattr(value, "__iter__"):
        return list(value)
    if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value
