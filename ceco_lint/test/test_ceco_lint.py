"""ceco_lint's checks on small packages written here, and on itself."""

import tomllib
from pathlib import Path

from ceco_lint import PEP257_IGNORE, pep257_errors, ruff_errors, undeclared_imports

PKG = Path(__file__).resolve().parents[1]
MANIFEST = """<?xml version="1.0"?>
<package format="3">
  <name>demo_pkg</name>
  <exec_depend>rclpy</exec_depend>
  <exec_depend>python3-numpy</exec_depend>
  <test_depend>python3-pytest</test_depend>
  <export><build_type>ament_python</build_type><ceco_optional_imports>fastsim</ceco_optional_imports></export>
</package>
"""


def _package(tmp_path, module: str, test: str = '') -> Path:
    pkg = tmp_path / 'demo_pkg'
    (pkg / 'demo_pkg').mkdir(parents=True)
    (pkg / 'test').mkdir()
    (pkg / 'package.xml').write_text(MANIFEST)
    (pkg / 'demo_pkg' / '__init__.py').write_text(module)
    (pkg / 'test' / 'test_demo.py').write_text(test)
    return pkg


def test_declared_imports_pass_and_each_missing_key_is_named(tmp_path):
    clean = 'import os\nimport numpy\nfrom rclpy.node import Node\nfrom demo_pkg import x\n'
    assert undeclared_imports(_package(tmp_path / 'a', clean, 'import pytest\n')) == []
    bad = clean + 'import yaml\nfrom lifecycle_msgs.msg import State\n'
    assert undeclared_imports(_package(tmp_path / 'b', bad, 'import pytest\nimport scipy\n')) == [
        'demo_pkg/__init__.py: imports yaml: package.xml lacks <exec_depend>python3-yaml</exec_depend>',
        'demo_pkg/__init__.py: imports lifecycle_msgs: package.xml lacks <exec_depend>lifecycle_msgs</exec_depend>',
        'test/test_demo.py: imports scipy: package.xml lacks <test_depend>python3-scipy</test_depend>',
    ]
    # pytest is a test dependency only
    assert undeclared_imports(_package(tmp_path / 'c', 'import pytest\n')) == [
        'demo_pkg/__init__.py: imports pytest: package.xml lacks <exec_depend>python3-pytest</exec_depend>'
    ]


def test_an_optional_import_must_be_guarded(tmp_path):
    guarded = 'def f():\n    import fastsim\n\n\ntry:\n    import fastsim\nexcept ImportError:\n    pass\n'
    assert undeclared_imports(_package(tmp_path / 'a', guarded)) == []
    assert undeclared_imports(_package(tmp_path / 'b', 'import fastsim\n')) == [
        'demo_pkg/__init__.py: optional fastsim imported at module level outside a try'
    ]


def test_pep257_and_ruff_report_findings(tmp_path):
    pkg = _package(tmp_path, 'def f():\n    """no period and lower case"""\n    return  1\n')
    found = pep257_errors(pkg)
    assert any('D415' in e or 'D400' in e for e in found), found
    assert ruff_errors(pkg), 'ruff found nothing in a badly formatted file'


def test_pep257_ignores_are_the_repository_ones():
    pyproject = tomllib.loads((PKG.parent / 'pyproject.toml').read_text())
    ruff_d = {c for c in pyproject['tool']['ruff']['lint']['ignore'] if c.startswith('D')}
    assert ruff_d <= set(PEP257_IGNORE) and set(PEP257_IGNORE) - ruff_d == {'D402', 'D403'}


def test_lint():
    assert ruff_errors(PKG) == []
    assert pep257_errors(PKG) == []
    assert undeclared_imports(PKG) == []
