"""
Every dependency key of package.xml resolves with rosdep on Ubuntu noble and Debian bookworm.

The key databases are rosdistro's (../shared/rosdep: base.yaml, python.yaml,
jazzy-distribution.yaml); the test skips when they are absent. A key resolves
if it is a package released for Jazzy, or if base.yaml/python.yaml give it a
rule for the platform (a package list, or an installer such as pip with
packages), following rosdep's rule syntax: per-OS entries, optionally keyed by
codename or '*', a null entry meaning "not available".
"""

from catkin_pkg.package import parse_package
from helpers import REPO, SHARED
import pytest
import yaml

ROSDEP = SHARED / 'rosdep'
PLATFORMS = (('ubuntu', 'noble'), ('debian', 'bookworm'))
INSTALLERS = ('apt', 'pip', 'source')

pytestmark = pytest.mark.skipif(
    not (ROSDEP / 'jazzy-distribution.yaml').is_file(),
    reason='../shared/rosdep is absent; the key check needs the rosdep databases')


@pytest.fixture(scope='module')
def databases():
    """(Jazzy package names, {key: rule} of base.yaml and python.yaml)."""
    with open(ROSDEP / 'jazzy-distribution.yaml') as fh:
        dist = yaml.safe_load(fh)
    released = set()
    for name, repo in dist['repositories'].items():
        release = (repo or {}).get('release')
        if release:
            released.update(release.get('packages', [name]))
    rules = {}
    for db in ('base.yaml', 'python.yaml'):
        with open(ROSDEP / db) as fh:
            for key, rule in yaml.safe_load(fh).items():
                # rosdep's sources list has base.yaml before python.yaml; the
                # first source that defines a key (e.g. mercurial) is used.
                rules.setdefault(key, rule)
    return released, rules


def _packages(rule):
    """Return the packages an installer rule installs, or None if it is not valid."""
    if isinstance(rule, str):
        return rule.split()
    if isinstance(rule, list):
        return rule if all(isinstance(p, str) for p in rule) else None
    if isinstance(rule, dict):
        if 'packages' in rule:
            return _packages(rule['packages'])
        for installer in INSTALLERS:
            if installer in rule:
                return _packages(rule[installer])
    return None


def resolve(rule, os_name, codename):
    """Return what rosdep installs for a rule on os_name/codename, or None if nothing."""
    if not isinstance(rule, dict) or os_name not in rule:
        return None
    entry = rule[os_name]
    if isinstance(entry, dict) and not set(entry) & {'packages', *INSTALLERS}:
        # keyed by codename ('*': every other release)
        entry = entry.get(codename, entry.get('*')) if codename in entry or '*' in entry \
            else None
    if entry is None:
        return None
    return _packages(entry)


def test_resolver_follows_rosdep_rules():
    """The resolver against hand-made rules of every shape the databases use."""
    assert resolve({'ubuntu': ['a'], 'debian': ['b']}, 'debian', 'bookworm') == ['b']
    assert resolve({'ubuntu': ['a']}, 'debian', 'bookworm') is None
    assert resolve({'ubuntu': {'pip': {'packages': ['p']}}}, 'ubuntu', 'noble') == ['p']
    assert resolve({'ubuntu': {'*': ['new'], 'focal': ['old']}}, 'ubuntu', 'noble') == ['new']
    assert resolve({'ubuntu': {'*': ['new'], 'noble': None}}, 'ubuntu', 'noble') is None
    assert resolve({'ubuntu': {'focal': ['old']}}, 'ubuntu', 'noble') is None
    assert resolve({'debian': {'bookworm': {'pip': {'packages': ['q']}}}},
                   'debian', 'bookworm') == ['q']
    assert resolve({'ubuntu': []}, 'ubuntu', 'noble') == []     # satisfied, nothing to install
    assert resolve({'ubuntu': None}, 'ubuntu', 'noble') is None


def test_resolver_on_known_keys(databases):
    """Keys whose status is documented: python3-numpy is apt, python3-mcap does not exist."""
    released, rules = databases
    assert resolve(rules['python3-numpy'], 'ubuntu', 'noble') == ['python3-numpy']
    assert 'python3-mcap' not in rules and 'python3-mcap' not in released
    assert 'rclpy' in released and 'rclpy' not in rules


def dependency_keys():
    pkg = parse_package(str(REPO / 'package.xml'))
    deps = (pkg.build_depends + pkg.buildtool_depends + pkg.build_export_depends
            + pkg.buildtool_export_depends + pkg.exec_depends + pkg.test_depends
            + pkg.doc_depends)
    return sorted({d.name for d in deps})


def test_package_xml_has_the_launch_and_description_dependencies():
    keys = dependency_keys()
    for key in ('launch', 'launch_ros', 'robot_state_publisher', 'xacro'):
        assert key in keys


@pytest.mark.parametrize('key', dependency_keys())
@pytest.mark.parametrize('os_name,codename', PLATFORMS)
def test_key_resolves(databases, key, os_name, codename):
    released, rules = databases
    if key in released:
        return
    assert key in rules, f'{key}: neither a Jazzy package nor a rosdep key'
    installs = resolve(rules[key], os_name, codename)
    assert installs is not None, f'{key}: no rule for {os_name} {codename}: {rules[key]}'
