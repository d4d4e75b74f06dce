"""
CDR (XCDR1, the ROS 2 default) encoding and decoding, with one alignment rule.

Plain ``struct`` code, no rclpy: the node, the offline tools and the recorder
all write the same bytes. Encoding is little endian with zero padding;
``rclpy.serialization.serialize_message`` gives the same bytes except in the
padding, which it leaves uninitialized. Fixed-layout messages are encoded
from a byte :class:`Template` with the stamp and doubles patched in.
"""
import struct

import numpy as np
from ..core.errors import LeadscrewError

NS = 1_000_000_000

#: CDR encapsulation header: plain CDR, little endian, no options.
CDR_LE = b'\x00\x01\x00\x00'

_D = struct.Struct('<d')
_STAMP = struct.Struct('<iI')


def padding(pos, n):
    """
    Return the padding [bytes] before an item of alignment ``n`` at byte ``pos``.

    CDR aligns relative to the payload, which starts after the 4-byte
    encapsulation header. The one rule of the writer, the reader and
    :func:`leadscrew_sim.io.msgdefs.cdr_length`.
    """
    return (-(pos - 4)) % n


def split_stamp(stamp_ns):
    """Return (sec, nanosec) of an integer nanosecond time (floor division)."""
    return divmod(int(stamp_ns), NS)


class CdrWriter:
    """Append-only plain CDR (little endian), padding bytes zero; methods return offsets."""

    def __init__(self):
        """Start a message with the encapsulation header."""
        self.buf = bytearray(CDR_LE)

    def _align(self, n):
        self.buf += b'\x00' * padding(len(self.buf), n)

    def u32(self, v):
        """Append a uint32."""
        self._align(4)
        self.buf += struct.pack('<I', v)

    def stamp(self, sec, nsec):
        """Append a builtin_interfaces/Time; return its offset."""
        self._align(4)
        off = len(self.buf)
        self.buf += _STAMP.pack(sec, nsec)
        return off

    def string(self, s):
        """Append a UTF-8 string: its length with the NUL, the bytes, the NUL."""
        raw = s.encode('utf-8') + b'\x00'
        self.u32(len(raw))
        self.buf += raw

    def f64(self, v):
        """Append a float64; return its offset."""
        self._align(8)
        off = len(self.buf)
        self.buf += _D.pack(v)
        return off

    def f64_seq(self, values):
        """Append a float64 sequence; return the offsets of its items."""
        self.u32(len(values))
        offs = []
        for v in values:
            offs.append(self.f64(v))
        return offs


def stamp_rows(stamps_ns):
    """
    Return the CDR bytes of builtin_interfaces/Time stamps: uint8 rows (n, 8), sec then nanosec.

    Parameters
    ----------
    stamps_ns : array_like of int
        The stamps [ns]; the seconds must fit in int32 (ValueError otherwise).

    """
    sec, nsec = np.divmod(np.asarray(stamps_ns, dtype=np.int64), NS)
    if len(sec) and not (-2**31 <= sec.min() and sec.max() < 2**31):
        raise ValueError('stamps must lie within the int32 range of seconds')
    stamp = np.empty((len(sec), 2), dtype='<u4')
    stamp[:, 0] = sec.astype('<i4').view('<u4')
    stamp[:, 1] = nsec
    return stamp.view(np.uint8).reshape(len(sec), 8)


class Template:
    """A fixed-layout message: a byte template with the stamp and double offsets."""

    __slots__ = ('tmpl', 'stamp_off', 'offsets', 'buf')

    def __init__(self, raw, stamp_off, offsets):
        """Keep the bytes ``raw``, the stamp offset (or None) and the double offsets."""
        self.tmpl = bytes(raw)
        self.stamp_off = stamp_off
        self.offsets = tuple(offsets)
        self.buf = bytearray(raw)

    def __call__(self, stamp_ns, values):
        """Return the message bytes with this stamp [ns] and these doubles."""
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
            out[:, self.stamp_off:self.stamp_off + 8] = stamp_rows(stamps_ns)
        for off, col in zip(self.offsets, columns):
            out[:, off:off + 8] = np.ascontiguousarray(col, dtype='<f8').view(
                np.uint8).reshape(n, 8)
        return out

    def matching(self, rows):
        """
        Return which of ``rows`` have this layout: a bool array (n,).

        ``rows`` is a uint8 array (n, message length); a row matches when it
        equals the template everywhere but in its stamp and doubles.
        """
        rows = np.ascontiguousarray(rows, dtype=np.uint8)
        width = len(self.tmpl)
        if rows.ndim != 2 or rows.shape[1] != width:
            return np.zeros(len(rows), dtype=bool)
        fixed = np.ones(width, dtype=bool)
        for off in self.offsets:
            fixed[off:off + 8] = False
        if self.stamp_off is not None:
            fixed[self.stamp_off:self.stamp_off + 8] = False
        tmpl = np.frombuffer(self.tmpl, dtype=np.uint8)
        if width % 4 == 0:              # compare 4 bytes at a time, the varying ones masked
            mask = np.where(fixed, 0xFF, 0).astype(np.uint8).view('<u4')
            words = rows.view('<u4')
            return ~((words ^ tmpl.view('<u4')) & mask).any(axis=1)
        return ((rows == tmpl) | ~fixed).all(axis=1)

    def columns(self, rows):
        """
        Return the doubles of messages of this layout: an array (n, len(offsets)), or None.

        The inverse of :meth:`rows`; ``rows`` is a uint8 array (n, message
        length). None when a message differs from the template anywhere
        but in its stamp and doubles (another layout: decode it field by field).
        """
        rows = np.ascontiguousarray(rows, dtype=np.uint8)
        width = len(self.tmpl)
        if rows.ndim != 2 or rows.shape[1] != width or not self.matching(rows).all():
            return None
        n = len(rows)
        out = np.empty((n, len(self.offsets)))
        for j, off in enumerate(self.offsets):      # each double, an unaligned strided view
            out[:, j] = np.ndarray((n,), dtype='<f8', buffer=rows, offset=off,
                                   strides=(width,))
        return out


def joint_state_template(names, n_pos, n_vel, n_eff):
    """Template of a sensor_msgs/JointState with these names and array lengths."""
    w = CdrWriter()
    stamp_off = w.stamp(0, 0)
    w.string('')                       # frame_id
    w.u32(len(names))
    for n in names:
        w.string(n)
    offs = w.f64_seq([0.0] * n_pos) + w.f64_seq([0.0] * n_vel) + w.f64_seq([0.0] * n_eff)
    return Template(w.buf, stamp_off, offs)


def wrench_template():
    """Template of a geometry_msgs/WrenchStamped; open: stamp, force.x, torque.x."""
    w = CdrWriter()
    stamp_off = w.stamp(0, 0)
    w.string('')
    offs = [w.f64(0.0) for _ in range(6)]        # force xyz, torque xyz
    return Template(w.buf, stamp_off, (offs[0], offs[3]))


def float64_template():
    """Template of a std_msgs/Float64; open: data."""
    w = CdrWriter()
    return Template(w.buf, None, [w.f64(0.0)])


def clock_template():
    """Template of a rosgraph_msgs/Clock; open: the stamp."""
    w = CdrWriter()
    return Template(w.buf, w.stamp(0, 0), [])


_F64 = float64_template()
#: The std_msgs/Float64 template (``F64_TEMPLATE.rows`` encodes many at once).
F64_TEMPLATE = _F64


def encode_bool(value):
    """Return the CDR bytes of a std_msgs/Bool with ``data = value``."""
    return CDR_LE + (b'\x01' if value else b'\x00')


def encode_float64(value):
    """Return the CDR bytes of a std_msgs/Float64 with ``data = value``."""
    return _F64(None, (value,))


# ---------------------------------------------------------------------------
# Decoding (fixed layouts; plain CDR, either endianness)
# ---------------------------------------------------------------------------

class DecodeError(LeadscrewError, ValueError):
    """Bytes that are not a valid CDR message of the expected type."""


class CdrReader:
    """Plain CDR (XCDR1) reader of either endianness, with the writer's alignment rule."""

    def __init__(self, data):
        """Check the encapsulation header of ``data``."""
        if len(data) < 4 or data[0] != 0 or data[1] not in (0, 1):
            raise DecodeError('not plain CDR')
        self.data = data
        self.e = '<' if data[1] else '>'
        self.pos = 4

    def _align(self, n):
        self.pos += padding(self.pos, n)

    def _take(self, fmt, size, align):
        self._align(align)
        try:
            v = struct.unpack_from(self.e + fmt, self.data, self.pos)
        except struct.error:
            raise DecodeError('message too short') from None
        self.pos += size
        return v

    def u32(self):
        """Read a uint32."""
        return self._take('I', 4, 4)[0]

    def stamp(self):
        """Read a builtin_interfaces/Time as integer ns."""
        sec, nsec = self._take('iI', 8, 4)
        return sec * NS + nsec

    def string(self):
        """Read a string."""
        n = self.u32()
        raw = self.data[self.pos:self.pos + n]
        if n == 0 or len(raw) != n:
            raise DecodeError('bad string')
        self.pos += n
        return bytes(raw[:-1]).decode('utf-8', 'replace')

    def f64(self):
        """Read a float64."""
        return self._take('d', 8, 8)[0]

    def f64_seq(self):
        """Read a float64 sequence as a tuple."""
        n = self.u32()
        if n > (len(self.data) - self.pos) // 8:
            raise DecodeError('sequence longer than the message')
        if n == 0:
            return ()
        return self._take(f'{n}d', 8 * n, 8)


#: std_msgs/Float64 encapsulations (CDR and XCDR2, big and little endian) -> the decoder
#: of the double at offset 4, as DDS implementations send them.
_F64_CDR = {b'\x00\x00': struct.Struct('>d'), b'\x00\x01': struct.Struct('<d'),
            b'\x00\x06': struct.Struct('>d'), b'\x00\x07': struct.Struct('<d')}


def decode_float64(data):
    """
    Return the ``data`` field of a serialized std_msgs/Float64.

    Takes plain CDR and XCDR2 of either endianness (the double sits at offset
    4 in all four); raises DecodeError for anything else.
    """
    codec = _F64_CDR.get(bytes(data[:2])) if len(data) >= 12 else None
    if codec is None:
        raise DecodeError('not a CDR std_msgs/Float64')
    return codec.unpack_from(data, 4)[0]


def decode_float64s(messages):
    """
    Return the ``data`` of many serialized std_msgs/Float64 as a float array (n,).

    ``messages``: a list of bytes, or a uint8 array (n, 12). Little-endian CDR
    (what rclpy writes) is read at once; anything else message by message
    (:func:`decode_float64`).
    """
    if isinstance(messages, np.ndarray):
        rows = messages if messages.ndim == 2 and messages.shape[1] == 12 else None
    else:
        blob = b''.join(messages)
        rows = (np.frombuffer(blob, dtype=np.uint8).reshape(-1, 12)
                if len(blob) == 12 * len(messages) else None)
    if rows is not None and (rows[:, 0] == 0).all() and (rows[:, 1] == 1).all():
        return rows[:, 4:].copy().view('<f8').ravel()
    return np.array([decode_float64(bytes(m)) for m in messages], dtype=float)


def decode_joint_state(data):
    """Return (stamp_ns, names, position, velocity, effort) of a serialized JointState."""
    r = CdrReader(data)
    stamp = r.stamp()
    r.string()
    n = r.u32()
    if n > len(data):
        raise DecodeError('bad name count')
    names = [r.string() for _ in range(n)]
    return stamp, names, r.f64_seq(), r.f64_seq(), r.f64_seq()


def decode_wrench_stamped(data):
    """Return (stamp_ns, (fx, fy, fz), (tx, ty, tz)) of a serialized WrenchStamped."""
    r = CdrReader(data)
    stamp = r.stamp()
    r.string()
    v = [r.f64() for _ in range(6)]
    return stamp, tuple(v[:3]), tuple(v[3:])


def decode_float64_multi_array(data):
    """
    Return the ``data`` of a serialized std_msgs/Float64MultiArray as a tuple.

    The layout (its dimensions and data_offset) is read past: the commands of
    ros2_control's forward_command_controller leave it empty.
    """
    r = CdrReader(data)
    n_dim = r.u32()
    if n_dim > len(data):
        raise DecodeError('bad dimension count')
    for _ in range(n_dim):
        r.string()                      # label
        r.u32()                         # size
        r.u32()                         # stride
    r.u32()                             # data_offset
    return r.f64_seq()


def decode_float64_multi_arrays(messages):
    """
    Return the ``data`` of many Float64MultiArray messages as a float array (n, m), or None.

    At once when every message has the first one's length and the bytes
    before its data (layout and length) are the same in all: the commands of
    one controller; else None (decode them one by one).
    """
    n = len(messages)
    if not n:
        return None
    rows = messages if isinstance(messages, np.ndarray) else None
    if rows is None:
        if len({len(d) for d in messages}) != 1:
            return None
        rows = np.frombuffer(b''.join(bytes(d) for d in messages), dtype=np.uint8).reshape(n, -1)
    r = CdrReader(bytes(rows[0]))
    if r.e != '<':
        return None
    for _ in range(r.u32()):
        r.string()
        r.u32()
        r.u32()
    r.u32()
    m = r.u32()
    r._align(8)
    start = r.pos
    if start + 8 * m != rows.shape[1] or not (rows[:, :start] == rows[0, :start]).all():
        return None
    return np.ascontiguousarray(rows[:, start:]).view('<f8').reshape(n, m)


def decode_joint_trajectory(data):
    """
    Return (stamp_ns, joint names, points) of a serialized trajectory_msgs/JointTrajectory.

    Each point is (positions, velocities, accelerations, effort,
    time_from_start [ns]); the arrays are tuples (empty when not given).
    """
    r = CdrReader(data)
    stamp = r.stamp()
    r.string()                          # frame_id
    n = r.u32()
    if n > len(data):
        raise DecodeError('bad joint name count')
    names = [r.string() for _ in range(n)]
    n_points = r.u32()
    if n_points > len(data):
        raise DecodeError('bad point count')
    points = []
    for _ in range(n_points):
        pos, vel, acc, eff = r.f64_seq(), r.f64_seq(), r.f64_seq(), r.f64_seq()
        sec, nsec = r._take('iI', 8, 4)
        points.append((pos, vel, acc, eff, sec * NS + nsec))
    return stamp, names, points
