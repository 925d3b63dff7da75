"""A node's ROS parameters from its config dataclass (prisma_common.parameters.Params): declared with
ParameterDescriptors built from the fields' specs, validated by the config class at start, and,
for the parameters the spec marks live, changed at run time through the same validation.

    self.config = declare_config(self, MyNodeConfig)           # at start: ParameterError if invalid
    accept_live_changes(self, MyNodeConfig, self._reconfigure)  # only if some parameter is live

What `ros2 param describe` then prints (and rqt_reconfigure shows) for each parameter: the spec's
description with its unit, a FloatingPointRange (step 0: continuous) or IntegerRange (step 1) from
its bounds, the choices, an excluded end of the range and the rules in additional_constraints, and
read_only unless the spec says live. rclpy enforces the range and read_only on every set; the
config class checks the rest (an excluded end, the choices, relations between parameters).
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter

from prisma_common.parameters import ParameterError, ParameterSpec, Params

ConfigT = TypeVar("ConfigT", bound=Params)


def parameter_descriptor(name: str, spec: ParameterSpec, default: Any) -> ParameterDescriptor:
    """The descriptor of parameter `name` whose spec is `spec` and default `default` (the type is
    the default's, as rclpy infers it at declaration)."""
    description = f"{spec.description} [{spec.unit}]" if spec.unit else spec.description
    descriptor = ParameterDescriptor(name=name, description=description,
                                     additional_constraints=spec.constraints(), read_only=not spec.live)
    if spec.bounds is not None:
        low, high = spec.bounds
        if isinstance(default, float):
            descriptor.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(high),
                                                                  step=0.0)]
        else:
            descriptor.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
    return descriptor


def declare_config(node: Node, config_class: type[ConfigT]) -> ConfigT:
    """Declare every parameter of `config_class` on `node`, described, and return the config the
    node's parameter values make; ParameterError (naming the parameter and the value) for an invalid
    one, whether rclpy's range check or the config class refuses it."""
    specs = config_class.parameter_specs()
    defaults = config_class().as_parameters()
    for name, default in defaults.items():
        try:
            node.declare_parameter(name, default, parameter_descriptor(name, specs[name], default))
        except (InvalidParameterValueException, InvalidParameterTypeException) as exc:
            # the override is out of the range or of another type: name it as the config check does
            value = node.declare_parameter(name, default, ParameterDescriptor(dynamic_typing=True)).value
            if Parameter.Type.from_parameter_value(value) != Parameter.Type.from_parameter_value(default):
                raise ParameterError(name, value, f"must be of type {type(default).__name__}, as its default "
                                                  f"{default!r}") from None
            specs[name].check(name, value, default)
            raise ParameterError(name, value, str(exc)) from None
    return config_class.from_parameters({name: node.get_parameter(name).value for name in defaults})


def accept_live_changes(node: Node, config_class: type[ConfigT],
                        apply: Callable[[ConfigT], None]) -> None:
    """Let the live parameters of `config_class` change while `node` runs: a change is checked as at
    start (the config class validates the node's values with it) and refused with the config's
    message, or the new config is passed to `apply` and the change logged. rclpy itself refuses the
    read-only parameters and values outside a range before this check."""
    names = set(config_class.parameter_specs())

    def on_set(parameters: list[Parameter]) -> SetParametersResult:
        changes = {p.name: p.value for p in parameters if p.name in names}  # not rclpy's own (use_sim_time)
        if not changes:
            return SetParametersResult(successful=True)
        values = {name: node.get_parameter(name).value for name in names}
        values.update(changes)
        try:
            config = config_class.from_parameters(values)
        except ParameterError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        apply(config)
        for name, value in changes.items():
            node.get_logger().info(f"parameter {name} = {value!r}")
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(on_set)
