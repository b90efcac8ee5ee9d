"""ROS parameter descriptors built from :data:`aes_ros.params.PARAMS`.

The model parameters (gains, noise, robot limits, swarm command) are defined
once, in :mod:`aes_ros.params`; the nodes declare them through
:func:`declare_model_parameters` so that ``ros2 param describe`` shows the same
description, unit and range as ``aes-swarm params`` and the README. Parameters
that exist only in the ROS interface (``robot_id``, ``publish_rate``, …) get
their descriptors from :func:`float_descriptor`, :func:`int_descriptor` and
friends, which format descriptions the same way.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.node import Node
from rclpy.parameter import Parameter

from aes_ros import scenario as scenario_mod
from aes_ros.obstacles import format_obstacles
from aes_ros.params import PARAMS, ParameterError, ParamSpec

#: Robot limits (docs/design.md#mona).
LIMIT_NAMES = ("max_linear_speed", "max_angular_speed")

_INT64_MAX = 2**63 - 1


def _text(description: str, unit: str, allowed: str) -> str:
    unit_text = f" [{unit}]" if unit else ""
    return f"{description}{unit_text}; {allowed}"


def descriptor(spec: ParamSpec, *, read_only: bool = False) -> ParameterDescriptor:
    """ParameterDescriptor of one :class:`ParamSpec`: description with unit and range.

    Scalars get ``floating_point_range``/``integer_range`` (enforced by rclpy);
    arrays and strings state their constraint in ``additional_constraints`` and
    are checked by :func:`check` in the node's set-parameters callback.
    """
    desc = ParameterDescriptor(
        description=_text(spec.description, spec.unit, spec.allowed()), read_only=read_only
    )
    if spec.kind == "float" and spec.low is not None and spec.high is not None:
        desc.floating_point_range = [
            FloatingPointRange(from_value=float(spec.low), to_value=float(spec.high), step=0.0)
        ]
    elif spec.kind == "int" and spec.low is not None and spec.high is not None:
        desc.integer_range = [
            IntegerRange(from_value=int(spec.low), to_value=int(spec.high), step=1)
        ]
    else:
        desc.additional_constraints = spec.allowed()
    return desc


def float_descriptor(
    description: str, unit: str, low: float, high: float, *, read_only: bool = False
) -> ParameterDescriptor:
    """Descriptor of a double in [low, high]."""
    return ParameterDescriptor(
        description=_text(description, unit, f"a number in [{low:g}, {high:g}]"),
        floating_point_range=[FloatingPointRange(from_value=low, to_value=high, step=0.0)],
        read_only=read_only,
    )


def int_descriptor(
    description: str, low: int, high: int = _INT64_MAX, *, read_only: bool = False
) -> ParameterDescriptor:
    """Descriptor of an integer in [low, high]."""
    return ParameterDescriptor(
        description=_text(description, "", f"an integer in [{low}, {high}]"),
        integer_range=[IntegerRange(from_value=low, to_value=high, step=1)],
        read_only=read_only,
    )


def text_descriptor(
    description: str, choices: Iterable[str] = (), *, read_only: bool = False
) -> ParameterDescriptor:
    """Descriptor of a string, optionally one of ``choices`` (checked by the node)."""
    choices = tuple(choices)
    allowed = "one of " + ", ".join(choices) if choices else "a string"
    return ParameterDescriptor(
        description=_text(description, "", allowed),
        additional_constraints=allowed,
        read_only=read_only,
    )


def array_descriptor(description: str, unit: str, constraint: str) -> ParameterDescriptor:
    """Descriptor of an array parameter; ``constraint`` says what is allowed."""
    return ParameterDescriptor(
        description=_text(description, unit, constraint), additional_constraints=constraint
    )


def bool_descriptor(description: str, *, read_only: bool = False) -> ParameterDescriptor:
    """Descriptor of a bool."""
    return ParameterDescriptor(
        description=_text(description, "", "true or false"), read_only=read_only
    )


def to_ros_value(spec: ParamSpec, value: Any) -> Any:
    """A validated PARAMS value in the type its ROS parameter is declared with."""
    value = spec.validate(value)
    if spec.kind == "float":
        return float(value)
    if spec.kind == "vec2":
        return [float(value[0]), float(value[1])]
    if spec.kind == "obstacles":  # a string parameter, one line (aes_ros.obstacles)
        return format_obstacles(value)
    return value


def declare_model_parameters(
    node: Node, names: Iterable[str], defaults: Mapping[str, Any]
) -> dict[str, Any]:
    """Declare PARAMS entries ``names`` on ``node`` with defaults from ``defaults``.

    ``defaults`` is typically ``Scenario.values``; a ``-p name:=value`` override
    takes precedence as usual. Returns the effective values.
    """
    out = {}
    for name in names:
        spec = PARAMS[name]
        value = to_ros_value(spec, defaults.get(name, spec.default))
        out[name] = node.declare_parameter(name, value, descriptor(spec)).value
    return out


def check(parameters: Iterable[Parameter], names: Iterable[str] | None = None) -> str | None:
    """Check parameters against PARAMS; the reason of the first failure, or None.

    Only parameters whose name is in PARAMS (and in ``names`` if given) are
    checked; rclpy has already enforced type and scalar range by then, so this
    catches non-finite values and the components of arrays.
    """
    allowed = None if names is None else set(names)
    for param in parameters:
        if param.name not in PARAMS or (allowed is not None and param.name not in allowed):
            continue
        value = param.value
        if isinstance(value, float) and not math.isfinite(value):
            return f"{param.name}: {value} is not finite"
        try:
            PARAMS[param.name].validate(
                list(value) if param.type_.name.endswith("ARRAY") else value
            )
        except ParameterError as exc:
            return str(exc)
    return None


def declare_scenario(
    node: Node, scenario: scenario_mod.Scenario | None = None
) -> scenario_mod.Scenario:
    """Declare the read-only ``scenario`` and ``num_robots`` parameters; the scenario.

    ``scenario``: a setup name (linear, rotation, combined) or a YAML path;
    ``num_robots``: 0 = the scenario's own formation, n > 0 = an n-robot grid.
    Returns ``scenario`` if given (a host that already loaded it), otherwise
    the one the parameters name. Raises ParameterError if it cannot be loaded.
    """
    name = node.declare_parameter(
        "scenario",
        "combined",
        text_descriptor(
            "scenario: a setup name (linear, rotation, combined) or a YAML file path; "
            "gives the formation, the sheet and default gains (read at start)",
            read_only=True,
        ),
    ).value
    n = node.declare_parameter(
        "num_robots",
        0,
        int_descriptor(
            "number of robots: 0 = the scenario's formation, n > 0 = an n-robot grid "
            "(read at start)",
            0,
            100_000,
            read_only=True,
        ),
    ).value
    return scenario if scenario is not None else load_scenario(name, n)


def load_scenario(name: str, num_robots: int) -> scenario_mod.Scenario:
    """The scenario ``name`` (setup or path), on ``num_robots`` robots if > 0."""
    scen = scenario_mod.load(name)
    return scen.with_robots(num_robots) if num_robots > 0 else scen


def guard_parameters(
    node: Node,
    check: Callable[[dict[str, Any]], str | None],
    apply: Callable[[], None],
) -> None:
    """Reject bad parameter sets of ``node`` with a reason; ``apply`` good ones.

    ``check(updates)`` returns why the node's parameters with ``updates`` applied
    are invalid, or None (rclpy has already checked types and the descriptors'
    ranges; this is for the cross-field rules). It is first run on the declared
    values: a bad start raises ParameterError. A rejected set leaves every value
    as it was; after an accepted one, ``apply()`` reads the parameters again.
    """
    reason = check({})
    if reason is not None:
        raise ParameterError(reason)

    def on_set(params: list[Parameter]) -> SetParametersResult:
        reason = check({p.name: p.value for p in params})
        return SetParametersResult(successful=reason is None, reason=reason or "")

    node.add_on_set_parameters_callback(on_set)
    node.add_post_set_parameters_callback(lambda _params: apply())


def choice_error(name: str, value: Any, choices: Iterable[str]) -> str | None:
    """The reason why ``value`` of parameter ``name`` is not one of ``choices``, or None."""
    choices = tuple(choices)
    if value in choices:
        return None
    return f"{name}: {value!r} is not one of {', '.join(choices)}"
