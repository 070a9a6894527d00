"""Declaring a node's parameters: each with a description, read-only unless told, with
the range it is judged against in its descriptor; what the node was given but does not
declare reported as ignored."""
from __future__ import annotations

import math

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.parameter import Parameter

from ..contract import INT64_MAX, INT64_MIN


class DeclaredParameters:
    """Mixin of an rclpy Node: `parameter` declares one and returns its value."""

    def parameter(self, name: str, default, description: str, read_only: bool = True,
                  value_range: tuple[float | None, float | None] | None = None,
                  constraints: str = ''):
        """Declare one parameter, read-only unless told; its value. Typed as given (the
        node's loaders judge the value, naming the parameter), an integer given for a
        number taken as that number; typed as `default` when not given. `value_range`
        (low, high; None: unbounded) becomes the descriptor's integer or floating-point
        range, as the value is typed; `constraints` says it in words."""
        if self.has_parameter(name):
            return self.get_parameter(name).value
        value = self.given_value(name, default)
        # A changeable one takes what `ros2 param set` sends (5 for 5.0): the change's
        # callback judges the value.
        descriptor = ParameterDescriptor(description=description, read_only=read_only,
                                         dynamic_typing=not read_only,
                                         additional_constraints=constraints)
        if value_range is not None and not isinstance(value, bool):
            low, high = value_range
            if isinstance(value, int):
                descriptor.integer_range = [IntegerRange(
                    from_value=INT64_MIN if low is None else math.ceil(low),
                    to_value=INT64_MAX if high is None else math.floor(high), step=1)]
            elif isinstance(value, float):
                descriptor.floating_point_range = [FloatingPointRange(
                    from_value=-math.inf if low is None else float(low),
                    to_value=math.inf if high is None else float(high), step=0.0)]
        return self.declare_parameter(name, value, descriptor).value

    def given_value(self, name: str, default):
        """What the command line gave for `name` (an integer given for a number taken as
        that number), else `default`; declares nothing."""
        given = self._parameter_overrides.get(name)   # rclpy keeps what --ros-args gave here
        if given is None:
            return default
        if isinstance(default, float) and given.type_ == Parameter.Type.INTEGER:
            given = Parameter(name, Parameter.Type.DOUBLE, float(given.value))
            self._parameter_overrides[name] = given
        return given.value

    def given_parameters(self) -> dict:
        """Name → value of every parameter this node was started with (--ros-args)."""
        return {name: parameter.value for name, parameter in self._parameter_overrides.items()}

    def ignored_parameters(self) -> list[str]:
        """The parameters the node was given but does not have (a misspelt name)."""
        return sorted(name for name in self._parameter_overrides if not self.has_parameter(name))
