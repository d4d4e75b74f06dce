"""
ROS 2 message definitions in the form rosbag2 stores them in MCAP schemas.

``ros2msg_definition('sensor_msgs/msg/JointState')`` returns the complete
definition with encoding ``ros2msg``, built the way rosbag2_cpp's
``LocalMessageDefinitionSource::get_full_text`` builds it:

* the type's own ``.msg`` file, verbatim (comments and constants included);
* then, for every non-primitive field type, depth-first and each type once, a
  newline, a line of 80 ``=``, a line ``MSG: pkg/Type`` and that type's text.

The dependencies of one file are visited in sorted order (rosbag2 keeps them
in a ``std::set<std::string>``), not in the order of their first appearance.
``wstring`` counts as a primitive here (rosbag2's list omits it and would
fall back to IDL). Only ``.msg`` files are read; nothing here imports rclpy.
Types of packages without an installed share directory (tf2_msgs: no PyPI
wheel) take their own text from :data:`EMBEDDED` and their hash from
:data:`EMBEDDED_HASHES`; their dependencies are read as usual.
"""
import functools
import json
import os
import re
import struct
import sys

from .cdr import padding
from ..core.errors import LeadscrewError

PRIMITIVE_TYPES = frozenset((
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string', 'wstring'))

DELIMITER = '=' * 80 + '\n'

#: Own ``.msg`` texts (verbatim) of types not installed here, consulted before the
#: share directory; keys ``'pkg/msg/Type'``.
EMBEDDED = {
    'tf2_msgs/msg/TFMessage': 'geometry_msgs/TransformStamped[] transforms\n',
    'leadscrew_sim/msg/ThreadState': (
        '# One tick of the thread contact of both nut bodies and the energy terms since\n'
        '# reset (recorded by leadscrew_sim only; SI units).\n'
        'std_msgs/Header header\n'
        '# nut A: contact 1 leading flank, -1 trailing, 0 in the backlash;\n'
        '# stick 1 stuck, 0 sliding, -1 no load\n'
        'float64 contact_a\n'
        'float64 stick_a\n'
        'float64 normal_leading_a  # flank normal force [N]\n'
        'float64 normal_trailing_a  # [N]\n'
        'float64 friction_a  # friction force along the flank [N]\n'
        'float64 sliding_velocity_a  # [m/s]\n'
        '# half-nut B of a split nut, the same (contact 0 and stick -1 without one)\n'
        'float64 contact_b\n'
        'float64 stick_b\n'
        'float64 normal_leading_b\n'
        'float64 normal_trailing_b\n'
        'float64 friction_b\n'
        'float64 sliding_velocity_b\n'
        '# energy since reset [J]: input + external = kinetic + potential + spring\n'
        '# + friction_dissipation + damping_dissipation (+ the integration residual)\n'
        'float64 input_work\n'
        'float64 external_work\n'
        'float64 kinetic\n'
        'float64 potential\n'
        'float64 spring\n'
        'float64 friction_dissipation\n'
        'float64 damping_dissipation\n'),
    'leadscrew_sim/msg/AgeingState': (
        '# The ageing of the axis at one tick (leadscrew_sim; SI units, temperature in degC).\n'
        'std_msgs/Header header\n'
        'float64 wear_leading  # leading flanks\' wear depth, summed over the nut bodies [m]\n'
        'float64 wear_trailing  # the same of the trailing flanks [m]\n'
        'float64 backlash  # effective backlash: the set one opened by the wear [m]\n'
        'float64 preload  # anti-backlash preload the worn flanks leave [N]; 0 single nut\n'
        'float64 lubricant  # lubricant state: 1 fresh, 0 used up [-]\n'
        'float64 mu_k  # kinetic thread friction coefficient now [-]\n'
        'float64 mu_s  # static thread friction coefficient now [-]\n'
        'float64 screw_temperature  # [degC]\n'
        'float64 heat_flow  # friction heat flowing into the screw [W]\n'
        'float64 thermal_growth  # growth of the screw at the nut [m]\n'),
}
#: RIHS01 type hashes of the :data:`EMBEDDED` types, computed with rosidl's algorithm
#: (``leadscrew_sim.io.tf.tfmessage_type_hash`` recomputes the TFMessage one).
EMBEDDED_HASHES = {
    'tf2_msgs/msg/TFMessage':
        'RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087',
}

_NAME = r'[A-Za-z][A-Za-z0-9_]*'
_TYPE_RE = re.compile(rf'^({_NAME})/(?:msg/)?({_NAME})$')
_FIELD_TYPE_RE = re.compile(r'^([A-Za-z0-9_/]+)(?:<=\d+)?(?:\[[^\]]*\])?$')


class DefinitionNotFoundError(LeadscrewError, LookupError):
    """No installed ``.msg`` file for a message type."""


def split_type(msg_type):
    """Return ``(package, Type)`` for ``'pkg/msg/Type'`` or ``'pkg/Type'``."""
    match = _TYPE_RE.match(msg_type)
    if not match:
        raise ValueError(f'not a ROS 2 message type name: {msg_type!r}')
    return match.group(1), match.group(2)


def full_type_name(msg_type):
    """Return the ``'pkg/msg/Type'`` form of a message type name."""
    return '%s/msg/%s' % split_type(msg_type)


def share_directory(package):
    """
    Return the share directory of an installed ROS package.

    Uses the ament index (``AMENT_PREFIX_PATH``) and falls back to
    ``sys.prefix/share/<package>``.
    """
    try:
        from ament_index_python.packages import get_package_share_directory
        return get_package_share_directory(package)
    except (ImportError, LookupError, ValueError, KeyError, OSError):
        return os.path.join(sys.prefix, 'share', package)


@functools.lru_cache(maxsize=None)
def msg_text(msg_type):
    """Return the verbatim text of the installed ``.msg`` file of ``msg_type``."""
    embedded = EMBEDDED.get(full_type_name(msg_type))
    if embedded is not None:
        return embedded
    package, name = split_type(msg_type)
    path = os.path.join(share_directory(package), 'msg', name + '.msg')
    try:
        with open(path, encoding='utf-8', newline='') as f:
            return f.read()
    except OSError:
        raise DefinitionNotFoundError(
            f'no message definition for {msg_type!r} (looked for {path})') from None


def msg_dependencies(text, package):
    """
    Return the sorted ``pkg/Type`` names of the non-primitive field types in ``text``.

    Comment lines are skipped; constants have primitive types, so they add
    nothing. A short name (``Header`` inside std_msgs) refers to ``package``.
    """
    deps = set()
    for line in text.splitlines():
        tokens = line.split(None, 1)
        if len(tokens) < 2 or tokens[0].startswith('#'):
            continue
        match = _FIELD_TYPE_RE.match(tokens[0])
        if not match or match.group(1) in PRIMITIVE_TYPES:
            continue
        base = match.group(1)
        if '/' in base:
            deps.add('%s/%s' % split_type(base))
        else:
            deps.add(f'{package}/{base}')
    return sorted(deps)


def ros2msg_definition(msg_type):
    """
    Return the complete ``ros2msg`` definition of ``msg_type`` as rosbag2 writes it.

    ``msg_type`` is ``'pkg/msg/Type'`` (or ``'pkg/Type'``). Raises
    :class:`DefinitionNotFoundError` when a ``.msg`` file is not installed.
    """
    seen = set()

    def append(name, depth):
        if depth <= 0:
            raise RecursionError(f'message definition of {msg_type!r} nests too deep')
        text = msg_text(name)
        out = [text]
        for dep in msg_dependencies(text, split_type(name)[0]):
            if dep not in seen:
                seen.add(dep)
                out += ['\n', DELIMITER, f'MSG: {dep}\n', append(dep, depth - 1)]
        return ''.join(out)

    return append(msg_type, 50)


@functools.lru_cache(maxsize=None)
def type_hash(msg_type):
    """
    Return the ROS 2 type hash (``'RIHS01_...'``) of ``msg_type``, or ``''``.

    Read from the ``.json`` type description installed next to the ``.msg``
    (:data:`EMBEDDED_HASHES` first).
    """
    embedded = EMBEDDED_HASHES.get(full_type_name(msg_type))
    if embedded is not None:
        return embedded
    package, name = split_type(msg_type)
    path = os.path.join(share_directory(package), 'msg', name + '.json')
    try:
        with open(path, encoding='utf-8') as f:
            hashes = json.load(f).get('type_hashes', [])
    except (OSError, ValueError, AttributeError):
        return ''
    full = full_type_name(msg_type)
    for entry in hashes:
        if isinstance(entry, dict) and entry.get('type_name') == full:
            return str(entry.get('hash_string', ''))
    return ''


_PRIMITIVE_SIZES = {
    'bool': 1, 'byte': 1, 'char': 1, 'int8': 1, 'uint8': 1, 'int16': 2, 'uint16': 2,
    'int32': 4, 'uint32': 4, 'float32': 4, 'int64': 8, 'uint64': 8, 'float64': 8}
_FIELD_RE = re.compile(r'^([A-Za-z0-9_/]+)(?:<=\d+)?(\[(<=)?(\d*)\])?$')


@functools.lru_cache(maxsize=None)
def msg_fields(msg_type):
    """
    Return the fields of ``msg_type`` as ``(type, array)`` pairs, constants left out.

    ``type`` is a primitive name, ``'string'``/``'wstring'`` or ``'pkg/msg/Type'``;
    ``array`` is None, ``'seq'`` (``[]``, ``[<=N]``) or the fixed length ``N``.
    """
    package = split_type(msg_type)[0]
    fields = []
    for line in msg_text(msg_type).splitlines():
        tokens = line.split('#', 1)[0].split()
        if len(tokens) < 2 or '=' in tokens[1] or tokens[2:3] and tokens[2][0] == '=':
            continue
        match = _FIELD_RE.match(tokens[0])
        if not match:
            raise ValueError(f'cannot parse field type {tokens[0]!r} of {msg_type}')
        base = match.group(1)
        if base not in PRIMITIVE_TYPES:
            base = full_type_name(base if '/' in base else f'{package}/{base}')
        array = None
        if match.group(2):
            array = 'seq' if match.group(3) or not match.group(4) else int(match.group(4))
        fields.append((base, array))
    return tuple(fields)


def _is_fixed(base):
    """Return True if a type's CDR size does not depend on its values (no strings, sequences)."""
    if base in _PRIMITIVE_SIZES:
        return True
    if base in ('string', 'wstring'):
        return False
    return all(array != 'seq' and _is_fixed(b) for b, array in msg_fields(base))


@functools.lru_cache(maxsize=None)
def fixed_cdr_length(msg_type):
    """Return the CDR length [bytes] of a fixed-size type (std_msgs/Float64: 12), else None."""
    try:
        name = full_type_name(msg_type)
        if not _is_fixed(name):
            return None
    except (LookupError, ValueError, RecursionError):
        return None
    return cdr_length(name, b'\x00\x01\x00\x00' + bytes(1 << 16), _walk=True)


def cdr_length(msg_type, data, _walk=False):
    """
    Return the length in bytes of the CDR message of ``msg_type`` at the start of ``data``.

    Walks plain (XCDR1) CDR, little or big endian, after the 4-byte
    encapsulation header (fixed-size types: a cached length). Returns None
    when the length cannot be determined (other encodings, ``wstring``
    fields, truncated or inconsistent data).
    """
    if len(data) < 4 or data[0] != 0 or data[1] not in (0, 1):
        return None
    if not _walk:
        fixed = fixed_cdr_length(msg_type)
        if fixed is not None:
            return fixed if fixed <= len(data) else None
    u32 = struct.Struct('<I' if data[1] else '>I').unpack_from
    size = len(data)

    def align(pos, n):
        return pos + padding(pos, n)

    def one(base, pos):
        if base in _PRIMITIVE_SIZES:
            n = _PRIMITIVE_SIZES[base]
            return align(pos, n) + n
        if base == 'string':
            pos = align(pos, 4)
            return pos + 4 + u32(data, pos)[0]
        if base == 'wstring':
            raise ValueError('wstring')
        fields = msg_fields(base)
        pos = walk(fields, pos) if fields else pos + 1   # empty types carry one uint8
        if pos > size:
            raise ValueError('past the end')
        return pos

    def walk(fields, pos):
        for base, array in fields:
            if array is None:
                pos = one(base, pos)
                continue
            if array == 'seq':
                pos = align(pos, 4)
                count = u32(data, pos)[0]
                pos += 4
            else:
                count = array
            if base in _PRIMITIVE_SIZES:
                if count:
                    n = _PRIMITIVE_SIZES[base]
                    pos = align(pos, n) + count * n
            else:
                for _ in range(count):
                    pos = one(base, pos)
            if pos > size:
                raise ValueError('past the end')
        return pos

    try:
        return one(full_type_name(msg_type), 4)
    except (struct.error, ValueError, LookupError, RecursionError):
        return None
