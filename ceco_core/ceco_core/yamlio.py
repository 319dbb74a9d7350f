"""YAML documents read with libyaml's safe loader when PyYAML has it (10x faster), else PyYAML's own.

The frozen benchmark files and the model parameter files are read on every run; ``CSafeLoader`` builds the
same Python objects as ``SafeLoader`` (baselines.yaml 158 -> 15 ms, the model's parameters 6.4 -> 0.75 ms).
"""

from __future__ import annotations

import yaml

__all__ = ["safe_load"]

_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def safe_load(stream):
    """``yaml.safe_load`` of a string or an open file, with libyaml where available."""
    return yaml.load(stream, Loader=_LOADER)
