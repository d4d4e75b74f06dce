"""
TF and robot description in recordings: TFMessage / String CDR checked by independent readers.

tf2_msgs is not installed; its definition text (embedded own text plus the
installed dependencies) must be accepted by rosbags and mcap_ros2, its RIHS01
hash must agree with rosbags' computation, and every encoded field must come
back bit for bit.
"""
import json
import math
from pathlib import Path
import random
import subprocess

from helpers import NS, SHARED
from leadscrew_sim.io import msgdefs, tf
from leadscrew_sim.io.mcap_file import McapRecorder
from leadscrew_sim.io.qos import qos_profile_yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, get_types_from_msg, Stores

MCAP_CLI = SHARED / 'mcap-cli' / 'mcap'
SEP = '\n' + '=' * 80 + '\n'
#: TFMessage's dependencies in the order msgdefs (and rosbag2) writes them: each file's
#: dependencies sorted, depth first.
DEPENDENCIES = ['geometry_msgs/TransformStamped', 'geometry_msgs/Transform',
                'geometry_msgs/Quaternion', 'geometry_msgs/Vector3', 'std_msgs/Header',
                'builtin_interfaces/Time']
#: The hash in rosidl-generated code for tf2_msgs/msg/TFMessage (jazzy builds).
TFMESSAGE_RIHS01 = 'RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087'
URDF = ('<?xml version="1.0"?>\n<robot name="leadscrew_axis">\n'
        '  <!-- Gewindespindel, Mutter: non-ASCII text -->\n'
        '  <link name="world"/>\n  <link name="screw"/>\n  <link name="nut"/>\n</robot>\n')


def _frame(rng):
    """Return a random frame name of 1..22 bytes (all string paddings occur)."""
    chars = 'abcdefghijklmnopqrstuvwxyz_/0123456789'
    name = ''.join(rng.choice(chars) for _ in range(rng.randint(1, 20)))
    return name + ('ü' if rng.random() < 0.2 else '')


def _unit_quaternion(rng):
    q = [rng.gauss(0.0, 1.0) for _ in range(4)]
    n = math.sqrt(sum(v * v for v in q))
    return tuple(v / n for v in q)


def _transform(rng, stamp_ns=None):
    if stamp_ns is None:
        stamp_ns = rng.randrange(-5 * NS, 2**31 * NS)
    return (stamp_ns, _frame(rng), _frame(rng),
            tuple(rng.uniform(-2.0, 2.0) for _ in range(3)), _unit_quaternion(rng))


def _typestore_from(definition, msg_type):
    """Return an EMPTY rosbags typestore holding only the types parsed from ``definition``."""
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(definition, msg_type))
    return store


def _as_tuples(msg):
    """Return the transforms of a decoded TFMessage (rosbags or mcap_ros2) as tuples."""
    out = []
    for t in msg.transforms:
        stamp = t.header.stamp.sec * NS + t.header.stamp.nanosec
        tr, q = t.transform.translation, t.transform.rotation
        out.append((stamp, t.header.frame_id, t.child_frame_id,
                    (tr.x, tr.y, tr.z), (q.x, q.y, q.z, q.w)))
    return out


def _same(got, expected):
    """Assert equal transforms, doubles compared bit for bit (also -0.0)."""
    assert len(got) == len(expected)
    for g, e in zip(got, expected):
        assert g[:3] == e[:3]
        assert np.array_equal(np.array(g[3] + g[4]).view('<u8'),
                              np.array(e[3] + e[4], dtype=float).view('<u8'))


def test_definition_text_is_rosbag2_style_from_installed_files():
    text = tf.tfmessage_definition()
    parts = text.split(SEP)
    assert parts[0] == tf.TFMESSAGE_TEXT == 'geometry_msgs/TransformStamped[] transforms\n'
    headers = [p.split('\n', 1)[0] for p in parts[1:]]
    assert headers == ['MSG: ' + d for d in DEPENDENCIES]
    for dep, part in zip(DEPENDENCIES, parts[1:]):
        body = part.split('\n', 1)[1]
        assert body == msgdefs.msg_text(dep)           # verbatim installed .msg
        pkg, name = dep.split('/')
        path = Path(msgdefs.share_directory(pkg)) / 'msg' / f'{name}.msg'
        assert body == path.read_bytes().decode('utf-8')
        types = get_types_from_msg(body, f'{pkg}/msg/{name}')   # each part parses alone
        assert f'{pkg}/msg/{name}' in types
    assert msgdefs.ros2msg_definition('tf2_msgs/TFMessage') == text
    types = get_types_from_msg(text, tf.TFMESSAGE_TYPE)
    assert set(types) == {tf.TFMESSAGE_TYPE} | {d.replace('/', '/msg/') for d in DEPENDENCIES}
    assert msgdefs.msg_fields(tf.TFMESSAGE_TYPE) == (
        ('geometry_msgs/msg/TransformStamped', 'seq'),)


def test_type_hash_is_rosidl_rihs01():
    # The algorithm reproduces installed hashes ...
    for msg_type in ('geometry_msgs/msg/TransformStamped', 'sensor_msgs/msg/JointState',
                     'std_msgs/msg/String', 'diagnostic_msgs/msg/DiagnosticArray'):
        pkg, _, name = msg_type.split('/')
        path = Path(msgdefs.share_directory(pkg)) / 'msg' / f'{name}.json'
        desc = json.loads(path.read_text())
        assert tf.rihs01(desc['type_description_msg']) == msgdefs.type_hash(msg_type) != ''
    # ... and gives TFMessage the hash of rosidl-generated code, of rosbags' computation
    # from OUR definition text, and of rosbags' built-in jazzy store.
    assert tf.tfmessage_type_hash() == TFMESSAGE_RIHS01
    assert msgdefs.type_hash(tf.TFMESSAGE_TYPE) == TFMESSAGE_RIHS01
    ours = _typestore_from(tf.tfmessage_definition(), tf.TFMESSAGE_TYPE)
    assert ours.hash_rihs01(tf.TFMESSAGE_TYPE) == TFMESSAGE_RIHS01
    assert get_typestore(Stores.ROS2_JAZZY).hash_rihs01(tf.TFMESSAGE_TYPE) == TFMESSAGE_RIHS01


def test_cdr_bytes_equal_rosbags_serialization():
    rng = random.Random(7)
    store = _typestore_from(tf.tfmessage_definition(), tf.TFMESSAGE_TYPE)
    T = store.types
    for n in (0, 1, 2, 3, 5, 8):
        transforms = [_transform(rng) for _ in range(n)]
        data = tf.encode_tf_message(transforms)
        msg = T[tf.TFMESSAGE_TYPE](transforms=[
            T['geometry_msgs/msg/TransformStamped'](
                header=T['std_msgs/msg/Header'](
                    stamp=T['builtin_interfaces/msg/Time'](*divmod(s, NS)), frame_id=p),
                child_frame_id=c,
                transform=T['geometry_msgs/msg/Transform'](
                    translation=T['geometry_msgs/msg/Vector3'](*tr),
                    rotation=T['geometry_msgs/msg/Quaternion'](*q)))
            for s, p, c, tr, q in transforms])
        assert bytes(store.serialize_cdr(msg, tf.TFMESSAGE_TYPE)) == data
        _same(_as_tuples(store.deserialize_cdr(data, tf.TFMESSAGE_TYPE)), transforms)
        _same(tf.decode_tf_message(data), transforms)
        assert msgdefs.cdr_length(tf.TFMESSAGE_TYPE, data + b'\xff' * 9) == len(data)
    string_store = _typestore_from(msgdefs.ros2msg_definition('std_msgs/msg/String'),
                                   'std_msgs/msg/String')
    s = string_store.types['std_msgs/msg/String']
    for text in ('', 'a', URDF, 'x' * 1001):
        data = tf.encode_string(text)
        assert bytes(string_store.serialize_cdr(s(data=text), 'std_msgs/msg/String')) == data
        assert tf.decode_string(data) == text


def test_tf_encoder_matches_the_general_encoder():
    rng = random.Random(3)
    frames = [(_frame(rng), _frame(rng)) for _ in range(4)]
    enc = tf.TfEncoder(frames)
    assert enc.n_values == 28 and len(enc) == len(enc.tmpl)
    stamps = np.array([0, 1, NS - 1, 1_700_000_000_123_456_789, -3 * NS + 5, 2**31 * NS - 1])
    values = np.array([[rng.uniform(-1, 1) for _ in range(28)] for _ in stamps])
    values[0, :] = -0.0
    rows = enc.rows(stamps, [values[:, j] for j in range(28)])
    assert rows.shape == (len(stamps), len(enc))
    for k, stamp in enumerate(stamps):
        expected = [(int(stamp), p, c, tuple(values[k, 7 * i:7 * i + 3]),
                     tuple(values[k, 7 * i + 3:7 * i + 7])) for i, (p, c) in enumerate(frames)]
        data = tf.encode_tf_message(expected)
        assert enc(int(stamp), list(values[k])) == data == bytes(rows[k])
        _same(tf.decode_tf_message(data), expected)
    assert tf.TfEncoder([])(5, []) == tf.encode_tf_message([])
    with pytest.raises(ValueError):
        enc(0, [0.0] * 27)
    with pytest.raises(ValueError):
        enc(2**31 * NS, [0.0] * 28)
    with pytest.raises(ValueError):
        enc.rows(stamps[:1], [values[:1, 0]] * 27)
    with pytest.raises(ValueError):
        enc.rows(np.array([2**31 * NS]), [np.zeros(1)] * 28)
    with pytest.raises(ValueError):
        tf.TfEncoder([('a\x00', 'b')])
    with pytest.raises(ValueError):
        tf.encode_tf_message([(0, 'a', 'b', (1.0, 2.0), (0.0, 0.0, 0.0, 1.0))])


@pytest.fixture
def tf_recording(tmp_path):
    """Write /robot_description, /tf_static and /tf (written singly and as rows)."""
    rng = random.Random(11)
    path = tmp_path / 'tf.mcap'
    latched = qos_profile_yaml(**tf.TF_STATIC_QOS)
    rec = McapRecorder(path, flush_interval=0.05, chunk_size=2048)
    ids = {'/robot_description': rec.add_channel('/robot_description', 'std_msgs/msg/String',
                                                 qos_profile_yaml(**tf.ROBOT_DESCRIPTION_QOS)),
           '/tf_static': rec.add_channel('/tf_static', tf.TFMESSAGE_TYPE, latched),
           '/tf': rec.add_channel('/tf', 'tf2_msgs/TFMessage', qos_profile_yaml(**tf.TF_QOS))}
    t0 = 1_700_000_000 * NS
    static = [_transform(rng) for _ in range(3)]
    rec.write(ids['/robot_description'], tf.encode_string(URDF), t0)
    rec.write(ids['/tf_static'], tf.encode_tf_message(static), t0)
    expected = {'/robot_description': [(t0, URDF)], '/tf_static': [(t0, static)], '/tf': []}
    frames = [(_frame(rng), _frame(rng)) for _ in range(2)]
    enc = tf.TfEncoder(frames)
    for k in range(40):                          # varying frame sets, written singly
        t = t0 + (k + 1) * 1_000_000
        msg = [_transform(rng, t) for _ in range(rng.randint(1, 4))]
        rec.write(ids['/tf'], tf.encode_tf_message(msg) + bytes(k % 3), t)    # trimmed
        expected['/tf'].append((t, msg))
    n = 60                                       # fixed frame set, as rows
    stamps = t0 + 100_000_000 + np.arange(n, dtype=np.int64) * 1_000_000
    columns = []
    for _ in frames:
        columns += [np.array([rng.uniform(-1, 1) for _ in range(n)]) for _ in range(3)]
        qs = np.array([_unit_quaternion(rng) for _ in range(n)])
        columns += [qs[:, j] for j in range(4)]
    rec.write_rows([ids['/tf']], [enc.rows(stamps, columns)], [stamps])
    for k, t in enumerate(stamps):
        expected['/tf'].append((int(t), [
            (int(t), p, c, tuple(float(columns[7 * i + j][k]) for j in range(3)),
             tuple(float(columns[7 * i + j][k]) for j in range(3, 7)))
            for i, (p, c) in enumerate(frames)]))
    rec.close()
    assert rec.error is None and rec.messages_written == 2 + 40 + n
    return path, expected


def _check(by_topic, expected):
    assert set(by_topic) == set(expected)
    assert by_topic['/robot_description'] == expected['/robot_description']
    for topic in ('/tf_static', '/tf'):
        got, exp = by_topic[topic], expected[topic]
        assert [t for t, _ in got] == [t for t, _ in exp]
        for (_, g), (_, e) in zip(got, exp):
            _same(g, e)


def test_recording_read_by_mcap_ros2(tf_recording):
    path, expected = tf_recording
    by_topic = {}
    with open(path, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        for schema, channel, message, msg in reader.iter_decoded_messages(log_time_order=True):
            assert schema.encoding == 'ros2msg' and channel.message_encoding == 'cdr'
            value = msg.data if channel.topic == '/robot_description' else _as_tuples(msg)
            by_topic.setdefault(channel.topic, []).append((message.log_time, value))
    _check(by_topic, expected)
    schemas = {s.name: s for s in summary.schemas.values()}
    assert set(schemas) == {'std_msgs/msg/String', tf.TFMESSAGE_TYPE}
    assert schemas[tf.TFMESSAGE_TYPE].data == tf.tfmessage_definition().encode()
    meta = {c.topic: c.metadata for c in summary.channels.values()}
    assert meta['/tf']['topic_type_hash'] == meta['/tf_static']['topic_type_hash'] == \
        TFMESSAGE_RIHS01
    assert meta['/robot_description']['topic_type_hash'] == \
        msgdefs.type_hash('std_msgs/msg/String') != ''


def test_recording_read_by_rosbags(tf_recording):
    path, expected = tf_recording
    by_topic = {}
    with AnyReader([path]) as reader:
        # AnyReader builds its typestore only from the file's schema texts.
        assert tf.TFMESSAGE_TYPE not in get_typestore(Stores.EMPTY).types
        assert reader.typestore.hash_rihs01(tf.TFMESSAGE_TYPE) == TFMESSAGE_RIHS01
        durability = {c.topic: c.ext.offered_qos_profiles[0].durability.name
                      for c in reader.connections}
        for conn, t, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            value = msg.data if conn.topic == '/robot_description' else _as_tuples(msg)
            by_topic.setdefault(conn.topic, []).append((t, value))
    assert durability == {'/robot_description': 'TRANSIENT_LOCAL',
                          '/tf_static': 'TRANSIENT_LOCAL', '/tf': 'VOLATILE'}
    _check(by_topic, expected)


@pytest.mark.skipif(not MCAP_CLI.exists(), reason='no mcap CLI in ../shared/mcap-cli')
def test_recording_passes_mcap_doctor(tf_recording):
    path, _ = tf_recording
    proc = subprocess.run([str(MCAP_CLI), 'doctor', str(path)], capture_output=True,
                          text=True, timeout=60)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out
    assert 'error' not in out.lower(), out
