"""
How a foreign recording maps onto the model: its state and command topics, joints and timing.

The keys are the options of the verbs (``state_topic``, ``screw_joint``,
``nut_joint``, ``command_topic``, ``command_kind``, ``command_index``,
``command_joint``, ``command_delay``, ``step_rate``) or the same keys
in a YAML file (the ``map`` option, dashes or underscores); an option given
with the call wins over the file.
"""
import dataclasses
import math

from ...core import yamlio
from ...io.topics import graph_name, TOPIC_SPECS
from ..options import RunError


class MappingError(RunError):
    """A recording's mapping onto the axis is wrong: the key (option), its value and why."""


#: What a scalar command is: motor torque [N m], nut velocity [m/s], nut position [m].
COMMAND_KINDS = ('torque', 'velocity', 'position')

#: ros2_control's command interface names, taken for the kinds: an ``effort`` command of
#: the screw joint is the motor torque.
KIND_ALIASES = {'effort': 'torque'}

#: The command types read, and the state type.
FLOAT64 = 'std_msgs/msg/Float64'
MULTI_ARRAY = 'std_msgs/msg/Float64MultiArray'
JOINT_STATE = 'sensor_msgs/msg/JointState'
TRAJECTORY = 'trajectory_msgs/msg/JointTrajectory'
COMMAND_TYPES = (FLOAT64, MULTI_ARRAY, JOINT_STATE, TRAJECTORY)

#: Default step rate [Hz] of the re-simulation (raised to the command rate where faster).
DEFAULT_STEP_RATE = 1000.0


@dataclasses.dataclass
class Mapping:
    """
    The mapping of a foreign recording (every field optional until resolved).

    Attributes
    ----------
    state_topic : str
        The sensor_msgs/JointState topic of the measured states.
    screw_joint, nut_joint : str
        Joint names of the screw (motor; rad, rad/s, N m) and of the nut
        (m, m/s, N) in the states.
    command_topic : str or list of str
        The command topic (a type of :data:`COMMAND_TYPES`), or several: the
        topics of ros2_control's controllers a switch leaves in one recording
        (effort for the breakaway, velocity for a sweep, position for
        reversals). Their commands act in the order of their times, the
        latest one's (the active controller's) in force.
        ``command_kind``, ``command_index`` and ``command_joint`` then are
        one value for all of them or a list, one per topic, in their order.
    command_kind : str
        torque, velocity or position: what a Float64 or Float64MultiArray
        command entry is (motor torque [N m], nut velocity [m/s], nut position [m]);
        ros2_control's interface name effort is taken for torque.
    command_index : int
        The entry of a Float64MultiArray command [-].
    command_joint : str
        The joint of a JointState or JointTrajectory command (default: the
        nut joint where the command names it, else the screw joint).
    command_delay : float
        Constant delay from a command's time to its effect [s] (None: estimated).
    step_rate : float
        Step rate of the re-simulation [Hz] (None: 1 kHz or the command rate).

    """

    state_topic: str = None
    screw_joint: str = None
    nut_joint: str = None
    command_topic: str = None
    command_kind: str = None
    command_index: int = None
    command_joint: str = None
    command_delay: float = None
    step_rate: float = None

    @classmethod
    def keys(cls):
        """Return the names of the mapping's fields (the option names with underscores)."""
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def from_args(cls, args):
        """
        Return the mapping of parsed options: the ``map`` file with the options on top, checked.

        Options the parser of a verb does not have count as not given.
        """
        values = {}
        path = getattr(args, 'map', None)
        if path:
            values.update(read_map_file(path))
        for key in cls.keys():
            v = getattr(args, 'rate' if key == 'step_rate' and not hasattr(args, key)
                        else key, None)
            if v is not None:
                values[key] = v
        out = cls(**values)
        out.check()
        return out

    def specs(self):
        """
        Return the mapped command topics as [(topic, kind, index, joint)] (one None topic: none).

        A kind not given is read from the topic's name where it says one
        (position, velocity, effort or torque), as the node's and ros2_control's
        controllers' topics do.
        """
        topics = _as_list(self.command_topic) or [None]
        per = {}
        for key in ('command_kind', 'command_index', 'command_joint'):
            values = _as_list(getattr(self, key))
            if len(values) > 1 and len(values) != len(topics):
                raise MappingError(f'<<{key}>>: {len(values)} values for '
                                   f'{len(topics)} <<command_topic>>: give one for all or one '
                                   'per topic, in their order')
            per[key] = values * len(topics) if len(values) == 1 else \
                (values or [None] * len(topics))
        kinds = [k if k is not None or t is None else kind_from_name(t)
                 for t, k in zip(topics, per['command_kind'])]
        return list(zip(topics, kinds, per['command_index'], per['command_joint']))

    @property
    def given(self):
        """Return whether any key is set (the recording is then read as a foreign one)."""
        return any(getattr(self, k) is not None for k in self.keys()
                   if k not in ('step_rate', 'command_delay'))

    def check(self):
        """Raise RunError for a key outside its range."""
        kinds = [KIND_ALIASES.get(k, k) for k in _as_list(self.command_kind)]
        for kind in kinds:
            if kind is not None and kind not in COMMAND_KINDS:
                raise MappingError(f"<<command_kind>> {kind!r}: must be one of "
                                   f"{', '.join(COMMAND_KINDS)} (or ros2_control's "
                                   f"{', '.join(KIND_ALIASES)})")
        self.command_kind = _one_or_list(kinds)
        indexes = []
        for index in _as_list(self.command_index):
            if index is None:               # a map file's commands entry without one
                indexes.append(None)
                continue
            try:
                index = int(index)
            except (TypeError, ValueError):
                raise MappingError(f'<<command_index>> {index!r}: must be an '
                                   'integer >= 0') from None
            if index < 0:
                raise MappingError(f'<<command_index>> {index}: must be >= 0')
            indexes.append(index)
        self.command_index = _one_or_list(indexes)
        for key, lo, hi in (('command_delay', -10.0, 10.0), ('step_rate', 1.0, 1e6)):
            v = getattr(self, key)
            if v is None:
                continue
            try:
                v = float(v)
            except (TypeError, ValueError):
                v = math.nan
            if not (math.isfinite(v) and lo <= v <= hi):
                unit = 's' if key == 'command_delay' else 'Hz'
                raise MappingError(f'<<{key}>> {getattr(self, key)!r}: must lie '
                                   f'in [{lo:g}, {hi:g}] {unit}')
            setattr(self, key, v)
        for key in ('state_topic', 'screw_joint', 'nut_joint', 'command_topic',
                    'command_joint'):
            values = _as_list(getattr(self, key)) if key in ('command_topic', 'command_joint') \
                else [getattr(self, key)]
            for v in values:
                if v is not None and (not isinstance(v, str) or not v):
                    raise MappingError(f'<<{key}>> {v!r}: must be a non-empty '
                                       'name')
            if key in ('command_topic', 'command_joint'):
                setattr(self, key, _one_or_list(values))
        self.specs()                # the per-topic lists fit the topics

    def flags(self):
        """
        Return the options that give this mapping, for the user to copy.

        Each is named ``<<keyword>>``: :func:`..options.option_text` names it
        by its keyword, the command line by its flag.
        """
        out = []
        for key in self.keys():
            for v in _as_list(getattr(self, key)):
                out.append(f'<<{key}>> {v:g}' if isinstance(v, float) else f'<<{key}>> {v}')
        return ' '.join(out)


def _as_list(value):
    """Return ``value`` as a list: [] for None, itself for a list or tuple, else [value]."""
    if value is None:
        return []
    return list(value) if isinstance(value, (list, tuple)) else [value]


def _one_or_list(values):
    """Return None, the one value, or the list of several."""
    return None if not values else values[0] if len(values) == 1 else list(values)


#: Name parts that say a command's kind, in the order they are looked for.
KIND_HINTS = (('position', 'position'), ('velocity', 'velocity'), ('effort', 'torque'),
              ('torque', 'torque'))


def kind_from_name(topic):
    """
    Return the command kind a topic's name says (``/velocity_controller/commands``), or None.

    None for the node's state topics: ``nut_position`` names a position it reports.
    """
    if is_state_topic(topic):
        return None
    low = topic.lower()
    return next((k for h, k in KIND_HINTS if h in low), None)


def is_state_topic(topic):
    """Return whether ``topic`` is one of leadscrew_sim's state topics (in any namespace)."""
    return any(topic == '/' + graph_name(k) or topic.endswith('/' + graph_name(k))
               for k, (_t, role, _q) in TOPIC_SPECS.items() if role in ('state', 'switch'))


def read_map_file(path):
    """Return the keys of a mapping YAML file (``map``: a mapping of the option names)."""
    try:
        with open(path, encoding='utf-8') as fh:
            data = yamlio.load(fh)
    except OSError as exc:
        raise MappingError(f'<<map>> {path}: {exc.strerror or exc}') from None
    except yamlio.YAMLError as exc:
        raise MappingError(f'<<map>> {path}: cannot parse YAML: '
                           f'{str(exc).splitlines()[0]}') from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise MappingError(f'<<map>> {path}: expected a mapping of keys '
                           f'({", ".join(Mapping.keys())}, or commands: a list of topic, kind, '
                           'index, joint)')
    out = {}
    if isinstance(data.get('commands'), list):     # commands: [{topic: .., kind: ..}, ...]
        entries = data.pop('commands')
        for field in ('topic', 'kind', 'index', 'joint'):
            values = [e.get(field) if isinstance(e, dict) else None for e in entries]
            if field == 'topic' and not all(values):
                raise MappingError(f'<<map>> {path}: every entry of commands needs a topic')
            if any(v is not None for v in values):
                out[f'command_{field}'] = values
    for key, value in data.items():
        name = str(key).lstrip('-').replace('-', '_')
        if name not in Mapping.keys():
            raise MappingError(f'<<map>> {path}: unknown key {key!r} (keys: '
                               f'{", ".join(Mapping.keys())})')
        out[name] = value
    return out
