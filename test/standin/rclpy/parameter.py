"""rclpy.parameter: Parameter with Parameter.Type, as in Jazzy."""
from __future__ import annotations

import array
from enum import Enum
from typing import Any


class Parameter:
    class Type(Enum):
        NOT_SET = 0
        BOOL = 1
        INTEGER = 2
        DOUBLE = 3
        STRING = 4
        BYTE_ARRAY = 5
        BOOL_ARRAY = 6
        INTEGER_ARRAY = 7
        DOUBLE_ARRAY = 8
        STRING_ARRAY = 9

        @classmethod
        def from_parameter_value(cls, parameter_value: Any) -> "Parameter.Type":
            # Same inference as rclpy, including its quirk: an empty list is a BYTE_ARRAY.
            if parameter_value is None:
                return cls.NOT_SET
            if isinstance(parameter_value, bool):
                return cls.BOOL
            if isinstance(parameter_value, int):
                return cls.INTEGER
            if isinstance(parameter_value, float):
                return cls.DOUBLE
            if isinstance(parameter_value, str):
                return cls.STRING
            if isinstance(parameter_value, (list, tuple, array.array)):
                if all(isinstance(v, bytes) for v in parameter_value):
                    return cls.BYTE_ARRAY
                if all(isinstance(v, bool) for v in parameter_value):
                    return cls.BOOL_ARRAY
                if all(isinstance(v, int) for v in parameter_value):
                    return cls.INTEGER_ARRAY
                if all(isinstance(v, float) for v in parameter_value):
                    return cls.DOUBLE_ARRAY
                if all(isinstance(v, str) for v in parameter_value):
                    return cls.STRING_ARRAY
                raise TypeError(f"The given value is not a list of one of the allowed types '{parameter_value}'.")
            raise TypeError(f"The given value is not one of the allowed types '{parameter_value}'.")

        def check(self, parameter_value: Any) -> bool:
            if self == Parameter.Type.NOT_SET:
                return parameter_value is None
            if self == Parameter.Type.BOOL:
                return isinstance(parameter_value, bool)
            if self == Parameter.Type.INTEGER:
                return isinstance(parameter_value, int) and not isinstance(parameter_value, bool)
            if self == Parameter.Type.DOUBLE:
                return isinstance(parameter_value, float)
            if self == Parameter.Type.STRING:
                return isinstance(parameter_value, str)
            if not isinstance(parameter_value, (list, tuple, array.array)):
                return False
            element = {
                Parameter.Type.BYTE_ARRAY: bytes,
                Parameter.Type.BOOL_ARRAY: bool,
                Parameter.Type.INTEGER_ARRAY: int,
                Parameter.Type.DOUBLE_ARRAY: float,
                Parameter.Type.STRING_ARRAY: str,
            }[self]
            return all(isinstance(v, element) for v in parameter_value)

    @classmethod
    def from_parameter_msg(cls, param_msg) -> "Parameter":
        return cls(param_msg.name, value=parameter_value_to_python(param_msg.value))

    def __init__(self, name: str, type_: "Parameter.Type | None" = None, value: Any = None) -> None:
        if type_ is None:
            type_ = Parameter.Type.from_parameter_value(value)
        if not isinstance(type_, Parameter.Type):
            raise TypeError("type must be an instance of '{}'".format(repr(Parameter.Type)))
        if not type_.check(value):
            raise ValueError(f"Type '{type_}' and value '{value}' do not agree")
        self._type_ = type_
        self._name = name
        self._value = value

    @property
    def name(self) -> str:
        return self._name

    @property
    def type_(self) -> "Parameter.Type":
        return self._type_

    @property
    def value(self) -> Any:
        return self._value

    def get_parameter_value(self):
        from rcl_interfaces.msg import ParameterValue

        msg = ParameterValue(type=self.type_.value)
        field = {
            Parameter.Type.BOOL: "bool_value",
            Parameter.Type.INTEGER: "integer_value",
            Parameter.Type.DOUBLE: "double_value",
            Parameter.Type.STRING: "string_value",
            Parameter.Type.BYTE_ARRAY: "byte_array_value",
            Parameter.Type.BOOL_ARRAY: "bool_array_value",
            Parameter.Type.INTEGER_ARRAY: "integer_array_value",
            Parameter.Type.DOUBLE_ARRAY: "double_array_value",
            Parameter.Type.STRING_ARRAY: "string_array_value",
        }.get(self.type_)
        if field is not None:
            value = self.value
            if self.type_ == Parameter.Type.BYTE_ARRAY:
                value = [b[0] for b in value]
            setattr(msg, field, value)
        return msg

    def to_parameter_msg(self):
        from rcl_interfaces.msg import Parameter as ParameterMsg

        return ParameterMsg(name=self.name, value=self.get_parameter_value())

    def __repr__(self) -> str:
        return f"Parameter(name={self.name!r}, type_={self.type_}, value={self.value!r})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Parameter):
            return NotImplemented
        return (self.name, self.type_, self.value) == (other.name, other.type_, other.value)


def parameter_value_to_python(parameter_value) -> Any:
    kind = Parameter.Type(parameter_value.type)
    if kind == Parameter.Type.NOT_SET:
        return None
    if kind == Parameter.Type.BOOL:
        return parameter_value.bool_value
    if kind == Parameter.Type.INTEGER:
        return parameter_value.integer_value
    if kind == Parameter.Type.DOUBLE:
        return parameter_value.double_value
    if kind == Parameter.Type.STRING:
        return parameter_value.string_value
    if kind == Parameter.Type.BYTE_ARRAY:
        return [bytes([int(b)]) for b in parameter_value.byte_array_value]
    if kind == Parameter.Type.BOOL_ARRAY:
        return [bool(v) for v in parameter_value.bool_array_value]
    if kind == Parameter.Type.INTEGER_ARRAY:
        return [int(v) for v in parameter_value.integer_array_value]
    if kind == Parameter.Type.DOUBLE_ARRAY:
        return [float(v) for v in parameter_value.double_array_value]
    return list(parameter_value.string_array_value)


PARAMETER_SEPARATOR_STRING = "."
