"""
Serialized (CDR) messages of the lead screw axis: the one place that encodes them.

The node publishes and records, and the offline tools (``leadscrew_sim``
command line) write, the same bytes:

- :data:`TOPICS`: relative topic name -> (type, role, QoS);
- :class:`StateEncoder`: ``joint_states``, ``nut_position``, ``thread_force``
  and ``/clock`` from a stamp [ns] and values, or from a
  :class:`leadscrew_sim.model.StepOutput`;
- :func:`encode_float64` for the commands ``torque_command`` / ``external_force``;
- small decoders for the fixed-layout messages (:func:`decode_float64`,
  :func:`decode_joint_state`, :func:`decode_wrench_stamped`).

The encoders are plain ``struct`` code (no rclpy import): plain CDR (XCDR1),
little endian, padding bytes zero. ``rclpy.serialization.serialize_message``
gives the same bytes except in the padding (it leaves padding bytes
uninitialized) and possibly trailing garbage after the message;
``test/test_cli.py`` checks this field by field and byte by byte.
The node, simulate and resim all encode through :class:`StateEncoder`.
"""
import struct

import numpy as np

NS = 1_000_000_000

#: CDR encapsulation header: plain CDR, little endian, no options.
CDR_LE = b'\x00\x01\x00\x00'

#: Relative topic name -> (message type, role, QoS). All QoS: reliable, volatile,
#: keep last 10 (the node's COMMAND_QOS and STATE_QOS; joint_state_broadcaster
#: convention). '/clock' is absolute, as the node publishes it.
TOPICS = {
    'torque_command': ('std_msgs/msg/Float64', 'command',
                       dict(reliability='reliable', durability='volatile', depth=10)),
    'joint_commands': ('sensor_msgs/msg/JointState', 'command',
                       dict(reliability='reliable', durability='volatile', depth=10)),
    'external_force': ('std_msgs/msg/Float64', 'command',
                       dict(reliability='reliable', durability='volatile', depth=10)),
    'joint_states': ('sensor_msgs/msg/JointState', 'state',
                     dict(reliability='reliable', durability='volatile', depth=10)),
    'nut_position': ('std_msgs/msg/Float64', 'state',
                     dict(reliability='reliable', durability='volatile', depth=10)),
    'thread_force': ('geometry_msgs/msg/WrenchStamped', 'state',
                     dict(reliability='reliable', durability='volatile', depth=10)),
    '/clock': ('rosgraph_msgs/msg/Clock', 'clock',
               dict(reliability='reliable', durability='volatile', depth=10)),
}

#: Topics in the order the node registers its recording channels.
COMMAND_TOPICS = ('torque_command', 'joint_commands', 'external_force')
STATE_TOPICS = ('joint_states', 'nut_position', 'thread_force')

_D = struct.Struct('<d')
_STAMP = struct.Struct('<iI')


def resolve(topic, namespace='/'):
    """Return the resolved name of a relative topic in ``namespace`` (``'/'`` default)."""
    if topic.startswith('/'):
        return topic
    ns = namespace.rstrip('/')
    return f'{ns}/{topic}'


def split_stamp(stamp_ns):
    """Return (sec, nanosec) of an integer nanosecond time (floor division)."""
    return divmod(int(stamp_ns), NS)


class _CdrWriter:
    """Append-only plain CDR (little endian) with alignment relative to the payload."""

    def __init__(self):
        self.buf = bytearray(CDR_LE)

    def _align(self, n):
        pad = (-(len(self.buf) - 4)) % n
        self.buf += b'\x00' * pad

    def u32(self, v):
        self._align(4)
        self.buf += struct.pack('<I', v)

    def stamp(self, sec, nsec):
        self._align(4)
        off = len(self.buf)
        self.buf += _STAMP.pack(sec, nsec)
        return off

    def string(self, s):
        raw = s.encode('utf-8') + b'\x00'
        self.u32(len(raw))
        self.buf += raw

    def f64(self, v):
        self._align(8)
        off = len(self.buf)
        self.buf += _D.pack(v)
        return off

    def f64_seq(self, values):
        self.u32(len(values))
        offs = []
        for v in values:
            offs.append(self.f64(v))
        return offs


class _Template:
    """A fixed-layout message: a byte template with the stamp and double offsets."""

    __slots__ = ('tmpl', 'stamp_off', 'offsets', 'buf')

    def __init__(self, raw, stamp_off, offsets):
        self.tmpl = bytes(raw)
        self.stamp_off = stamp_off
        self.offsets = tuple(offsets)
        self.buf = bytearray(raw)

    def __call__(self, stamp_ns, values):
        buf = self.buf
        if self.stamp_off is not None:
            sec, nsec = divmod(stamp_ns, NS)
            _STAMP.pack_into(buf, self.stamp_off, sec, nsec)
        for off, v in zip(self.offsets, values):
            _D.pack_into(buf, off, v)
        return bytes(buf)

    def rows(self, stamps_ns, columns):
        """
        Return n messages at once as a uint8 array of shape (n, message length).

        ``stamps_ns``: int array (n,) of stamps [ns] (ignored for stamp-less
        types); ``columns``: one float array (n,) per value, in the order of
        ``__call__``. Row k equals ``self(stamps_ns[k], [c[k] for c in columns])``.
        """
        n = len(columns[0]) if columns else len(stamps_ns)
        out = np.empty((n, len(self.tmpl)), dtype=np.uint8)
        out[:] = np.frombuffer(self.tmpl, dtype=np.uint8)
        if self.stamp_off is not None:
            sec, nsec = np.divmod(np.asarray(stamps_ns, dtype=np.int64), NS)
            if n and not (-2**31 <= sec.min() and sec.max() < 2**31):
                raise ValueError('stamps must lie within the int32 range of seconds')
            stamp = np.empty((n, 2), dtype='<u4')
            stamp[:, 0] = sec.astype('<i4').view('<u4')
            stamp[:, 1] = nsec
            out[:, self.stamp_off:self.stamp_off + 8] = stamp.view(np.uint8)
        for off, col in zip(self.offsets, columns):
            out[:, off:off + 8] = np.ascontiguousarray(col, dtype='<f8').view(
                np.uint8).reshape(n, 8)
        return out


def _joint_state_template(names, n_pos, n_vel, n_eff):
    w = _CdrWriter()
    stamp_off = w.stamp(0, 0)
    w.string('')                       # frame_id
    w.u32(len(names))
    for n in names:
        w.string(n)
    offs = w.f64_seq([0.0] * n_pos) + w.f64_seq([0.0] * n_vel) + w.f64_seq([0.0] * n_eff)
    return _Template(w.buf, stamp_off, offs)


def _wrench_template():
    w = _CdrWriter()
    stamp_off = w.stamp(0, 0)
    w.string('')
    offs = [w.f64(0.0) for _ in range(6)]        # force xyz, torque xyz
    return _Template(w.buf, stamp_off, (offs[0], offs[3]))


def _float64_template():
    w = _CdrWriter()
    return _Template(w.buf, None, [w.f64(0.0)])


def _clock_template():
    w = _CdrWriter()
    return _Template(w.buf, w.stamp(0, 0), [])


_F64 = _float64_template()
#: The std_msgs/Float64 template (``F64_TEMPLATE.rows`` encodes many at once).
F64_TEMPLATE = _F64


def encode_float64(value):
    """Return the CDR bytes of a std_msgs/Float64 with ``data = value``."""
    return _F64(None, (value,))


def encode_joint_state(stamp_ns, names, position=(), velocity=(), effort=()):
    """Return the CDR bytes of a sensor_msgs/JointState (empty frame_id)."""
    t = _joint_state_template(list(names), len(position), len(velocity), len(effort))
    return t(int(stamp_ns), tuple(position) + tuple(velocity) + tuple(effort))


class StateEncoder:
    """
    Encode the states of one tick, as the node publishes and records them.

    Joint names are ``<joint_prefix>screw_joint`` and ``<joint_prefix>nut_joint``.
    Each method takes ``(stamp_ns, values)`` like the node's serializers:

    - ``joint_states(stamp, (screw_angle, nut_position, screw_velocity,
      nut_velocity, motor_torque, axial_force))``;
    - ``nut_position(stamp_or_None, (x,))``;
    - ``thread_force(stamp, (axial_force, thread_torque))``;
    - ``clock(stamp, ())``.

    Stamps are integer nanoseconds >= 0 (sec fits int32).
    """

    def __init__(self, joint_prefix=''):
        """Build the byte templates for the joint names of ``joint_prefix``."""
        self.joint_prefix = joint_prefix
        self.joint_names = (joint_prefix + 'screw_joint', joint_prefix + 'nut_joint')
        self.joint_states = _joint_state_template(self.joint_names, 2, 2, 2)
        self.nut_position = _float64_template()
        self.thread_force = _wrench_template()
        self.clock = _clock_template()

    @staticmethod
    def values(o):
        """Return the value tuples (joint_states, nut_position, thread_force) of a StepOutput."""
        return ((o.screw_angle, o.nut_position, o.screw_velocity, o.nut_velocity,
                 o.motor_torque, o.axial_force), (o.nut_position,),
                (o.axial_force, o.thread_torque))

    def encode(self, stamp_ns, o):
        """Return the bytes of (joint_states, nut_position, thread_force) for a StepOutput."""
        js, x, wr = self.values(o)
        return (self.joint_states(stamp_ns, js), self.nut_position(None, x),
                self.thread_force(stamp_ns, wr))


# ---------------------------------------------------------------------------
# Decoding (fixed layouts; plain CDR, either endianness)
# ---------------------------------------------------------------------------

class DecodeError(ValueError):
    """Bytes that are not a valid CDR message of the expected type."""


class _CdrReader:
    def __init__(self, data):
        if len(data) < 4 or data[0] != 0 or data[1] not in (0, 1):
            raise DecodeError('not plain CDR')
        self.data = data
        self.e = '<' if data[1] else '>'
        self.pos = 4

    def _align(self, n):
        self.pos += (-(self.pos - 4)) % n

    def _take(self, fmt, size, align):
        self._align(align)
        try:
            v = struct.unpack_from(self.e + fmt, self.data, self.pos)
        except struct.error:
            raise DecodeError('message too short') from None
        self.pos += size
        return v

    def u32(self):
        return self._take('I', 4, 4)[0]

    def stamp(self):
        sec, nsec = self._take('iI', 8, 4)
        return sec * NS + nsec

    def string(self):
        n = self.u32()
        raw = self.data[self.pos:self.pos + n]
        if n == 0 or len(raw) != n:
            raise DecodeError('bad string')
        self.pos += n
        return bytes(raw[:-1]).decode('utf-8', 'replace')

    def f64(self):
        return self._take('d', 8, 8)[0]

    def f64_seq(self):
        n = self.u32()
        if n > (len(self.data) - self.pos) // 8:
            raise DecodeError('sequence longer than the message')
        if n == 0:
            return ()
        return self._take(f'{n}d', 8 * n, 8)


def decode_float64(data):
    """Return the ``data`` field of a serialized std_msgs/Float64."""
    return _CdrReader(data).f64()


def decode_joint_state(data):
    """Return (stamp_ns, names, position, velocity, effort) of a serialized JointState."""
    r = _CdrReader(data)
    stamp = r.stamp()
    r.string()
    n = r.u32()
    if n > len(data):
        raise DecodeError('bad name count')
    names = [r.string() for _ in range(n)]
    return stamp, names, r.f64_seq(), r.f64_seq(), r.f64_seq()


def decode_wrench_stamped(data):
    """Return (stamp_ns, (fx, fy, fz), (tx, ty, tz)) of a serialized WrenchStamped."""
    r = _CdrReader(data)
    stamp = r.stamp()
    r.string()
    v = [r.f64() for _ in range(6)]
    return stamp, tuple(v[:3]), tuple(v[3:])
