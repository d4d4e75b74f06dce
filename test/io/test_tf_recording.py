"""
Robot description and TF in run files: leadscrew_sim.io.description against yourdfpy.

The oracle of every transform is yourdfpy's forward kinematics of the same URDF
text (an independent URDF parser), compared as 4x4 matrices; the recordings are
read back with rosbags (its types registered from the file's own schema texts)
and mcap_ros2, and checked with ``mcap doctor`` when the mcap CLI is present.
"""
import ast
import io
import math
from pathlib import Path
import subprocess
import sys

from helpers import cli_ok, NS, REPO, SHARED
from leadscrew_sim.core.presets import load_preset
from leadscrew_sim.io import description as D, tf
from leadscrew_sim.io.run_file import RunFileError, RunWriter
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_types_from_msg, get_typestore, Stores
import yourdfpy

MCAP_CLI = SHARED / 'mcap-cli' / 'mcap'
TOL = 1e-12

#: A URDF exercising what the package's URDF does not: origins with rpy, oblique axes,
#: a chain of moving joints, fixed joints below moving ones and a mimic joint.
SYNTHETIC = """<?xml version="1.0"?>
<robot name="synthetic">
  <link name="base"/><link name="mount"/><link name="screw"/><link name="nut"/>
  <link name="tool"/><link name="follower"/>
  <joint name="mount_joint" type="fixed">
    <parent link="base"/><child link="mount"/>
    <origin xyz="0.1 -0.2 0.3" rpy="0.3 -1.1 2.5"/>
  </joint>
  <joint name="p_screw_joint" type="continuous">
    <parent link="mount"/><child link="screw"/>
    <origin xyz="-0.05 0.02 0.7" rpy="-2.9 0.4 -0.8"/>
    <axis xyz="0.3 -0.5 0.8"/>
  </joint>
  <joint name="p_nut_joint" type="prismatic">
    <parent link="screw"/><child link="nut"/>
    <origin xyz="0.25 0.01 -0.02" rpy="1.2 1.5 -0.6"/>
    <axis xyz="-0.6 0.0 0.8"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <joint name="tool_joint" type="fixed">
    <parent link="nut"/><child link="tool"/>
    <origin xyz="0.0 0.0 0.1" rpy="0 1.5707963267948966 0"/>
  </joint>
  <joint name="follower_joint" type="revolute">
    <parent link="tool"/><child link="follower"/>
    <origin xyz="0.03 0.0 0.0" rpy="0.1 0.2 0.3"/>
    <axis xyz="0 1 0"/>
    <limit lower="-100" upper="100" effort="1" velocity="1"/>
    <mimic joint="p_screw_joint" multiplier="-0.5" offset="0.25"/>
  </joint>
</robot>
"""


def matrix(translation, q):
    """Return the 4x4 matrix of a translation and an (x, y, z, w) quaternion."""
    x, y, z, w = q
    m = np.eye(4)
    m[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    m[:3, 3] = translation
    return m


def chain(transforms):
    """Return {child: 4x4 pose in the root frame} of parent -> child transforms (a tree)."""
    edges = {c: (p, matrix(t, q)) for p, c, t, q in transforms}
    poses = {}

    def pose(link):
        if link not in poses:
            parent = edges.get(link)
            poses[link] = np.eye(4) if parent is None else pose(parent[0]) @ parent[1]
        return poses[link]

    for link in list(edges):
        pose(link)
    return poses


def load_urdf(text, tmp_path, name='robot.urdf'):
    """Load URDF text with yourdfpy from a file."""
    path = tmp_path / name
    path.write_text(text)
    return yourdfpy.URDF.load(str(path), build_collision_scene_graph=False,
                              load_meshes=False, load_collision_meshes=False)


def set_cfg(robot, cfg):
    """
    Set yourdfpy's joint configuration exactly.

    trimesh's scene graph keeps an edge whose new matrix is within 1e-8 of the
    old one, so the configuration first moves far away.
    """
    robot.update_cfg({name: q + 10.0 for name, q in cfg.items()})
    robot.update_cfg(cfg)


def check_fk(tree, robot, states, base):
    """Assert JointTree's chained transforms equal yourdfpy's FK for each (angle, x)."""
    static = tree.static_transforms()
    actuated = set(robot.actuated_joint_names)
    for angle, x in states:
        cfg = {n: v for n, v in ((tree.screw_joint, angle), (tree.nut_joint, x))
               if n in actuated}
        set_cfg(robot, cfg)
        poses = chain(static + tree.moving_transforms(angle, x))
        assert set(poses) == set(robot.link_map)
        for link, pose in poses.items():
            np.testing.assert_allclose(pose, robot.get_transform(link, base), rtol=0, atol=TOL,
                                       err_msg=f'{link} at ({angle}, {x})')


def random_states(seed, n=20, angle=900.0, x=0.3):
    rng = np.random.default_rng(seed)
    return list(zip(rng.uniform(-angle, angle, n), rng.uniform(-x, x, n)))


# ---------------------------------------------------------------------------
# JointTree against yourdfpy
# ---------------------------------------------------------------------------

@pytest.mark.parametrize('prefix,preset,hand', [('', 'tr12x3', None), ('x_', 'tr12x3', 'left'),
                                                ('gantry/y_', 'stick_slip', None)])
def test_package_urdf_matches_yourdfpy(prefix, preset, hand, tmp_path):
    params = load_preset(preset)
    args = D.xacro_args(params, prefix)
    if hand:
        args['hand'] = hand
    text = D.render_urdf(args)
    tree = D.JointTree(text)
    assert tree.screw_joint == prefix + 'screw_joint' and tree.nut_joint == prefix + 'nut_joint'
    assert tree.static_frames == ((prefix + 'base_link', prefix + 'motor_link'),)
    assert tree.moving_frames == ((prefix + 'base_link', prefix + 'screw_link'),
                                  (prefix + 'base_link', prefix + 'nut_link'))
    robot = load_urdf(text, tmp_path)
    check_fk(tree, robot, random_states(len(prefix)), prefix + 'base_link')


def test_synthetic_urdf_matches_yourdfpy(tmp_path):
    """Rpy origins, oblique axes, a chain, a fixed joint below a moving one and a mimic."""
    tree = D.JointTree(SYNTHETIC)
    assert tree.screw_joint == 'p_screw_joint' and tree.nut_joint == 'p_nut_joint'
    assert tree.static_frames == (('base', 'mount'), ('nut', 'tool'))
    assert tree.moving_frames == (('mount', 'screw'), ('screw', 'nut'), ('tool', 'follower'))
    robot = load_urdf(SYNTHETIC, tmp_path)
    check_fk(tree, robot, random_states(5, angle=50.0, x=2.0), 'base')


def test_ideal_mimic_nut_follows_the_screw(tmp_path):
    """With ideal_mimic the nut is h l / (2 pi) theta whatever nut_position says."""
    text = D.render_urdf(dict(D.xacro_args(load_preset('tr12x3'), 'm_'), ideal_mimic='true'))
    tree = D.JointTree(text)
    robot = load_urdf(text, tmp_path)
    check_fk(tree, robot, random_states(9), 'm_base_link')
    (_p, _c, t0, _q), = [m for m in tree.moving_transforms(10.0, 0.0) if m[1] == 'm_nut_link']
    (_p, _c, t1, _q), = [m for m in tree.moving_transforms(10.0, 0.1) if m[1] == 'm_nut_link']
    assert t0 == t1


def test_quaternions_and_columns():
    """Unit quaternions; moving_columns equals moving_values row by row, bit for bit."""
    for text in (SYNTHETIC, D.render_urdf(D.xacro_args(load_preset('tr12x3')))):
        tree = D.JointTree(text)
        for _p, _c, _t, q in tree.static_transforms():
            assert math.isclose(math.fsum(v * v for v in q), 1.0, abs_tol=1e-15)
        states = random_states(3, n=200, angle=5e4) + [(0.0, 0.0), (-0.0, -0.0), (1e-300, 5.0)]
        a = np.array([s[0] for s in states])
        x = np.array([s[1] for s in states])
        cols = tree.moving_columns(a, x)
        assert len(cols) == tf.VALUES_PER_FRAME * len(tree.moving_frames)
        assert all(c.dtype == np.float64 and c.shape == a.shape for c in cols)
        for k, (ak, xk) in enumerate(states):
            values = tree.moving_values(ak, xk)
            assert np.array([c[k] for c in cols]).tobytes() == np.array(values).tobytes()
            for i in range(len(tree.moving_frames)):
                q = values[7 * i + 3:7 * i + 7]
                assert math.isclose(math.fsum(v * v for v in q), 1.0, abs_tol=1e-15)
        enc = tf.TfEncoder(tree.moving_frames)
        stamps = np.arange(len(states), dtype=np.int64) * 1_000_000
        rows = enc.rows(stamps, cols)
        for k, (ak, xk) in enumerate(states):
            assert rows[k].tobytes() == enc(int(stamps[k]), tree.moving_values(ak, xk))


# ---------------------------------------------------------------------------
# xacro arguments and rendering
# ---------------------------------------------------------------------------

def _launch_source():
    """Return the syntax tree of the single-axis launch file (read with ast, no launch imports)."""
    return ast.parse((REPO / 'launch' / 'leadscrew_sim.launch.py').read_text())


def test_xacro_args():
    # The launch file maps a preset with this function, not a copy of the mapping.
    tree = _launch_source()
    assert any(isinstance(n, ast.ImportFrom) and n.module == 'leadscrew_sim.io.description'
               and 'xacro_args' in [a.name for a in n.names] for n in tree.body)
    assert not any(isinstance(n, ast.Assign) and any(
        getattr(t, 'id', None) == 'XACRO_FROM_PARAMETERS' for t in n.targets) for n in tree.body)
    p = load_preset('tr12x3')
    args = D.xacro_args(p, 'z_')
    assert args == {'prefix': 'z_', 'lead': str(p.pitch * p.starts), 'hand': p.hand,
                    'backlash': str(p.backlash), 'stroke_min': str(p.stroke_min),
                    'stroke_max': str(p.stroke_max), 'screw_diameter': str(p.major_diameter),
                    'max_torque': str(p.max_torque),
                    'max_screw_velocity': str(p.max_screw_velocity),
                    'initial_position': str(p.initial_position)}
    # A mapping of node parameters, as the launch file reads them: only what is present.
    assert D.xacro_args({'starts': 2, 'backlash': 5e-5, 'mu_s': 0.2}) == {
        'prefix': '', 'lead': str(0.003 * 2), 'backlash': '5e-05'}
    assert D.xacro_args({}) == {'prefix': ''}


def test_render_urdf_has_no_machine_path_and_errors(monkeypatch, tmp_path):
    text = D.render_urdf({'prefix': 'q_', 'lead': 0.004})
    assert 'autogenerated by xacro' not in text and str(REPO) not in text
    assert 'prefix:=q_ lead:=0.004' in text
    robot = yourdfpy.URDF.load(io.StringIO(text), load_meshes=False,
                               build_collision_scene_graph=False, load_collision_meshes=False)
    assert robot.joint_map['q_nut_joint'].limit.velocity == pytest.approx(
        robot.joint_map['q_screw_joint'].limit.velocity * 0.004 / (2 * math.pi))
    with pytest.raises(D.DescriptionError, match="hand must be 'right' or 'left'"):
        D.render_urdf({'hand': 'middle'})
    monkeypatch.setattr(D, 'xacro_dirs', lambda: [])
    with pytest.raises(D.DescriptionError, match='not found'):
        D.render_urdf()
    monkeypatch.setitem(sys.modules, 'xacro', None)
    with pytest.raises(D.DescriptionError, match='package xacro is needed'):
        D.render_urdf()
    with pytest.raises(RunFileError, match='robot description: .*xacro is needed'):
        RunWriter(tmp_path / 'x.mcap', params=load_preset('tr12x3'))


def test_xacro_dirs_installed_layout(tmp_path, monkeypatch):
    share = tmp_path / 'share' / 'leadscrew_sim' / 'urdf'
    share.mkdir(parents=True)
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path))
    dirs = D.xacro_dirs()
    assert dirs[0] == REPO / 'urdf' and share in dirs
    assert D.xacro_path() == REPO / 'urdf' / D.XACRO_FILE


# ---------------------------------------------------------------------------
# simulate and resim recordings
# ---------------------------------------------------------------------------

@pytest.fixture(scope='module')
def tf_run(tmp_path_factory):
    """Return a 0.3 s simulate recording with joint prefix x_ (the screw turns, the nut moves)."""
    d = tmp_path_factory.mktemp('tfrun')
    path = d / 'run.mcap'
    cli_ok('simulate', '--duration', 0.3, '--profile', 'sine', '--amplitude', 0.3,
           '--frequency', 3.0, '--set', 'joint_prefix=x_', '--clock', '--output', path, '-q')
    return path


def _typestore(path):
    """Return an EMPTY rosbags typestore with the types of the file's own schemas."""
    store = get_typestore(Stores.EMPTY)
    with open(path, 'rb') as f:
        for schema in make_reader(f).get_summary().schemas.values():
            assert schema.encoding == 'ros2msg'
            store.register(get_types_from_msg(schema.data.decode(), schema.name))
    return store


def _tf_tuples(msg):
    return [(t.header.stamp.sec * NS + t.header.stamp.nanosec, t.header.frame_id,
             t.child_frame_id, (t.transform.translation.x, t.transform.translation.y,
                                t.transform.translation.z),
             (t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z,
              t.transform.rotation.w)) for t in msg.transforms]


def _read_rosbags(path):
    by_topic = {}
    with AnyReader([Path(path)], default_typestore=_typestore(path)) as r:
        qos = {c.topic: [(p.durability.name, p.depth) for p in c.ext.offered_qos_profiles]
               for c in r.connections}
        for conn, t, raw in r.messages():
            by_topic.setdefault(conn.topic, []).append((t, r.deserialize(raw, conn.msgtype)))
    return by_topic, qos


def _read_mcap_ros2(path):
    by_topic = {}
    with open(path, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _s, channel, message, decoded in reader.iter_decoded_messages(
                log_time_order=False):
            by_topic.setdefault(channel.topic, []).append((message.log_time, decoded))
    return by_topic


def test_simulate_recording_tf(tf_run, tmp_path):
    rb, qos = _read_rosbags(tf_run)
    mc = _read_mcap_ros2(tf_run)
    for topic in ('/axis/robot_description', '/tf_static', '/tf', '/axis/joint_states'):
        assert [t for t, _ in rb[topic]] == [t for t, _ in mc[topic]], topic
    assert qos['/axis/robot_description'] == qos['/tf_static'] == [('TRANSIENT_LOCAL', 1)]
    assert qos['/tf'] == [('VOLATILE', 100)]

    # axis/robot_description: the xacro rendering of the recorded axis, loadable by yourdfpy
    (t_desc, desc), = rb['/axis/robot_description']
    (_t, desc2), = mc['/axis/robot_description']
    assert t_desc == 0 and desc.data == desc2.data == D.render_urdf(
        D.xacro_args(load_preset('tr12x3'), 'x_'))
    robot = load_urdf(desc.data, tmp_path)
    assert robot.validate() and robot.base_link == 'x_base_link'

    # /tf_static: one message at t0 with the fixed joints, as yourdfpy places them
    (t_static, static), = rb['/tf_static']
    assert t_static == 0 and _tf_tuples(static) == _tf_tuples(mc['/tf_static'][0][1])
    (stamp, parent, child, tr, q), = _tf_tuples(static)
    assert (stamp, parent, child) == (0, 'x_base_link', 'x_motor_link')
    np.testing.assert_allclose(matrix(tr, q), robot.get_transform('x_motor_link', 'x_base_link'),
                               rtol=0, atol=TOL)

    # /tf: every tick, stamped and logged as its axis/joint_states, FK of its positions
    js, tfs, tfs2 = rb['/axis/joint_states'], rb['/tf'], mc['/tf']
    assert len(js) == len(tfs) == 300
    moved = 0
    for (t_js, m), (t_tf, msg), (_t2, msg2) in zip(js, tfs, tfs2):
        got = _tf_tuples(msg)
        assert got == _tf_tuples(msg2)
        assert t_tf == t_js and {g[0] for g in got} == {t_js}
        assert list(m.name) == ['x_screw_joint', 'x_nut_joint']
        angle, x = m.position
        set_cfg(robot, {'x_screw_joint': angle, 'x_nut_joint': x})
        assert [(g[1], g[2]) for g in got] == [('x_base_link', 'x_screw_link'),
                                               ('x_base_link', 'x_nut_link')]
        for _s, parent, child, tr, q in got:
            np.testing.assert_allclose(matrix(tr, q), robot.get_transform(child, parent),
                                       rtol=0, atol=TOL)
        moved += abs(angle) > 1.0
    assert moved > 100                                   # the screw did turn

    if MCAP_CLI.is_file():
        r = subprocess.run([str(MCAP_CLI), 'doctor', str(tf_run)], capture_output=True,
                           text=True, timeout=60)
        assert r.returncode == 0, r.stdout + r.stderr


def test_tick_order(tf_run):
    """Description first at t0; per tick the states, then /tf, then /clock."""
    with open(tf_run, 'rb') as f:
        seq = [(c.topic, m.log_time) for _s, c, m in make_reader(f).iter_messages(
            log_time_order=False)]
    ms = 1_000_000
    expected = [('/axis/robot_description', 0), ('/tf_static', 0)]
    for k in range(300):
        expected.append(('/torque_command', k * ms))
        expected += [(t, (k + 1) * ms) for t in ('/axis/joint_states', '/nut_position',
                                                 '/thread_force', '/sim/joint_states',
                                                 '/sim/thread_state', '/sim/ageing', '/tf',
                                                 '/clock')]
    assert seq == expected


def _raw(path, topic):
    with open(path, 'rb') as f:
        return [(m.log_time, m.data) for _s, _c, m in make_reader(f).iter_messages(
            topics=[topic], log_time_order=False)]


def test_resim_writes_the_same_description_and_tf(tf_run, tmp_path):
    """Per tick, resim writes the bytes simulate wrote block-wise; mcap doctor passes."""
    out = tmp_path / 'again.mcap'
    cli_ok('resim', tf_run, '--output', out, '--quiet')
    for topic in ('/axis/robot_description', '/tf_static', '/tf', '/axis/joint_states'):
        assert _raw(out, topic) == _raw(tf_run, topic), topic
    if MCAP_CLI.is_file():
        r = subprocess.run([str(MCAP_CLI), 'doctor', str(out)], capture_output=True,
                           text=True, timeout=60)
        assert r.returncode == 0, r.stdout + r.stderr


def test_run_writer_without_params_has_no_description(tmp_path):
    w = RunWriter(tmp_path / 'plain.mcap')
    assert w.tf is None and not {'robot_description', '/tf', '/tf_static'} & set(w.ids)
    w.write_description(0)
    w.write_tf(1, 0.0, 0.0)
    w.close()
    with open(tmp_path / 'plain.mcap', 'rb') as f:
        summary = make_reader(f).get_summary()
    assert summary.statistics.message_count == 0
    assert not {'/axis/robot_description', '/tf', '/tf_static'} & {
        c.topic for c in summary.channels.values()}
