"""
The robot description urdf/leadscrew_axis.urdf.xacro, rendered and loaded by third parties.

xacro (the PyPI package, its Python API) renders it with arguments; yourdfpy
loads it and computes the forward kinematics. The oracles are closed forms:
a prismatic joint along +x is a translation, a revolute joint about +x is
Rx(theta), an ideal mimic is x = h (l / 2 pi) theta; the limits are the
arguments mapped through the lead; the defaults are the default preset's values
read from config/tr12x3.yaml.
"""
import io
import math

from helpers import REPO
from leadscrew_sim.io.topics import resolve
from lxml import etree
import numpy as np
import pytest
import xacro
import yaml
import yourdfpy

XACRO = REPO / 'urdf' / 'leadscrew_axis.urdf.xacro'

#: (prefix, lead, stroke_min, stroke_max, hand) combinations rendered.
CASES = [
    ('', 0.003, -0.2, 0.2, 'right'),
    ('x_', 0.008, 0.0, 0.3, 'right'),
    ('gantry_y_', 0.002, -0.05, 0.45, 'left'),
    ('z_', 0.0254 * 0.25 * 2, -0.5, -0.1, 'right'),
]


def render(**args):
    """Return the URDF text xacro makes of the file with these arguments."""
    mappings = {k: str(v).lower() if isinstance(v, bool) else str(v) for k, v in args.items()}
    return xacro.process_file(str(XACRO), mappings=mappings).toxml()


def load(xml):
    """Load URDF text with yourdfpy (no meshes: the model has none)."""
    return yourdfpy.URDF.load(io.StringIO(xml), build_collision_scene_graph=False,
                              load_meshes=False, load_collision_meshes=False)


def rot_x(theta):
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def case_args(case):
    prefix, lead, lo, hi, hand = case
    return dict(prefix=prefix, lead=lead, stroke_min=lo, stroke_max=hi, hand=hand)


@pytest.fixture(scope='module', params=CASES, ids=lambda c: f'{c[0] or "noprefix"}-{c[1]:g}')
def case(request):
    """One argument set, its rendered URDF text and the yourdfpy model of it."""
    xml = render(**case_args(request.param))
    return request.param, xml, load(xml)


def test_defaults_are_the_default_preset():
    with open(REPO / 'config' / 'tr12x3.yaml') as fh:
        doc = yaml.safe_load(fh)
    (section,) = [v for v in doc.values() if 'ros__parameters' in v]
    p = section['ros__parameters']
    robot = load(render())
    nut = robot.joint_map['nut_joint']
    assert nut.limit.lower == pytest.approx(p['stroke_min'])
    assert nut.limit.upper == pytest.approx(p['stroke_max'])
    lead = p['pitch'] * p['starts']
    # velocity limit = screw velocity limit * l / (2 pi): recovers the lead.
    screw = robot.joint_map['screw_joint']
    assert nut.limit.velocity / screw.limit.velocity * 2 * math.pi == pytest.approx(lead)
    assert screw.limit.effort == pytest.approx(p['max_torque'])
    # The screw's axial inertia is the preset's screw_inertia to within the
    # difference of a plain steel cylinder of the major diameter and a real screw.
    ixx = robot.link_map['screw_link'].inertial.inertia[0, 0]
    assert 0.7 < ixx / p['screw_inertia'] < 1.4


def test_loads_and_validates(case):
    (prefix, *_), _xml, robot = case
    assert robot.validate()
    names = {f'{prefix}{n}' for n in ('base_link', 'motor_link', 'screw_link', 'nut_link')}
    assert set(robot.link_map) == names
    assert robot.base_link == f'{prefix}base_link'
    assert sorted(robot.actuated_joint_names) == sorted(
        [f'{prefix}screw_joint', f'{prefix}nut_joint'])


def test_joint_types_axes_limits(case):
    (prefix, lead, lo, hi, hand), _xml, robot = case
    screw = robot.joint_map[f'{prefix}screw_joint']
    nut = robot.joint_map[f'{prefix}nut_joint']
    assert screw.type == 'revolute' and nut.type == 'prismatic'
    np.testing.assert_allclose(screw.axis, [1, 0, 0])
    np.testing.assert_allclose(nut.axis, [1, 0, 0])
    assert screw.parent == nut.parent == f'{prefix}base_link'
    assert nut.mimic is None and screw.mimic is None
    assert (nut.limit.lower, nut.limit.upper) == pytest.approx((lo, hi))
    # The screw turns through the stroke (and the backlash b/2 beyond each end).
    h = -1.0 if hand == 'right' else 1.0
    b = 1e-4
    ends = sorted([h * 2 * math.pi * (lo - b / 2) / lead, h * 2 * math.pi * (hi + b / 2) / lead])
    assert (screw.limit.lower, screw.limit.upper) == pytest.approx(ends)
    assert nut.limit.velocity == pytest.approx(screw.limit.velocity * lead / (2 * math.pi))
    assert nut.limit.effort == pytest.approx(2 * math.pi * screw.limit.effort / lead)


def test_forward_kinematics(case):
    (prefix, _lead, lo, hi, _hand), _xml, robot = case
    base, nut, screw = (f'{prefix}{n}' for n in ('base_link', 'nut_link', 'screw_link'))
    robot.update_cfg({f'{prefix}screw_joint': 0.0, f'{prefix}nut_joint': 0.0})
    nut0 = robot.get_transform(nut, base)
    screw0 = robot.get_transform(screw, base)
    np.testing.assert_allclose(nut0[:3, :3], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(screw0, np.eye(4), atol=1e-12)
    rng = np.random.default_rng(20260)
    for _ in range(25):
        theta = rng.uniform(-400.0, 400.0)
        x = rng.uniform(lo, hi)
        robot.update_cfg({f'{prefix}screw_joint': theta, f'{prefix}nut_joint': x})
        t_nut = robot.get_transform(nut, base)
        t_screw = robot.get_transform(screw, base)
        expected = nut0.copy()
        expected[0, 3] += x
        np.testing.assert_allclose(t_nut, expected, atol=1e-12)
        np.testing.assert_allclose(t_screw[:3, :3], rot_x(theta), atol=1e-9)
        np.testing.assert_allclose(t_screw[:3, 3], 0.0, atol=1e-12)


def test_nut_stays_on_the_screw_over_the_stroke(case):
    (prefix, _lead, lo, hi, _hand), xml, robot = case
    doc = etree.fromstring(xml.encode())
    screw_len = float(doc.find(f"link[@name='{prefix}screw_link']/collision/geometry/cylinder")
                      .get('length'))
    nut_len = float(doc.find(f"link[@name='{prefix}nut_link']/collision/geometry/cylinder")
                    .get('length'))
    for x in (lo, hi):
        robot.update_cfg({f'{prefix}screw_joint': 0.0, f'{prefix}nut_joint': x})
        centre = robot.get_transform(f'{prefix}nut_link', f'{prefix}base_link')[0, 3]
        assert nut_len / 2 < centre < screw_len - nut_len / 2


def test_inertias_are_physical(case):
    _c, _xml, robot = case
    for name, link in robot.link_map.items():
        if link.inertial is None:
            continue
        assert link.inertial.mass > 0, name
        inertia = link.inertial.inertia
        np.testing.assert_allclose(inertia, inertia.T)
        ev = np.linalg.eigvalsh(inertia)
        assert ev.min() > 0, name
        assert 2 * ev.max() <= ev.sum() * (1 + 1e-9), name   # triangle inequality
    assert robot.link_map[f'{_c[0]}screw_link'].inertial is not None
    assert robot.link_map[f'{_c[0]}nut_link'].inertial is not None


@pytest.mark.parametrize('hand,h', [('right', -1.0), ('left', 1.0)])
def test_ideal_mimic_is_the_rigid_thread(hand, h):
    lead = 0.005
    robot = load(render(prefix='m_', lead=lead, hand=hand, ideal_mimic=True))
    assert robot.actuated_joint_names == ['m_screw_joint']
    mimic = robot.joint_map['m_nut_joint'].mimic
    assert mimic.joint == 'm_screw_joint'
    assert mimic.multiplier == pytest.approx(h * lead / (2 * math.pi))
    robot.update_cfg({'m_screw_joint': 0.0})
    x0 = robot.get_transform('m_nut_link', 'm_base_link')[0, 3]
    for theta in (-37.0, -1.0, 0.5, 12.0):
        robot.update_cfg({'m_screw_joint': theta})
        x = robot.get_transform('m_nut_link', 'm_base_link')[0, 3] - x0
        # physics section 3: right hand, positive turn -> nut toward -x.
        assert x == pytest.approx(h * lead * theta / (2 * math.pi), abs=1e-15)


#: command interface -> (joint it belongs to, the other joint)
COMMAND_JOINT = {'position': ('nut_joint', 'screw_joint'),
                 'velocity': ('nut_joint', 'screw_joint'),
                 'effort': ('screw_joint', 'nut_joint')}


@pytest.mark.parametrize('interface', sorted(COMMAND_JOINT))
@pytest.mark.parametrize('prefix', ['', 'y_'])
def test_ros2_control_block(interface, prefix):
    xml = render(prefix=prefix, ros2_control=True, command_interface=interface)
    assert load(xml).validate()
    doc = etree.fromstring(xml.encode())
    (block,) = doc.findall('ros2_control')
    assert block.get('type') == 'system'
    assert block.findtext('hardware/plugin') == 'topic_based_ros2_control/TopicBasedSystem'
    params = {p.get('name'): p.text for p in block.findall('hardware/param')}
    # The default topics are the node's in the root namespace (apart from
    # joint_state_broadcaster's /joint_states).
    assert params == {'joint_commands_topic': '/axis/joint_commands',
                      'joint_states_topic': '/axis/joint_states',
                      'trigger_joint_command_threshold': '-1'}
    assert params['joint_commands_topic'] == resolve('joint_commands')
    assert params['joint_states_topic'] == resolve('joint_states')
    joints = {j.get('name'): j for j in block.findall('joint')}
    # the commanded joint only: TopicBasedSystem packs each interface's values for the
    # joints that have it, under the names of all joints of the block
    commanded, _other = COMMAND_JOINT[interface]
    assert set(joints) == {prefix + commanded}
    assert [c.get('name') for c in joints[prefix + commanded].findall('command_interface')] \
        == [interface]
    for j in joints.values():
        assert sorted(s.get('name') for s in j.findall('state_interface')) == \
            ['effort', 'position', 'velocity']
    # The joints of the block are joints of the URDF.
    urdf_joints = {j.get('name') for j in doc.findall('joint')}
    assert set(joints) <= urdf_joints


def test_ros2_control_topics_are_arguments():
    # The node in the namespace x_axis.
    xml = render(ros2_control=True, joint_commands_topic='/x_axis/axis/joint_commands',
                 joint_states_topic='/x_axis/axis/joint_states')
    params = {p.get('name'): p.text
              for p in etree.fromstring(xml.encode()).findall('ros2_control/hardware/param')}
    assert params['joint_commands_topic'] == '/x_axis/axis/joint_commands'
    assert params['joint_states_topic'] == '/x_axis/axis/joint_states'


def test_no_ros2_control_block_by_default():
    assert etree.fromstring(render().encode()).find('ros2_control') is None


@pytest.mark.parametrize('args', [
    dict(command_interface='torque', ros2_control=True),
    dict(hand='both'),
    dict(lead=0.0),
    dict(stroke_min=0.2, stroke_max=0.1),
    dict(ideal_mimic=True, ros2_control=True, command_interface='position'),
], ids=['interface', 'hand', 'lead', 'stroke', 'mimic-command'])
def test_bad_arguments_are_refused(args):
    with pytest.raises(xacro.XacroException):
        render(**args)
