"""The workspace layout a ROS 2 user relies on: ament packages colcon recognises
and executables where `ros2 run` looks for them."""

import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PYTHON_PKGS = [
    'ceco_lint',
    'ceco_core',
    'ceco_ros',
    'ceco_v2x_preview',
    'ceco_plant_sim',
    'ceco_controller',
    'ceco_bringup',
]
NODE_PKGS = ['ceco_v2x_preview', 'ceco_plant_sim', 'ceco_controller', 'ceco_bringup']
"""The packages with executables (nodes, the ceco command)."""
EMAIL = re.compile(r'^[^@\s]+@[^@\s]+\.[a-z]{2,}$')


@pytest.mark.parametrize('pkg', PYTHON_PKGS + ['ceco_msgs'])
def test_package_xml_is_format3_with_valid_maintainer(pkg):
    tree = ET.parse(ROOT / pkg / 'package.xml').getroot()
    assert tree.get('format') == '3'
    assert tree.findtext('name') == pkg
    email = tree.find('maintainer').get('email')
    # colcon silently demotes a package with an invalid email to plain Python.
    assert EMAIL.match(email), email
    build_type = tree.find('export/build_type').text
    assert build_type == ('ament_cmake' if pkg == 'ceco_msgs' else 'ament_python')


@pytest.mark.parametrize('pkg', PYTHON_PKGS + ['ceco_msgs'])
def test_workspace_src_links_every_package(pkg):
    link = ROOT / 'ros_ws' / 'src' / pkg
    assert link.is_symlink() and link.resolve() == (ROOT / pkg).resolve()


@pytest.mark.parametrize('pkg', NODE_PKGS)
def test_console_scripts_installed_where_ros2_run_looks(pkg):
    setup_py = (ROOT / pkg / 'setup.py').read_text()
    scripts = re.findall(r"'(\w+) = [\w.]+:\w+'", setup_py)
    assert scripts, f'{pkg} declares no executables'
    prefix = os.environ.get('COLCON_PREFIX_PATH', str(ROOT / 'ros_ws' / 'install')).split(':')[0]
    for exe in scripts:
        path = Path(prefix) / pkg / 'lib' / pkg / exe
        assert path.is_file() and os.access(path, os.X_OK), path


# --- the package dependency graph (docs/architecture.md) -----------------------------------------
ALLOWED = {
    'ceco_lint': set(),  # imported by the packages' tests only
    'ceco_core': set(),
    'ceco_ros': {'ceco_core', 'ceco_msgs'},
    'ceco_v2x_preview': {'ceco_core', 'ceco_ros', 'ceco_msgs'},
    'ceco_plant_sim': {'ceco_core', 'ceco_ros', 'ceco_msgs', 'ceco_v2x_preview'},
    'ceco_controller': {'ceco_core', 'ceco_ros', 'ceco_msgs', 'ceco_v2x_preview', 'ceco_plant_sim'},
    'ceco_bringup': {'ceco_core', 'ceco_ros', 'ceco_msgs', 'ceco_v2x_preview', 'ceco_plant_sim', 'ceco_controller'},
}


NODE_MODULES = {'preview_node', 'plant_node', 'mpc_node', 'baseline_node'}


def _imports(path: Path, pkg: str) -> set[str]:
    """Modules a Python file of package ``pkg`` imports, anywhere in the file (relative imports resolved)."""
    import ast

    base = '.'.join(path.relative_to(ROOT / pkg).parts[:-1])  # e.g. ceco_bringup.sweep
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                out.add(node.module or '')
                out.update(f'{node.module}.{a.name}' for a in node.names)  # `from pkg import module`
                continue
            parent = base.rsplit('.', node.level - 1)[0] if node.level > 1 else base
            if node.module:
                out.add(f'{parent}.{node.module}')
            else:
                out.update(f'{parent}.{a.name}' for a in node.names)
    return out


def _package_imports(pkg: str) -> dict[str, set[str]]:
    return {str(f.relative_to(ROOT)): _imports(f, pkg) for f in sorted((ROOT / pkg / pkg).rglob('*.py'))}


@pytest.mark.parametrize('pkg', PYTHON_PKGS)
def test_package_imports_follow_the_one_way_dependency_graph_and_its_manifest(pkg):
    declared = {e.text for e in ET.parse(ROOT / pkg / 'package.xml').getroot().iter('exec_depend')}
    used = set()
    for f, mods in _package_imports(pkg).items():
        ceco = {m.split('.')[0] for m in mods if m.startswith('ceco_')} - {pkg}
        assert ceco <= ALLOWED[pkg], f'{f} imports {sorted(ceco - ALLOWED[pkg])} against the graph'
        # nobody imports another package's node module
        foreign_nodes = [
            m for m in mods if len(m.split('.')) > 1 and m.split('.')[1] in NODE_MODULES and m.split('.')[0] != pkg
        ]
        assert not foreign_nodes, (f, foreign_nodes)
        used |= ceco
    assert used <= declared, f'{pkg}/package.xml lacks exec_depend {sorted(used - declared)}'


def test_the_pure_core_imports_no_ros_and_no_coolprop_and_the_controllers_no_plant():
    for f, mods in _package_imports('ceco_core').items():
        bad = {m for m in mods if m.split('.')[0] in ('rclpy', 'CoolProp', 'ceco_msgs', 'rosbags')}
        assert not bad, (f, bad)
    # what mpc_node / baseline_node import, transitively inside ceco_controller, reaches no plant code
    ctrl = {f.split('/')[-1][:-3]: mods for f, mods in _package_imports('ceco_controller').items()}
    seen, todo = set(), ['mpc_node', 'baseline_node']
    while todo:
        name = todo.pop()
        if name in seen or name not in ctrl:
            continue
        seen.add(name)
        for m in ctrl[name]:
            assert not m.startswith('ceco_plant_sim') and not m.startswith('CoolProp'), (name, m)
            if m.startswith('ceco_controller.'):
                todo.append(m.split('.')[1])
    assert {'mpc_node', 'nmpc', 'factory', 'estimator'} <= seen


def test_colcon_test_runs_each_packages_own_tests(tmp_path):
    """`colcon test` (as a ROS 2 developer runs it) finds and runs tests in every package: each
    ament_python package's lint (ceco_lint) through pytest, ceco_msgs' interface test through ctest;
    `colcon test-result` counts them. (The packages' other tests run here in the whole suite.)"""
    import subprocess

    results, logs = tmp_path / 'results', tmp_path / 'log'
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE='1')
    cmd = ['colcon', '--log-base', str(logs), 'test', '--test-result-base', str(results)]
    done = subprocess.run(
        # each package's package.xml check (its other tests run in this suite directly), ceco_msgs' ctest
        [*cmd, '--pytest-args', '-k', 'declared_imports or msgs', '-p', 'no:cacheprovider'],
        cwd=ROOT / 'ros_ws',
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    summary = subprocess.run(
        ['colcon', 'test-result', '--test-result-base', str(results), '--all'],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    ).stdout
    counts = {}
    for line in summary.splitlines():
        m = re.match(r'^\S*/(ceco_\w+)/\S+: (\d+) tests?, (\d+) errors?, (\d+) failures?, (\d+) skipped', line)
        if m:
            counts[m[1]] = counts.get(m[1], 0) + int(m[2])
            assert m.groups()[2:] == ('0', '0', '0'), line
    assert set(counts) == set(PYTHON_PKGS) | {'ceco_msgs'}, summary
    assert all(n >= 1 for n in counts.values()), counts
