"""The workspace layout a ROS 2 user relies on: ament packages colcon recognises
and executables where `ros2 run` looks for them."""
import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PYTHON_PKGS = ['ceco_v2x_preview', 'ceco_plant_sim', 'ceco_controller', 'ceco_bringup']
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


@pytest.mark.parametrize('pkg', PYTHON_PKGS)
def test_console_scripts_installed_where_ros2_run_looks(pkg):
    setup_py = (ROOT / pkg / 'setup.py').read_text()
    scripts = re.findall(r"'(\w+) = [\w.]+:\w+'", setup_py)
    assert scripts, f'{pkg} declares no executables'
    prefix = os.environ.get('COLCON_PREFIX_PATH', str(ROOT / 'ros_ws' / 'install')).split(':')[0]
    for exe in scripts:
        path = Path(prefix) / pkg / 'lib' / pkg / exe
        assert path.is_file() and os.access(path, os.X_OK), path
