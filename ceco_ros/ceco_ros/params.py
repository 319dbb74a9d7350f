"""Parameter declaration with full descriptors (unit in the description, declared ranges, choices).

Used by every node's ``_read_config``; a ValueError names the parameter.
"""
from __future__ import annotations

import math
from typing import Any, Sequence

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

__all__ = ['declare']


def declare(node, name: str, default: Any, description: str, *,
            float_range: tuple[float, float] | None = None,
            int_range: tuple[int, int] | None = None,
            choices: Sequence[str] | None = None,
            read_only: bool = True) -> Any:
    """Declare one parameter with a full descriptor and return its value.

    `description` carries the unit; `float_range`/`int_range` become the
    descriptor's range (rclpy rejects an out-of-range value at declaration,
    with a message naming the parameter). `choices` is checked here.
    Raises ValueError with the parameter name on any invalid value.
    """
    desc = ParameterDescriptor(name=name, description=description, read_only=read_only)
    if float_range is not None:
        desc.floating_point_range = [FloatingPointRange(
            from_value=float(float_range[0]), to_value=float(float_range[1]), step=0.0)]
        desc.additional_constraints = f'{float_range[0]} <= {name} <= {float_range[1]}'
    if int_range is not None:
        desc.integer_range = [IntegerRange(
            from_value=int(int_range[0]), to_value=int(int_range[1]), step=1)]
        desc.additional_constraints = f'{int_range[0]} <= {name} <= {int_range[1]}'
    if choices is not None:
        desc.additional_constraints = f'one of {", ".join(choices)}'
    try:
        value = node.declare_parameter(name, default, desc).value
    except Exception as err:  # rclpy: InvalidParameterValueException, type errors
        raise ValueError(f'invalid parameter {name}: {err}') from None
    if isinstance(default, float):
        if isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if not isinstance(value, float) or not math.isfinite(value):
            raise ValueError(f'invalid parameter {name}={value!r}: must be a finite number')
    if float_range is not None and not float_range[0] <= value <= float_range[1]:
        raise ValueError(f'invalid parameter {name}={value!r}: must lie in '
                         f'[{float_range[0]}, {float_range[1]}]')
    if int_range is not None and not int_range[0] <= value <= int_range[1]:
        raise ValueError(f'invalid parameter {name}={value!r}: must lie in '
                         f'[{int_range[0]}, {int_range[1]}]')
    if choices is not None and value not in choices:
        raise ValueError(f'invalid parameter {name}={value!r}: must be one of '
                         f'{", ".join(choices)}')
    return value
