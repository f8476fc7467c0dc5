"""Judging a node's run-time parameter changes (its on-set-parameters callback)."""

from typing import Any, Callable, Mapping, Optional, Sequence

from rcl_interfaces.msg import SetParametersResult
from rclpy.exceptions import ParameterUninitializedException

from .parameters import check_value


def _current_value(node: Any, name: str) -> Any:
    """Return a parameter's value; None while declared by type only (parameters.declare)."""
    try:
        return node.get_parameter(name).value
    except ParameterUninitializedException:
        return None


def check_parameters(node: Any, specs: Mapping[str, Any], parameters: Sequence[Any],
                     check: Callable[[str, Any, Mapping[str, Any]], Optional[str]] = check_value
                     ) -> SetParametersResult:
    """
    Judge a parameter change of ``node`` (an on-set-parameters callback's work).

    ``check(name, value, others)`` gives the reason to reject a value (None: accept), with
    the others as they would be after the change; descriptors have already checked
    read-only and ranges.
    """
    values = {name: _current_value(node, name) for name in specs if node.has_parameter(name)}
    values.update({parameter.name: parameter.value for parameter in parameters})
    for parameter in parameters:
        reason = check(parameter.name, parameter.value, values)
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
    return SetParametersResult(successful=True)
