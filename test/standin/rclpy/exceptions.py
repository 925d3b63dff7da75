"""rclpy.exceptions with the Jazzy class hierarchy and messages."""
from __future__ import annotations


class NotInitializedException(Exception):
    def __init__(self, *args):
        Exception.__init__(self, "rclpy.init() has not been called", *args)


class NoTypeSupportImportedException(Exception):
    pass


class NameValidationException(Exception):
    def __init__(self, name_type, name, error_msg, invalid_index, *args):
        msg = "Invalid {name_type}: {error_msg}:\n  '{name}'\n   {indent}^".format(
            name_type=name_type, name=name, error_msg=error_msg, indent=" " * invalid_index)
        Exception.__init__(self, msg)


class InvalidNamespaceException(NameValidationException):
    def __init__(self, name, error_msg, invalid_index, *args):
        NameValidationException.__init__(self, "namespace", name, error_msg, invalid_index)


class InvalidNodeNameException(NameValidationException):
    def __init__(self, name, error_msg, invalid_index, *args):
        NameValidationException.__init__(self, "node name", name, error_msg, invalid_index)


class InvalidTopicNameException(NameValidationException):
    def __init__(self, name, error_msg, invalid_index, *args):
        NameValidationException.__init__(self, "topic name", name, error_msg, invalid_index)


class InvalidServiceNameException(NameValidationException):
    def __init__(self, name, error_msg, invalid_index, *args):
        NameValidationException.__init__(self, "service name", name, error_msg, invalid_index)


class ParameterException(Exception):
    def __init__(self, error_msg, parameters, *args):
        Exception.__init__(self, f"{error_msg}: {parameters}", *args)


class ParameterNotDeclaredException(ParameterException):
    def __init__(self, parameters, *args):
        ParameterException.__init__(self, "Invalid access to undeclared parameter(s)", parameters, *args)


class ParameterAlreadyDeclaredException(ParameterException):
    def __init__(self, parameters, *args):
        ParameterException.__init__(self, "Parameter(s) already declared", parameters, *args)


class InvalidParameterException(ParameterException):
    def __init__(self, parameter, *args):
        ParameterException.__init__(self, "Invalid parameter name", parameter, *args)


class InvalidParameterTypeException(ParameterException):
    def __init__(self, desired_parameter, expected_type, *args):
        Exception.__init__(
            self,
            f"Trying to set parameter '{desired_parameter.name}' to '{desired_parameter.value}'"
            f" of type '{desired_parameter.type_.name}', expecting type '{expected_type}'",
            *args)


class InvalidParameterValueException(ParameterException):
    def __init__(self, parameter, value, reason, *args):
        Exception.__init__(
            self,
            f"Invalid parameter value ({value}) for parameter '{parameter}'. Reason: {reason}",
            *args)


class ParameterImmutableException(ParameterException):
    def __init__(self, parameter, *args):
        ParameterException.__init__(self, "Attempted to modify read-only parameter", parameter, *args)


class ParameterUninitializedException(ParameterException):
    def __init__(self, parameter_name, *args):
        Exception.__init__(self, f"The parameter '{parameter_name}' is not initialized", *args)


class ROSInterruptException(Exception):
    def __init__(self, *args):
        Exception.__init__(self, "rclpy.shutdown() has been called", *args)


class InvalidHandle(Exception):
    pass
