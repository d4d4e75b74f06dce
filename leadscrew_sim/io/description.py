"""
The robot description of a run and the transforms robot_state_publisher makes of it.

:func:`xacro_args` maps the parameters of an axis to the arguments of the
package's ``urdf/leadscrew_axis.urdf.xacro`` (the mapping the launch file
applies: ``launch/leadscrew_sim.launch.py`` could call it with the mapping of
the preset and the parameter file), :func:`render_urdf` renders it with the
xacro Python API, and :class:`JointTree` computes from the URDF text the
transforms robot_state_publisher publishes: the fixed joints once on
``/tf_static``, the screw and nut joints on ``/tf`` for every joint state,
each ``parent link -> child link`` = joint origin * joint motion.

A transform is ``(parent_frame, child_frame, (tx, ty, tz), (qx, qy, qz, qw))``:
translation [m] and unit rotation quaternion. URDF's ``rpy`` is roll, pitch,
yaw about the fixed axes: R = Rz(yaw) Ry(pitch) Rx(roll).
"""
from collections.abc import Mapping
import math
import re
import xml.etree.ElementTree as ET

import numpy as np

from ..core.presets import package_data_dirs
from ..core.errors import LeadscrewError

#: The package's robot description, in ``urdf/`` of the source tree and the share directory.
XACRO_FILE = 'leadscrew_axis.urdf.xacro'

#: xacro argument <- ScrewParams field (plus ``lead`` = pitch x starts and ``prefix``).
XACRO_FROM_PARAMETERS = {
    'hand': 'hand',
    'backlash': 'backlash',
    'stroke_min': 'stroke_min',
    'stroke_max': 'stroke_max',
    'screw_diameter': 'major_diameter',
    'max_torque': 'max_torque',
    'max_screw_velocity': 'max_screw_velocity',
    'initial_position': 'initial_position',
}

#: Joint names (after the prefix) of the screw (revolute) and the nut (prismatic).
SCREW_JOINT = 'screw_joint'
NUT_JOINT = 'nut_joint'

_MOVING = ('revolute', 'continuous', 'prismatic')

__all__ = ['DescriptionError', 'Joint', 'JointTree', 'NUT_JOINT', 'SCREW_JOINT', 'XACRO_FILE',
           'XACRO_FROM_PARAMETERS', 'render_urdf', 'xacro_args', 'xacro_dirs', 'xacro_path']


class DescriptionError(LeadscrewError, RuntimeError):
    """The robot description cannot be rendered (no xacro, no xacro file, a xacro error)."""


# ---------------------------------------------------------------------------
# xacro
# ---------------------------------------------------------------------------

def xacro_args(params, joint_prefix=''):
    """
    Return the xacro arguments ``{name: str}`` of an axis, as the launch file maps them.

    Parameters
    ----------
    params : ScrewParams or Mapping
        An object with the fields pitch, starts, hand, backlash, stroke_min,
        stroke_max, major_diameter and max_torque; or a mapping of node
        parameters (a preset's ``ros__parameters``), of which only the keys
        present count (``lead`` if pitch or starts is present, pitch defaulting
        to 0.003 m and starts to 1): a missing one keeps the xacro default.
    joint_prefix : str
        The ``prefix`` argument (the node's ``joint_prefix``).

    """
    if isinstance(params, Mapping):
        def get(name, default=None):
            return params.get(name, default)
        present = set(params)
    else:
        def get(name, default=None):
            return getattr(params, name)
        present = {'pitch', *XACRO_FROM_PARAMETERS.values()}
    args = {'prefix': str(joint_prefix)}
    if present & {'pitch', 'starts'}:
        args['lead'] = str(float(get('pitch', 0.003)) * int(get('starts', 1)))
    for arg, name in XACRO_FROM_PARAMETERS.items():
        if name in present:
            args[arg] = str(get(name))
    return args


def xacro_dirs():
    """Return the directories searched for :data:`XACRO_FILE`, in order (existing ones)."""
    return package_data_dirs('urdf')


def xacro_path():
    """Return the path of :data:`XACRO_FILE`; raise DescriptionError if none is found."""
    for d in xacro_dirs():
        path = d / XACRO_FILE
        if path.is_file():
            return path
    raise DescriptionError(
        f'robot description {XACRO_FILE} not found (looked in the source tree urdf/ and '
        '<prefix>/share/leadscrew_sim/urdf of AMENT_PREFIX_PATH and sys.prefix)')


def _comment_text(text):
    # an XML comment must not contain '--' (xacro's banner does the same)
    return re.sub(r'-+', '-', text)


def render_urdf(args=None):
    """
    Return the URDF text of :data:`XACRO_FILE` rendered with xacro arguments ``args``.

    The text is what the ``xacro`` command prints (``toprettyxml``, two-space
    indent), except that xacro's banner, which names the file's path, is
    replaced by a comment naming the package file and the arguments, so the
    text does not depend on where the package is installed. Raises
    DescriptionError if the xacro Python package is missing, the file is not
    found or xacro fails (bad arguments: the file's own checks).

    Parameters
    ----------
    args : dict, optional
        ``{argument: value}`` (values passed as ``str(value)``), e.g. of :func:`xacro_args`.

    """
    try:
        import xacro
    except ImportError as exc:
        raise DescriptionError(
            f'the Python package xacro is needed to render the robot description ({exc}); '
            'install it with pip install xacro or apt install ros-jazzy-xacro') from None
    path = xacro_path()
    mappings = {str(k): str(v) for k, v in (args or {}).items()}
    try:
        doc = xacro.process_file(str(path), mappings=dict(mappings))   # xacro adds to it
    except Exception as exc:  # noqa: B902 - xacro raises XacroException and others
        msg = ' '.join(str(exc).split()) or exc.__class__.__name__
        raise DescriptionError(f'xacro cannot render {XACRO_FILE}: {msg}') from None
    nodes = list(doc.childNodes)
    if (len(nodes) > 4 and all(n.nodeType == n.COMMENT_NODE for n in nodes[:4])
            and 'autogenerated by xacro' in nodes[1].data):
        for n in nodes[:4]:
            doc.removeChild(n)
    arg_text = ' '.join(f'{k}:={v}' for k, v in mappings.items()) or '(defaults)'
    doc.insertBefore(doc.createComment(_comment_text(
        f' leadscrew_sim/urdf/{XACRO_FILE} rendered by xacro with {arg_text} ')),
        doc.firstChild)
    return doc.toprettyxml(indent='  ')


# ---------------------------------------------------------------------------
# Transforms (plain math)
# ---------------------------------------------------------------------------

def _rpy_quaternion(roll, pitch, yaw):
    """Return (x, y, z, w) of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    sr, cr = math.sin(0.5 * roll), math.cos(0.5 * roll)
    sp, cp = math.sin(0.5 * pitch), math.cos(0.5 * pitch)
    sy, cy = math.sin(0.5 * yaw), math.cos(0.5 * yaw)
    return (sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy)


def _rpy_matrix(roll, pitch, yaw):
    """Return the rows of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    sr, cr = math.sin(roll), math.cos(roll)
    sp, cp = math.sin(pitch), math.cos(pitch)
    sy, cy = math.sin(yaw), math.cos(yaw)
    return ((cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
            (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
            (-sp, cp * sr, cp * cr))


def _qmul(a, b):
    """Return the quaternion product a b of (x, y, z, w) quaternions (floats or arrays)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def _floats(text, default, n=3):
    values = tuple(float(v) for v in (text or default).split())
    if len(values) != n:
        raise ValueError(f'{text!r} is not {n} numbers')
    return values


class Joint:
    """
    One URDF joint: name, type, parent and child link, origin, axis and mimic.

    ``xyz``, ``rpy`` are the origin, ``axis`` the unit joint axis in the joint
    frame (URDF default 1 0 0), ``mimic`` None or (leader joint, multiplier,
    offset). ``rotation`` and ``matrix`` are the origin's quaternion and matrix.
    """

    __slots__ = ('name', 'type', 'parent', 'child', 'xyz', 'rpy', 'axis', 'mimic',
                 'rotation', 'matrix')

    def __init__(self, element):
        """Read a ``<joint>`` element."""
        self.name = element.get('name')
        self.type = element.get('type')
        parent, child = element.find('parent'), element.find('child')
        if not self.name or parent is None or child is None:
            raise ValueError('a joint needs a name, a parent and a child')
        self.parent, self.child = parent.get('link'), child.get('link')
        origin = element.find('origin')
        origin = {} if origin is None else origin.attrib
        self.xyz = _floats(origin.get('xyz'), '0 0 0')
        self.rpy = _floats(origin.get('rpy'), '0 0 0')
        axis = element.find('axis')
        axis = _floats(None if axis is None else axis.get('xyz'), '1 0 0')
        norm = math.sqrt(sum(a * a for a in axis))
        if self.type in _MOVING and not norm > 0.0:
            raise ValueError(f'joint {self.name!r} has a zero axis')
        self.axis = tuple(a / norm for a in axis) if norm > 0.0 else axis
        mimic = element.find('mimic')
        self.mimic = None if mimic is None else (
            mimic.get('joint'), float(mimic.get('multiplier', '1')),
            float(mimic.get('offset', '0')))
        self.rotation = _rpy_quaternion(*self.rpy)
        self.matrix = _rpy_matrix(*self.rpy)

    def transform(self, q):
        """Return ((tx, ty, tz), (qx, qy, qz, qw)) of origin * motion at joint value ``q``."""
        (tx, ty, tz), (rx, ry, rz, rw) = _motion(self, q, math.sin, math.cos)
        return (float(tx), float(ty), float(tz)), (float(rx), float(ry), float(rz), float(rw))

    def __repr__(self):
        """Return a short description."""
        return f'Joint({self.name!r}, {self.type}, {self.parent} -> {self.child})'


def _motion(j, q, sin, cos):
    """Return (translation, rotation) of origin * motion of joint ``j`` at ``q`` (float/array)."""
    if j.type == 'prismatic':
        d0, d1, d2 = (a * q for a in j.axis)
        translation = tuple(p + (m0 * d0 + m1 * d1 + m2 * d2)
                            for p, (m0, m1, m2) in zip(j.xyz, j.matrix))
        return translation, j.rotation
    if j.type in ('revolute', 'continuous'):
        half = 0.5 * q
        s, c = sin(half), cos(half)
        return j.xyz, _qmul(j.rotation, (j.axis[0] * s, j.axis[1] * s, j.axis[2] * s, c))
    return j.xyz, j.rotation


class JointTree:
    """
    The joints of a URDF and the transforms robot_state_publisher publishes for them.

    Fixed joints give the static transforms; the screw joint (the revolute or
    continuous joint named ``<prefix>screw_joint``) and the nut joint (the
    prismatic ``<prefix>nut_joint``) the moving ones, in the order of the URDF.
    A moving joint with a ``<mimic>`` follows its leader (multiplier * leader +
    offset), as robot_state_publisher computes it. Other moving joints raise
    ValueError.

    Parameters
    ----------
    urdf_text : str or bytes
        The URDF (e.g. of :func:`render_urdf`).

    """

    def __init__(self, urdf_text):
        """Parse the joints of ``urdf_text``."""
        root = ET.fromstring(urdf_text)
        if root.tag != 'robot':
            raise ValueError(f'not a URDF: root element <{root.tag}>')
        self.robot_name = root.get('name', '')
        self.joints = [Joint(e) for e in root.findall('joint')]
        self.joint_map = {j.name: j for j in self.joints}
        self.fixed = [j for j in self.joints if j.type == 'fixed']
        self.moving = [j for j in self.joints if j.type in _MOVING]
        other = [j.name for j in self.joints if j.type != 'fixed' and j.type not in _MOVING]
        if other:
            raise ValueError(f'joint types other than fixed, revolute, continuous and '
                             f'prismatic: {", ".join(other)}')
        self.screw_joint = self._find(SCREW_JOINT, ('revolute', 'continuous'))
        self.nut_joint = self._find(NUT_JOINT, ('prismatic',))
        for j in self.moving:
            if j.mimic is not None and j.mimic[0] not in (self.screw_joint, self.nut_joint):
                raise ValueError(f'joint {j.name!r} mimics {j.mimic[0]!r}, not the screw or '
                                 'nut joint')
            if j.mimic is None and j.name not in (self.screw_joint, self.nut_joint):
                raise ValueError(f'moving joint {j.name!r} is neither the screw nor the nut joint')
        #: (parent, child) of the static and of the moving transforms, in their order.
        self.static_frames = tuple((j.parent, j.child) for j in self.fixed)
        self.moving_frames = tuple((j.parent, j.child) for j in self.moving)

    def _find(self, suffix, types):
        found = [j.name for j in self.moving if j.name.endswith(suffix) and j.type in types]
        if len(found) != 1:
            raise ValueError(f'the URDF needs one {"/".join(types)} joint named '
                             f'<prefix>{suffix}, not {found or "none"}')
        return found[0]

    def _value(self, j, screw_angle, nut_position):
        if j.mimic is not None:
            leader, multiplier, offset = j.mimic
            q = screw_angle if leader == self.screw_joint else nut_position
            return multiplier * q + offset
        return screw_angle if j.name == self.screw_joint else nut_position

    def static_transforms(self):
        """Return [(parent, child, translation, quaternion)] of the fixed joints."""
        return [(j.parent, j.child) + j.transform(0.0) for j in self.fixed]

    def moving_transforms(self, screw_angle, nut_position):
        """
        Return [(parent, child, translation, quaternion)] of the moving joints.

        Parameters
        ----------
        screw_angle : float
            Screw joint [rad].
        nut_position : float
            Nut joint [m].

        """
        return [(j.parent, j.child) + j.transform(self._value(j, screw_angle, nut_position))
                for j in self.moving]

    def moving_values(self, screw_angle, nut_position):
        """Return the 7 doubles per moving frame (``TfEncoder(moving_frames)`` values)."""
        out = []
        for _p, _c, t, r in self.moving_transforms(screw_angle, nut_position):
            out += t
            out += r
        return out

    def moving_columns(self, screw_angles, nut_positions):
        """
        Return 7 float64 arrays per moving frame: the columns of ``TfEncoder.rows``.

        Row k holds the values of :meth:`moving_values` at ``(screw_angles[k],
        nut_positions[k])`` (same operations: equal bits where numpy's sin and
        cos are the C library's).
        """
        a = np.asarray(screw_angles, dtype=np.float64)
        x = np.asarray(nut_positions, dtype=np.float64)
        if a.shape != x.shape or a.ndim != 1:
            raise ValueError('screw_angles and nut_positions must be 1-d and of one length')
        n = len(a)
        cols = []
        for j in self.moving:
            translation, rotation = _motion(j, self._value(j, a, x), np.sin, np.cos)
            for v in tuple(translation) + tuple(rotation):
                cols.append(v if isinstance(v, np.ndarray) else np.full(n, float(v)))
        return cols
