"""Field overrides of frozen parameter dataclasses, nested parts by dotted name.

``with_overrides(ComfortParams(), {"air.jet_body_fraction": 0.2, "solar.f_bes": 0.75})``
returns a copy with those fields replaced (the nested ``OccupantAirParams`` and
``SolarParams`` copied with theirs) and validated. Used for the sensitivity runs of
the benchmark (the simulated car's comfort model and plant, ``SimSettings.comfort_overrides``
/ ``plant_overrides``). Every error is a ValueError naming the field.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

__all__ = ["with_overrides", "check_overrides"]


def _fields(obj) -> dict:
    return {f.name: f for f in dataclasses.fields(obj)}


def _check_value(owner: str, name: str, old, value):
    if isinstance(old, bool):
        if not isinstance(value, bool):
            raise ValueError(f"{owner}.{name} must be a bool, got {value!r}")
        return value
    if isinstance(old, (int, float)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ValueError(f"{owner}.{name} must be a finite number, got {value!r}")
        return type(old)(value) if isinstance(old, float) else value
    if dataclasses.is_dataclass(old):
        raise ValueError(
            f"{owner}.{name} is a {type(old).__name__}: override its fields by dotted name "
            f"({name}.<field>), not the whole part"
        )
    raise ValueError(f"{owner}.{name}: a field of type {type(old).__name__} cannot be overridden")


def with_overrides(obj, overrides: Mapping | None, *, owner: str | None = None):
    """Copy of the frozen dataclass ``obj`` with ``overrides`` = ``{"field" or "part.field": value}``.

    Numbers replace numbers (finite; ints stay ints, floats become floats), bools replace bools;
    a nested dataclass is changed field by field (``"air.jet_body_fraction"``), never replaced whole.
    The result is validated (its ``validate()``, which checks the nested parts too). Raises
    ValueError naming the field (``ComfortParams.air.jet_body_fraction ...``) for an unknown field,
    a wrong type or a value its ``validate()`` rejects.
    """
    owner = owner or type(obj).__name__
    if not overrides:
        return obj
    if not isinstance(overrides, Mapping):
        raise ValueError(f"{owner} overrides must be a mapping of field names to values, got {overrides!r}")
    new = _replace(obj, overrides, owner)
    validate = getattr(new, "validate", None)
    if validate is not None:
        try:
            validate()
        except ValueError as exc:
            raise ValueError(f"{owner} with overrides {dict(overrides)}: {exc}") from exc
    return new


def _replace(obj, overrides: Mapping, owner: str):
    fields = _fields(obj)
    own: dict = {}
    nested: dict = {}
    for key, value in overrides.items():
        if not isinstance(key, str) or not key:
            raise ValueError(f"{owner}: override names must be non-empty strings, got {key!r}")
        head, _, rest = key.partition(".")
        if head not in fields:
            raise ValueError(f"{owner}.{head}: no such field (fields: {', '.join(sorted(fields))})")
        old = getattr(obj, head)
        if rest:
            if not dataclasses.is_dataclass(old):
                raise ValueError(f"{owner}.{key}: {owner}.{head} is a {type(old).__name__}, not a part with fields")
            nested.setdefault(head, {})[rest] = value
        else:
            own[head] = _check_value(owner, head, old, value)
    for head, sub in nested.items():
        own[head] = _replace(getattr(obj, head), sub, f"{owner}.{head}")
    return dataclasses.replace(obj, **own)


def check_overrides(obj, overrides: Mapping | None, *, owner: str | None = None) -> None:
    """Raise ValueError naming the field if ``with_overrides(obj, overrides)`` would fail."""
    with_overrides(obj, overrides, owner=owner)
