"""
How a foreign recording maps onto the model: its state and command topics, joints and timing.

The keys are the options of the verbs (``--state-topic``, ``--screw-joint``,
``--nut-joint``, ``--command-topic``, ``--command-kind``, ``--command-index``,
``--command-joint``, ``--command-delay``, ``--step-rate``) or the same keys
in a YAML file (``--map FILE``, dashes or underscores); an option given on
the command line wins over the file.
"""
import dataclasses
import math

from ...core import yamlio
from ..options import RunError

#: What a scalar command is: motor torque [N m], nut velocity [m/s], nut position [m].
COMMAND_KINDS = ('torque', 'velocity', 'position')

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
    command_topic : str
        The command topic (a type of :data:`COMMAND_TYPES`).
    command_kind : str
        torque, velocity or position: what a Float64 or Float64MultiArray
        command entry is (motor torque [N m], nut velocity [m/s], nut position [m]).
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
        Return the mapping of parsed options: ``--map FILE`` with the options on top, checked.

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

    @property
    def given(self):
        """Return whether any key is set (the recording is then read as a foreign one)."""
        return any(getattr(self, k) is not None for k in self.keys()
                   if k not in ('step_rate', 'command_delay'))

    def check(self):
        """Raise RunError for a key outside its range."""
        if self.command_kind is not None and self.command_kind not in COMMAND_KINDS:
            raise RunError(f"--command-kind {self.command_kind!r}: must be one of "
                           f"{', '.join(COMMAND_KINDS)}")
        if self.command_index is not None:
            try:
                self.command_index = int(self.command_index)
            except (TypeError, ValueError):
                raise RunError(f'--command-index {self.command_index!r}: must be an '
                               'integer >= 0') from None
            if self.command_index < 0:
                raise RunError(f'--command-index {self.command_index}: must be >= 0')
        for key, lo, hi in (('command_delay', -10.0, 10.0), ('step_rate', 1.0, 1e6)):
            v = getattr(self, key)
            if v is None:
                continue
            try:
                v = float(v)
            except (TypeError, ValueError):
                v = math.nan
            if not (math.isfinite(v) and lo <= v <= hi):
                raise RunError(f'--{key.replace("_", "-")} {getattr(self, key)!r}: must lie '
                               f'in [{lo:g}, {hi:g}] {"s" if key == "command_delay" else "Hz"}')
            setattr(self, key, v)
        for key in ('state_topic', 'screw_joint', 'nut_joint', 'command_topic',
                    'command_joint'):
            v = getattr(self, key)
            if v is not None and (not isinstance(v, str) or not v):
                raise RunError(f'--{key.replace("_", "-")} {v!r}: must be a non-empty name')

    def flags(self):
        """Return the options that give this mapping, for the user to copy."""
        out = []
        for key in self.keys():
            v = getattr(self, key)
            if v is not None:
                out.append(f'--{key.replace("_", "-")} {v:g}' if isinstance(v, float)
                           else f'--{key.replace("_", "-")} {v}')
        return ' '.join(out)


def read_map_file(path):
    """Return the keys of a ``--map`` YAML file (a mapping of the option names)."""
    try:
        with open(path, encoding='utf-8') as fh:
            data = yamlio.load(fh)
    except OSError as exc:
        raise RunError(f'--map {path}: {exc.strerror or exc}') from None
    except yamlio.YAMLError as exc:
        raise RunError(f'--map {path}: cannot parse YAML: {str(exc).splitlines()[0]}') from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise RunError(f'--map {path}: expected a mapping of keys ({", ".join(Mapping.keys())})')
    out = {}
    for key, value in data.items():
        name = str(key).lstrip('-').replace('-', '_')
        if name not in Mapping.keys():
            raise RunError(f'--map {path}: unknown key {key!r} (keys: '
                           f'{", ".join(Mapping.keys())})')
        out[name] = value
    return out
