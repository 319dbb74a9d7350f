"""The lint of ceco_core under colcon test (ceco_lint: ruff, ament_pep257, package.xml against the imports)."""

from pathlib import Path

import pytest

from ceco_lint import pep257_errors, ruff_errors, undeclared_imports

PKG = Path(__file__).resolve().parents[1]


@pytest.mark.linter
@pytest.mark.parametrize('check', [ruff_errors, pep257_errors, undeclared_imports], ids=lambda f: f.__name__)
def test_lint(check):
    errors = check(PKG)
    assert errors == [], '\n'.join(errors)
