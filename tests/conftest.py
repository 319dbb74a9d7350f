"""Shared pytest set-up: tests of an optional extra skip (with the reason) when it is missing.

``@pytest.mark.extra("fastsim")`` marks a test that needs an optional package
(requirements/analysis.txt: fastsim, ray and what they pull in, e.g. polars).
Without it the test is skipped and says which extra to install; with
``CECO_REQUIRE_EXTRAS=1`` (set by .ci/run, where every extra is installed) a
missing extra fails the test instead, so CI cannot pass by skipping.
"""

import importlib
import os

import pytest


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "extra(module): needs the optional package `module` (requirements/analysis.txt); skipped without it"
    )


def pytest_runtest_setup(item):
    for mark in item.iter_markers(name="extra"):
        for module in mark.args:
            try:
                importlib.import_module(module)
            except ImportError as exc:
                if os.environ.get("CECO_REQUIRE_EXTRAS") == "1":
                    pytest.fail(f"optional extra {module!r} is required here (CECO_REQUIRE_EXTRAS=1): {exc}")
                pytest.skip(f"needs the optional extra {module!r}: pip install -r requirements/analysis.txt")
