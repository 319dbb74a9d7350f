"""The apt install path (Ubuntu 24.04, ROS 2 Jazzy from apt) is one path: the
same commands in README.md, docs/ros.md and docker/Dockerfile, and its
skip-keys and pip file agree with the package manifests."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = {name: (ROOT / name).read_text() for name in ('README.md', 'docs/ros.md', 'docker/Dockerfile')}
PACKAGES = sorted(p.parent.name for p in ROOT.glob('ceco_*/package.xml'))
SKIP_KEYS = ('casadi-pip', 'python3-rosbags-pip')
ROSDEP = f'rosdep install --from-paths ros_ws/src --ignore-src -y --skip-keys "{" ".join(SKIP_KEYS)}"'


def _exec_depends(pkg: str) -> list[str]:
    return [e.text for e in ET.parse(ROOT / pkg / 'package.xml').getroot().iter('exec_depend')]


@pytest.mark.parametrize('doc', list(DOCS))
def test_the_same_commands_everywhere(doc):
    text = DOCS[doc]
    assert ROSDEP in text
    assert 'python3 -m venv --system-site-packages' in text
    assert re.search(r'pip install (--no-cache-dir )?-r requirements/apt\.txt', text)
    assert 'python -m colcon build' in text
    assert 'pip install -r requirements/core.txt' not in text  # the old PEP 668-refused line


def test_skip_keys_are_exactly_the_pip_keys_of_the_manifests():
    pip_keys = {k for pkg in PACKAGES for k in _exec_depends(pkg) if k.endswith('-pip')}
    assert pip_keys == set(SKIP_KEYS)


def test_apt_requirements_cover_the_skipped_and_keyless_packages_with_core_pins():
    def pins(path):
        out = {}
        for line in (ROOT / path).read_text().splitlines():
            line = line.split('#')[0].strip()
            if line:
                name, op, version = re.match(r'([A-Za-z0-9_.\-]+)\s*(==|<|>=)?\s*(\S*)', line).groups()
                out[name.lower()] = (op, version)
        return out

    apt, core = pins('requirements/apt.txt'), pins('requirements/core.txt')
    # casadi-pip, python3-rosbags-pip and CoolProp (no rosdep key), at the versions of core.txt
    assert set(apt) == {'numpy', 'casadi', 'coolprop', 'rosbags'}
    for name in ('casadi', 'coolprop', 'rosbags'):
        assert apt[name] == core[name] and apt[name][0] == '=='
    assert apt['numpy'] == ('<', '2')  # keeps apt's numpy 1.26
    # apt-provided keys are declared, not pip-installed
    declared = {k for pkg in PACKAGES for k in _exec_depends(pkg)}
    assert {
        'python3-numpy',
        'python3-scipy',
        'python3-yaml',
        'python3-matplotlib',
        'python3-tqdm',
        'python3-ruamel.yaml',
        'ament_index_python',
        'launch_ros',
        'ros2bag',
    } <= declared


def test_manifests_are_valid_xml_without_double_dash_in_comments():
    for pkg in PACKAGES:
        text = (ROOT / pkg / 'package.xml').read_text()
        ET.fromstring(text)  # '--' inside a comment is invalid XML
        for comment in re.findall(r'<!--(.*?)-->', text, re.S):
            assert '--' not in comment, pkg
