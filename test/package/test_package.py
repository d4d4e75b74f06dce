"""The package as colcon builds it: install layout, package.xml schema."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

from helpers import REPO, SHARED
import pytest

SCHEMA = SHARED / 'schemas' / 'package_format3.xsd'


@pytest.fixture(scope='module')
def install_prefix(tmp_path_factory):
    """Build and install the package the way colcon's ament_python task does."""
    tmp = tmp_path_factory.mktemp('colcon')
    src = tmp / 'src'
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(
        '.venv', '.git', 'build', 'install', 'runs', '.ros_log', '*.egg-info',
        '__pycache__', '.hypothesis'))
    prefix = tmp / 'install'
    cmd = [sys.executable, 'setup.py',
           'egg_info', '--egg-base', str(tmp / 'build'),
           'build', '--build-base', str(tmp / 'build' / 'build'),
           'install', '--prefix', str(prefix), '--record', str(tmp / 'record.txt'),
           '--single-version-externally-managed']
    (tmp / 'build').mkdir()
    res = subprocess.run(cmd, cwd=src, capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr
    return prefix


def test_ament_index_marker(install_prefix):
    marker = install_prefix / 'share/ament_index/resource_index/packages/leadscrew_sim'
    assert marker.is_file()


def test_package_xml_installed(install_prefix):
    assert (install_prefix / 'share/leadscrew_sim/package.xml').is_file()


@pytest.mark.parametrize('exe', ['leadscrew_sim_node', 'leadscrew_sim'])
def test_executables_in_lib(install_prefix, exe):
    path = install_prefix / 'lib/leadscrew_sim' / exe
    assert path.is_file(), sorted(p.name for p in (install_prefix / 'lib').iterdir())
    assert os.access(path, os.X_OK)


def test_presets_installed(install_prefix):
    share = install_prefix / 'share/leadscrew_sim/config'
    installed = sorted(p.name for p in share.glob('*.yaml'))
    source = sorted(p.name for p in (REPO / 'config').glob('*.yaml'))
    assert source and installed == source


def test_foxglove_layout_installed(install_prefix):
    """The Foxglove layout the README names is in the install space, byte for byte."""
    installed = install_prefix / 'share/leadscrew_sim/doc/foxglove/leadscrew_axis.json'
    assert installed.is_file()
    assert installed.read_bytes() == (REPO / 'doc/foxglove/leadscrew_axis.json').read_bytes()


def test_ament_index_finds_package(install_prefix):
    code = ('from ament_index_python.packages import get_package_share_directory as g;'
            'print(g("leadscrew_sim"))')
    env = dict(os.environ, AMENT_PREFIX_PATH=f'{install_prefix}:{sys.prefix}')
    out = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True,
                         text=True, check=True).stdout.strip()
    assert Path(out) == install_prefix / 'share/leadscrew_sim'


def test_package_xml_validates_against_format3_schema():
    if not SCHEMA.is_file():
        pytest.skip('../shared/schemas is absent; schema check needs it')
    from lxml import etree
    schema = etree.XMLSchema(etree.parse(str(SCHEMA)))
    doc = etree.parse(str(REPO / 'package.xml'))
    assert schema.validate(doc), str(schema.error_log)


def test_package_xml_parses_like_colcon():
    from catkin_pkg.package import parse_package
    pkg = parse_package(str(REPO / 'package.xml'))
    pkg.validate()
    assert pkg.name == 'leadscrew_sim'
    assert pkg.package_format == 3
    assert pkg.get_build_type() == 'ament_python'
    deps = {d.name for d in pkg.exec_depends}
    for d in ('rclpy', 'std_msgs', 'sensor_msgs', 'geometry_msgs', 'diagnostic_msgs',
              'rosgraph_msgs', 'std_srvs', 'python3-numpy', 'python3-scipy'):
        assert d in deps


def test_every_module_is_installed(install_prefix):
    """Each .py file under leadscrew_sim/ in the source tree lands in site-packages."""
    site = next(install_prefix.glob('lib/python3*/site-packages'))
    source = sorted(p.relative_to(REPO).as_posix()
                    for p in (REPO / 'leadscrew_sim').rglob('*.py')
                    if '__pycache__' not in p.parts)
    missing = [rel for rel in source if not (site / rel).is_file()]
    assert source and not missing, f'not installed: {missing}'


def test_commission_template_installed(install_prefix):
    """The commissioning report's page template (package data) lands beside its module."""
    site = next(install_prefix.glob('lib/python3*/site-packages'))
    assert (site / 'leadscrew_sim/offline/commission/report_template.html').is_file()
