"""
TF (tf2_msgs/msg/TFMessage) and std_msgs/String in CDR, without tf2_msgs.

tf2_msgs has no PyPI wheel, so neither rclpy nor the share directory knows
TFMessage. Its own one-line ``.msg`` text and its RIHS01 type hash live in
:data:`leadscrew_sim.io.msgdefs.EMBEDDED` / ``EMBEDDED_HASHES``; the texts of
its dependencies (geometry_msgs, std_msgs, builtin_interfaces) come from the
installed ``.msg`` files. So ``McapRecorder.add_channel('/tf',
'tf2_msgs/msg/TFMessage')`` writes the full rosbag2-style schema like for any
installed type, and :func:`tfmessage_type_hash` recomputes the hash with
rosidl's algorithm from the installed type descriptions.

A transform is ``(stamp_ns, parent_frame, child_frame, (tx, ty, tz),
(qx, qy, qz, qw))``: integer nanoseconds, frame names, translation [m] and
rotation quaternion (encoded as given, not normalized).
"""
import copy
import hashlib
import json
import os
import struct

import numpy as np

from .cdr import CdrReader, CdrWriter, DecodeError, NS, split_stamp, stamp_rows
from .msgdefs import EMBEDDED, ros2msg_definition, share_directory
from .record_fill import EncodedRows

TFMESSAGE_TYPE = 'tf2_msgs/msg/TFMessage'
STRING_TYPE = 'std_msgs/msg/String'

#: The verbatim ``tf2_msgs/msg/TFMessage.msg`` (ros2/geometry2, jazzy).
TFMESSAGE_TEXT = EMBEDDED[TFMESSAGE_TYPE]

#: ``qos_profile_yaml`` keywords of tf2_ros' broadcasters and robot_state_publisher:
#: ``/tf`` reliable, volatile, keep last 100; ``/tf_static`` and ``/robot_description``
#: reliable, transient local, keep last 1.
TF_QOS = {'reliability': 'reliable', 'durability': 'volatile', 'depth': 100}
TF_STATIC_QOS = {'reliability': 'reliable', 'durability': 'transient_local', 'depth': 1}
ROBOT_DESCRIPTION_QOS = dict(TF_STATIC_QOS)

#: Doubles per transform: translation x, y, z, rotation x, y, z, w.
VALUES_PER_FRAME = 7

_STAMP = struct.Struct('<iI')
_TQ = struct.Struct('<7d')

# type_id of a field ``Type[] name`` (FIELD_TYPE_NESTED_TYPE_UNBOUNDED_SEQUENCE).
_NESTED_UNBOUNDED_SEQUENCE = 145


def tfmessage_definition():
    """Return the full ``ros2msg`` definition of tf2_msgs/msg/TFMessage as rosbag2 writes it."""
    return ros2msg_definition(TFMESSAGE_TYPE)


def rihs01(type_description_msg):
    """
    Return the RIHS01 hash string of a full type description (rosidl's algorithm).

    ``type_description_msg`` is ``{'type_description': ..., 'referenced_type_descriptions':
    [...]}`` as in the installed ``.json`` files: the ``default_value`` of every field is
    dropped, the rest dumped as compact JSON (``', '`` and ``': '`` separators, keys in
    order) and hashed with SHA-256.
    """
    full = copy.deepcopy(type_description_msg)
    for td in [full['type_description']] + list(full['referenced_type_descriptions']):
        for field in td['fields']:
            field.pop('default_value', None)
    text = json.dumps(full, ensure_ascii=True, allow_nan=False, indent=None,
                      separators=(', ', ': '), sort_keys=False)
    return 'RIHS01_' + hashlib.sha256(text.encode('utf-8')).hexdigest()


def tfmessage_type_description():
    """
    Return the full type description of tf2_msgs/msg/TFMessage.

    Built from the installed ``geometry_msgs/msg/TransformStamped.json`` plus the one
    field ``geometry_msgs/TransformStamped[] transforms``; referenced types sorted by
    name, as rosidl_generator_type_description orders them.
    """
    path = os.path.join(share_directory('geometry_msgs'), 'msg', 'TransformStamped.json')
    with open(path, encoding='utf-8') as f:
        stamped = json.load(f)['type_description_msg']
    referenced = [stamped['type_description']] + stamped['referenced_type_descriptions']
    return {
        'type_description': {'type_name': TFMESSAGE_TYPE, 'fields': [{
            'name': 'transforms',
            'type': {'type_id': _NESTED_UNBOUNDED_SEQUENCE, 'capacity': 0,
                     'string_capacity': 0,
                     'nested_type_name': 'geometry_msgs/msg/TransformStamped'},
            'default_value': ''}]},
        'referenced_type_descriptions': sorted(referenced, key=lambda td: td['type_name']),
    }


def tfmessage_type_hash():
    """Return the RIHS01 type hash of tf2_msgs/msg/TFMessage, computed from the descriptions."""
    return rihs01(tfmessage_type_description())


def _frame_name(name):
    name = str(name)
    if '\x00' in name:
        raise ValueError(f'frame name {name!r} contains a NUL character')
    return name


def _stamp(stamp_ns):
    sec, nsec = split_stamp(stamp_ns)
    if not -2**31 <= sec < 2**31:
        raise ValueError(f'stamp {stamp_ns!r} ns lies outside the int32 range of seconds')
    return sec, nsec


def _vector(values, n, what):
    values = tuple(float(v) for v in values)
    if len(values) != n:
        raise ValueError(f'{what} needs {n} values, not {len(values)}')
    return values


def encode_tf_message(transforms):
    """
    Return the CDR bytes of a tf2_msgs/msg/TFMessage.

    ``transforms``: iterable of ``(stamp_ns, parent_frame, child_frame, (tx, ty, tz),
    (qx, qy, qz, qw))``; each becomes one geometry_msgs/TransformStamped with
    ``header.frame_id = parent_frame``.
    """
    items = list(transforms)
    w = CdrWriter()
    w.u32(len(items))
    for stamp_ns, parent, child, translation, rotation in items:
        w.stamp(*_stamp(stamp_ns))
        w.string(_frame_name(parent))
        w.string(_frame_name(child))
        for v in _vector(translation, 3, 'translation') + _vector(rotation, 4, 'rotation'):
            w.f64(v)
    return bytes(w.buf)


def decode_tf_message(data):
    """Return the transforms of a serialized TFMessage (the form of :func:`encode_tf_message`)."""
    r = CdrReader(data)
    n = r.u32()
    if n > len(data) // 64:                 # a transform takes at least 64 bytes
        raise DecodeError('bad transform count')
    out = []
    for _ in range(n):
        stamp = r.stamp()
        parent, child = r.string(), r.string()
        v = [r.f64() for _ in range(VALUES_PER_FRAME)]
        out.append((stamp, parent, child, tuple(v[:3]), tuple(v[3:])))
    return out


class TfEncoder:
    """
    The TFMessage of a fixed frame set as a byte template; stamp and doubles patched in.

    ``frames``: sequence of ``(parent_frame, child_frame)``. All transforms of one
    message carry the same stamp. ``values`` are the 7 doubles of each frame in turn
    (tx, ty, tz, qx, qy, qz, qw of the first frame, then of the second, ...).
    """

    __slots__ = ('frames', 'tmpl', 'stamp_offsets', 'offsets', '_buf')

    def __init__(self, frames):
        """Lay out the message of ``frames`` (pairs of parent and child frame names)."""
        self.frames = tuple((_frame_name(p), _frame_name(c)) for p, c in frames)
        w = CdrWriter()
        w.u32(len(self.frames))
        stamps, offsets = [], []
        for parent, child in self.frames:
            stamps.append(w.stamp(0, 0))
            w.string(parent)
            w.string(child)
            offs = [w.f64(0.0) for _ in range(VALUES_PER_FRAME - 1)] + [w.f64(1.0)]
            assert offs == list(range(offs[0], offs[0] + 8 * VALUES_PER_FRAME, 8))
            offsets.append(offs[0])
        self.tmpl = bytes(w.buf)
        #: Byte offsets of each frame's header.stamp and of its first double.
        self.stamp_offsets = tuple(stamps)
        self.offsets = tuple(offsets)
        self._buf = bytearray(self.tmpl)

    @property
    def n_values(self):
        """Return the number of doubles of one message (7 per frame)."""
        return VALUES_PER_FRAME * len(self.frames)

    def __len__(self):
        """Return the message length [bytes]."""
        return len(self.tmpl)

    def __call__(self, stamp_ns, values):
        """Return the message bytes with this stamp [ns] on every transform and these doubles."""
        if len(values) != self.n_values:
            raise ValueError(f'{self.n_values} values needed, not {len(values)}')
        sec, nsec = divmod(int(stamp_ns), NS)
        buf = self._buf
        try:
            k = 0
            for s_off, v_off in zip(self.stamp_offsets, self.offsets):
                _STAMP.pack_into(buf, s_off, sec, nsec)
                _TQ.pack_into(buf, v_off, *values[k:k + VALUES_PER_FRAME])
                k += VALUES_PER_FRAME
        except struct.error as exc:
            raise ValueError(f'cannot encode stamp {stamp_ns!r} ns or values: {exc}') from None
        return bytes(buf)

    def rows(self, stamps_ns, columns):
        """
        Return n messages at once as a uint8 array of shape (n, message length).

        ``stamps_ns``: int array (n,) [ns]; ``columns``: one float array (n,) per value,
        in the order of ``__call__``. Row k equals
        ``self(stamps_ns[k], [c[k] for c in columns])``.
        """
        if len(columns) != self.n_values:
            raise ValueError(f'{self.n_values} columns needed, not {len(columns)}')
        stamp = stamp_rows(stamps_ns)
        n = len(stamp)
        out = np.empty((n, len(self.tmpl)), dtype=np.uint8)
        out[:] = np.frombuffer(self.tmpl, dtype=np.uint8)
        values = np.empty((n, VALUES_PER_FRAME), dtype='<f8')
        for k, (s_off, v_off) in enumerate(zip(self.stamp_offsets, self.offsets)):
            out[:, s_off:s_off + 8] = stamp
            for j in range(VALUES_PER_FRAME):
                values[:, j] = columns[VALUES_PER_FRAME * k + j]
            out[:, v_off:v_off + 8 * VALUES_PER_FRAME] = values.view(np.uint8).reshape(
                n, 8 * VALUES_PER_FRAME)
        return out


def tf_encoded(encoder, stamps_ns, columns):
    """
    Return the /tf messages of n ticks as EncodedRows (the bytes of ``encoder.rows``).

    Parameters
    ----------
    encoder : TfEncoder
        The layout.
    stamps_ns : numpy.ndarray of int64
        One stamp per tick [ns], on every transform.
    columns : list of numpy.ndarray
        One float array (n,) per value, in the order of ``encoder.rows``.

    """
    if len(columns) != encoder.n_values:
        raise ValueError(f'{encoder.n_values} columns needed, not {len(columns)}')
    offsets = [v + 8 * j for v in encoder.offsets for j in range(VALUES_PER_FRAME)]
    return EncodedRows(encoder.tmpl, encoder.stamp_offsets, offsets, stamps_ns, columns)


def encode_string(text):
    """Return the CDR bytes of a std_msgs/msg/String with ``data = text``."""
    w = CdrWriter()
    w.string(str(text))
    return bytes(w.buf)


def decode_string(data):
    """Return the ``data`` field of a serialized std_msgs/msg/String."""
    return CdrReader(data).string()
