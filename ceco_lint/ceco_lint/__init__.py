"""The lint every ceco package runs under ``colcon test`` (ament_lint_common's role for ceco).

A package's ``test/test_lint.py`` calls the three checks on its own directory:

* :func:`ruff_errors`: ``ruff check`` and ``ruff format --check`` with the repository's rules
  (pyproject.toml: pyflakes, pycodestyle, isort, bugbear, pyupgrade, numpy, pydocstyle).
* :func:`pep257_errors`: the ROS linter ament_pep257 (pydocstyle) with the Google convention the
  repository writes its docstrings in.
* :func:`undeclared_imports`: every module the package imports (its modules, launch files and
  tests) is declared in its package.xml by the rosdep key that installs it; imports a package makes
  only when present are listed in ``<export><ceco_optional_imports>`` and are never imported at
  module level outside a ``try``.

Each returns a list of error lines (empty: clean). Pure Python; ruff and ament_pep257 are imported
only when their check runs.
"""

from __future__ import annotations

import ast
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

__all__ = ['PEP257_IGNORE', 'ROSDEP_KEYS', 'pep257_errors', 'ruff_errors', 'undeclared_imports']

PEP257_IGNORE = ('D105', 'D107', 'D203', 'D213', 'D401', 'D402', 'D403', 'D406', 'D407', 'D413')
"""pydocstyle codes ament_pep257 ignores here: the pydocstyle ignores of pyproject.toml's ruff
section, plus D402/D403, whose heuristics misread acronyms ('QoS', 'NaN') and methods named
after a word of their summary."""

ROSDEP_KEYS = {
    'casadi': 'casadi-pip',
    'jsonschema': 'python3-jsonschema',
    'matplotlib': 'python3-matplotlib',
    'numpy': 'python3-numpy',
    'pytest': 'python3-pytest',
    'rosbags': 'python3-rosbags-pip',
    'ruamel': 'python3-ruamel.yaml',
    'scipy': 'python3-scipy',
    'tqdm': 'python3-tqdm',
    'yaml': 'python3-yaml',
    'cryptography': 'python3-cryptography',
    'hypothesis': 'python3-hypothesis',
}
"""Top-level module -> rosdep key (ros/rosdistro rosdep/python.yaml) where they differ; a ROS
package's module (rclpy, std_msgs, ...) is its own key."""

UNDECLARED_OK = {
    'ruff': 'requirements/test.txt (pip)',
    'pythermalcomfort': 'requirements/test.txt (pip; the PMV reference of the tests)',
    'CoolProp': 'requirements/core.txt, requirements/apt.txt (pip)',
}
"""Modules without a rosdep key, so no package.xml can declare them, with where they come from."""


def ruff_errors(package_dir: Path) -> list[str]:
    """``ruff check`` and ``ruff format --check`` of ``package_dir``: their findings (none: clean)."""
    try:
        from ruff.__main__ import find_ruff_bin
    except ImportError:
        return ['ruff is not installed: pip install -r requirements/test.txt']
    ruff = find_ruff_bin()
    errors = []
    for cmd in ([ruff, 'check', '--no-cache', '--quiet'], [ruff, 'format', '--check', '--no-cache', '--quiet']):
        done = subprocess.run([*cmd, str(package_dir)], capture_output=True, text=True, check=False)
        if done.returncode != 0:
            errors += [line for line in (done.stdout + done.stderr).splitlines() if line.strip()] or [
                f'{cmd[1]} exited {done.returncode}'
            ]
    return errors


def pep257_errors(package_dir: Path) -> list[str]:
    """ament_pep257 over ``package_dir`` but its tests (Google convention, :data:`PEP257_IGNORE`): its findings."""
    from ament_pep257.main import generate_pep257_report

    root = package_dir.resolve()
    excludes = [str(root / 'setup.py'), str(root / 'test')]  # tests: no docstring rules (pyproject.toml)
    report = generate_pep257_report([str(root)], excludes, None, None, 'google', ','.join(PEP257_IGNORE), None)
    return [f'{name}:{e["linenumber"]}: {e["category"]}: {e["message"]}' for name, errs in report for e in errs]


def _python_files(package_dir: Path) -> list[Path]:
    skip = {'build', 'install', 'log'}
    return sorted(p for p in package_dir.rglob('*.py') if not skip & set(p.relative_to(package_dir).parts))


def _imports(path: Path) -> list[tuple[str, bool]]:
    """``(top-level module, guarded)`` of each absolute import; guarded: inside a function or a ``try``."""
    out: list[tuple[str, bool]] = []

    def visit(node: ast.AST, guarded: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.Import):
                out.extend((a.name.split('.')[0], guarded) for a in child.names)
            elif isinstance(child, ast.ImportFrom) and child.level == 0 and child.module:
                out.append((child.module.split('.')[0], guarded))
            inner = guarded or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Try)
            visit(child, inner)

    visit(ast.parse(path.read_text(encoding='utf-8'), filename=str(path)), False)
    return out


def undeclared_imports(package_dir: Path) -> list[str]:
    """What ``package_dir``'s imports need and its package.xml does not declare, one line each."""
    root = ET.parse(package_dir / 'package.xml').getroot()
    name = root.findtext('name')
    depends = {'depend', 'exec_depend', 'build_export_depend'}
    run = {e.text for e in root if e.tag in depends}
    test = run | {e.text for e in root if e.tag == 'test_depend'}
    optional = set((root.findtext('export/ceco_optional_imports') or '').split())
    local = {p.name for p in package_dir.iterdir() if p.is_dir()} | {p.stem for p in package_dir.rglob('*.py')}
    errors = []
    for path in _python_files(package_dir):
        rel = path.relative_to(package_dir)
        declared = test if rel.parts[0] == 'test' or rel.name == 'setup.py' else run
        for module, guarded in _imports(path):
            if module in sys.stdlib_module_names or module in local or module in (name, 'setuptools'):
                continue
            key = ROSDEP_KEYS.get(module, module)
            if module in optional:
                if not guarded:
                    errors.append(f'{rel}: optional {module} imported at module level outside a try')
                continue
            if key in declared or module in UNDECLARED_OK:
                continue
            kind = 'test_depend' if declared is test else 'exec_depend'
            errors.append(f'{rel}: imports {module}: package.xml lacks <{kind}>{key}</{kind}>')
    return list(dict.fromkeys(errors))
