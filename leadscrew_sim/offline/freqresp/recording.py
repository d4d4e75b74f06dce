"""
The frequency response of a recording with broadband excitation (``freqresp RUN.mcap``).

:func:`recording_response` reads the node's recording of an ``excite chirp``
or ``excite multisine`` run (on the node or a real axis), or another source's
ros2 MCAP with the topic mapping ``identify`` has, picks the input and the
output by name, puts both on the steps' grid (doc/frequency_response.md: the
command acting over each step, the state stamped at its start) and returns
H1 and the coherence of :mod:`leadscrew_sim.analysis.freqresp.welch`.
"""
from dataclasses import dataclass
import math

import numpy as np

from ..options import NS, open_recording, RunError
from ...analysis.freqresp import welch
from ...io import cdr as C
from ...io.mcap_reader import RecordingError
from ...core.params import ParameterError
from ...io.run_file import PARAMS_RECORD, params_from_record

__all__ = ['INPUTS', 'OUTPUTS', 'RecordingOptions', 'recording_response']

#: Input name -> the command kind of its topic (external_force: its own topic).
INPUTS = {'torque': 'torque', 'velocity_command': 'velocity',
          'position_command': 'position', 'external_force': None}
#: Fields of a decoded JointState (stamp, names, position, velocity, effort).
_POS, _VEL, _EFF = 2, 3, 4
#: Output name -> (joint role, JointState field) of the states; None: not a joint value.
OUTPUTS = {'motor_angle': ('motor', _POS), 'motor_velocity': ('motor', _VEL),
           'motor_torque': ('motor', _EFF), 'nut_position': ('nut', _POS),
           'nut_velocity': ('nut', _VEL), 'thread_force': None,
           'following_error': ('motor', _POS)}
#: Joint of JointState commands of each kind, and its value field.
_COMMAND_FIELD = {'torque': ('screw', _EFF), 'velocity': ('nut', _VEL),
                  'position': ('nut', _POS)}
#: Rest kept before the first and after the last change of the input [s].
MARGIN_S = 1.0
#: Fewest frequency bins with input power for a broadband excitation.
MIN_BINS = 3


@dataclass
class RecordingOptions:
    """
    What :func:`recording_response` estimates and how it reads the recording.

    Attributes
    ----------
    input : str or None
        ``torque`` [N m], ``velocity_command`` [m/s], ``position_command`` [m]
        or ``external_force`` [N]; None: the kind of the one recorded command.
    output : str
        ``motor_angle`` [rad], ``motor_velocity`` [rad/s], ``nut_position`` [m],
        ``nut_velocity`` [m/s], ``thread_force`` [N], ``following_error`` [rad]
        (theta_ref - theta: the position command as a motor angle, h 2 pi / l
        x_ref, less the motor angle; the drive's on its motor encoder) or
        ``motor_torque`` [N m].
    fmin, fmax : float or None
        Band [Hz]; None: from the lowest bin to the Nyquist frequency.
    segments : int
        Welch segments (half overlapped, Hann), 1 .. 1000.
    state_topic : str or None
        JointState topic of the states (default ``joint_states``;
        ``sim/joint_states`` for the node's truth).
    command_topic : str or None
        Command topic (default: the input's own topic, e.g. ``velocity_command``,
        else ``joint_commands``).
    command_kind : str or None
        ``torque``, ``velocity`` or ``position``: what a Float64 ``command_topic``
        carries (needed when its name does not say).
    screw_joint, nut_joint : str or None
        Joint names in the states and JointState commands (default the
        recording's prefix + ``screw_joint`` / ``nut_joint``).
    step_rate : float or None
        Step rate [Hz] of a foreign recording (default: from its state stamps).
    command_index : int or None
        Entry of a std_msgs/Float64MultiArray command (default 0).
    command_joint : str or None
        Joint of JointState commands (default: the joint the kind names).
    command_delay : float or None
        Constant command-to-state delay [s]: the commands' times are shifted
        by it (default 0).
    map_file : str or None
        A mapping YAML file (the ``map`` option) with these mapping keys
        (:mod:`leadscrew_sim.offline.foreign.mapping`); a key set here wins.
    params : ScrewParams or None
        The axis (hand and lead) for ``following_error`` of a foreign
        recording; a leadscrew_sim recording has its own.

    """

    input: str = None
    output: str = 'motor_velocity'
    fmin: float = None
    fmax: float = None
    segments: int = 8
    state_topic: str = None
    command_topic: str = None
    command_kind: str = None
    screw_joint: str = None
    nut_joint: str = None
    step_rate: float = None
    command_index: int = None
    command_joint: str = None
    command_delay: float = None
    map_file: str = None
    params: object = None


def _check_options(o):
    """Raise RunError for an unknown name or a band or count out of range; read the map file."""
    from ..foreign.mapping import Mapping
    keys = {k: getattr(o, k) for k in Mapping.keys()}
    keys['map'] = o.map_file
    mapping = Mapping.from_args(type('MapOptions', (), keys)())
    for k in Mapping.keys():
        setattr(o, k, getattr(mapping, k))
    if o.input is not None and o.input not in INPUTS:
        raise RunError(f"<<input>> '{o.input}' is not an input ({', '.join(INPUTS)})")
    if o.output not in OUTPUTS:
        raise RunError(f"<<output>> '{o.output}' is not an output ({', '.join(OUTPUTS)})")
    if o.command_kind is not None and o.command_kind not in _COMMAND_FIELD:
        raise RunError(f"<<command_kind>> '{o.command_kind}' must be torque, velocity or "
                       'position')
    for name, v in (('fmin', o.fmin), ('fmax', o.fmax), ('step_rate', o.step_rate)):
        if v is not None and not (math.isfinite(v) and v > 0.0):
            raise RunError(f'<<{name}>> {v!r} must be a positive number [Hz]')
    if o.fmin is not None and o.fmax is not None and not o.fmin < o.fmax:
        raise RunError(f'<<fmax>> {o.fmax:g} Hz must exceed <<fmin>> {o.fmin:g} Hz')
    if not (isinstance(o.segments, int) and 1 <= o.segments <= 1000):
        raise RunError(f'<<segments>> {o.segments!r} must be a whole number in [1, 1000]')


def _topic(rec, name):
    """Return the recorded topic ``name`` (a relative name matches any namespace) or None."""
    found = rec.role_topic(name.lstrip('/')) if not name.startswith('/') else None
    if found:
        return found
    for topic in rec.topic_types:
        if topic == name or topic == '/' + name.lstrip('/') or topic.endswith('/' + name):
            return topic
    return None


class _Reader:
    """The recording's topics, joints and step grid, as the options map them."""

    def __init__(self, path, o):
        """Open the recording and find the topics of the input and the output."""
        try:
            rec = open_recording(path, load_messages=False)
            rec.require_ros2()
        except RecordingError as exc:
            raise RunError(str(exc)) from None
        self.rec, self.o, self.path = rec, o, path
        self.meta = rec.record(PARAMS_RECORD)
        counts = rec.statistics().channel_message_counts
        self.sizes = {c.topic: counts.get(i, 0) for i, c in rec.channels.items()}
        prefix = (self.meta or {}).get('joint_prefix', '')
        self.joints = {'screw': o.screw_joint or prefix + 'screw_joint',
                       'nut': o.nut_joint or prefix + 'nut_joint'}
        self.state_topic = self._require(o.state_topic or 'joint_states', 'the states')
        if rec.topic_types.get(self.state_topic) != 'sensor_msgs/msg/JointState':
            raise RunError(f'{path}: the state topic {self.state_topic} has type '
                           f'{rec.topic_types.get(self.state_topic)!r}, not '
                           'sensor_msgs/msg/JointState')
        self.input = o.input or self._recorded_input()
        self.command_topic, self.kind = self._command_topic(self.input)
        need = {self.state_topic, self.command_topic}
        if o.output == 'following_error':
            need.add(self.command_topic_of('position_command'))
        self.force_topic = _topic(rec, 'thread_force') if o.output == 'thread_force' else None
        rec.load(sorted(t for t in need | {self.force_topic} if t))

    def _require(self, name, what):
        """Return the recorded topic ``name``; RunError naming the topics without it."""
        topic = _topic(self.rec, name)
        if topic is None:
            raise RunError(f'{self.path}: no topic {name} for {what} (topics: '
                           f'{", ".join(sorted(self.rec.topic_types))})')
        return topic

    def _recorded_input(self):
        """Return the input of the one command topic recorded; RunError for none or several."""
        found = [n for n in ('torque', 'velocity_command', 'position_command')
                 if self.sizes.get(_topic(self.rec, f'{INPUTS[n]}_command'))]
        if self.o.command_kind and self.o.command_topic:
            found = [n for n in INPUTS if INPUTS[n] == self.o.command_kind]
        if len(found) != 1:
            raise RunError(f'{self.path}: give <<input>> ({", ".join(INPUTS)}): '
                           f'{"no" if not found else "more than one"} recorded command topic')
        return found[0]

    def command_topic_of(self, name):
        """Return the topic of the commands of input ``name``."""
        return self._command_topic(name)[0]

    def _command_topic(self, name):
        """Return (topic, command kind or None) of input ``name``."""
        kind = INPUTS[name]
        if kind is None:
            return self._require('external_force', 'the input external_force'), None
        own = self.o.command_topic
        if own is not None and self.o.command_kind not in (None, kind):
            own = None                          # a mapped topic of another kind
        found = [_topic(self.rec, t) for t in ([own] if own else []) +
                 [f'{kind}_command', 'joint_commands']]
        found = [t for t in found if t]
        if found:                           # the first with messages, else the first
            return next((t for t in found if self.sizes.get(t)), found[0]), kind
        raise RunError(f'{self.path}: no {kind} commands for the input {name} (no topic '
                       f'{own or kind + "_command"} nor joint_commands; topics: '
                       f'{", ".join(sorted(self.rec.topic_types))})')

    def grid(self, stamps):
        """Return (t0 [ns], dt [ns], tolerance [share of dt]) of the steps."""
        meta = self.meta or {}
        if self.o.step_rate:
            return int(stamps[0]), int(round(NS / self.o.step_rate)), 0.5
        if 'dt_ns' in meta and 't0_ns' in meta:
            return int(meta['t0_ns']), int(meta['dt_ns']), 1e-6
        if len(stamps) < 2:
            raise RunError(f'{self.path}: fewer than 2 states on {self.state_topic}')
        return int(stamps[0]), int(np.median(np.diff(stamps))), 0.5

    def messages(self, topic):
        """Return [(log time [ns], bytes)] of ``topic``."""
        return [(t, d) for t, tp, d in self.rec.messages if tp == topic]


def _joint_values(messages, joint, field, stamped):
    """Return (times [ns], values) of one field of one joint in JointState messages."""
    times, values = [], []
    for log_time, data in messages:
        msg = C.decode_joint_state(data)
        if joint in msg[1]:
            j = msg[1].index(joint)
            seq = msg[field]
            if j < len(seq) and math.isfinite(seq[j]):
                times.append(msg[0] if stamped else log_time)
                values.append(seq[j])
    return np.array(times, dtype=np.int64), np.array(values, dtype=float)


def _input_series(r, topic, kind):
    """Return (log times [ns] + the command delay, values) of the commands of ``kind``."""
    t, v = _commands(r, topic, kind)
    return t + int(round((r.o.command_delay or 0.0) * NS)), v


def _commands(r, topic, kind):
    """Return (log times [ns], values) of the commands of ``kind`` on ``topic``."""
    msgs = r.messages(topic)
    ctype = r.rec.topic_types.get(topic)
    if ctype == 'sensor_msgs/msg/JointState':
        role, field = _COMMAND_FIELD[kind]
        return _joint_values(msgs, r.o.command_joint or r.joints[role], field, stamped=False)
    if ctype == 'std_msgs/msg/Float64MultiArray':
        index = r.o.command_index or 0
        times, values = [], []
        for i, (t, d) in enumerate(msgs):
            a = C.decode_float64_multi_array(d)
            if index >= len(a):
                raise RunError(f'<<command_index>> {index}: past the array of message {i} on '
                               f'{topic} ({len(a)} entries)')
            if math.isfinite(a[index]):         # a NaN command is skipped, as the node does
                times.append(t)
                values.append(a[index])
        return np.array(times, dtype=np.int64), np.array(values, dtype=float)
    if ctype not in (None, 'std_msgs/msg/Float64'):
        raise RunError(f'<<command_topic>> {topic}: type {ctype!r} is not read by freqresp '
                       '(std_msgs/Float64, std_msgs/Float64MultiArray, sensor_msgs/JointState)')
    return (np.array([t for t, _d in msgs], dtype=np.int64),
            np.array([C.decode_float64(d) for _t, d in msgs], dtype=float))


def _output_series(r):
    """Return (stamps [ns], values) of the output."""
    out = r.o.output
    states = r.messages(r.state_topic)
    if out == 'thread_force' and r.force_topic:
        rows = [C.decode_wrench_stamped(d) for _t, d in r.messages(r.force_topic)]
        return (np.array([s for s, _f, _m in rows], dtype=np.int64),
                np.array([f[0] for _s, f, _m in rows], dtype=float))
    if out == 'thread_force':
        return _joint_values(states, r.joints['nut'], _EFF, stamped=True)
    role, field = OUTPUTS[out]
    joint = r.joints['screw']
    motor = joint.replace('screw_joint', 'motor_joint')
    if role == 'motor' and states and motor in C.decode_joint_state(states[0][1])[1]:
        joint = motor                       # the node's truth has the motor's own joint
    return _joint_values(states, joint if role == 'motor' else r.joints['nut'], field,
                         stamped=True)


def recording_response(path, options=None):
    """
    Return the :class:`FrequencyResponse` (H1, coherence) of a recording's input to its output.

    Raises :class:`RunError` (one line) for unknown names, a recording
    without the chosen signals, and one without broadband excitation (a
    constant input, or fewer than :data:`MIN_BINS` frequency bins with
    input power).

    Parameters
    ----------
    path : str or Path
        The MCAP file (ros2 profile).
    options : RecordingOptions, optional
        Signals, band, segments and topic mapping (default: the recorded
        command to ``motor_velocity`` over the whole band).

    """
    o = options or RecordingOptions()
    _check_options(o)
    r = _Reader(path, o)
    t_in, u_in = _input_series(r, r.command_topic, r.kind)
    if not len(t_in):
        raise RunError(f'{path}: no {r.input} commands on {r.command_topic}')
    stamps, y_out = _output_series(r)
    if not len(stamps):
        raise RunError(f'{path}: no {o.output} in the states on {r.state_topic} (joints '
                       f'{r.joints["screw"]}, {r.joints["nut"]})')
    t0, dt, tol = r.grid(np.sort(stamps))
    n = int((stamps.max() - t0) // dt) + 1
    u, y = welch.align(t0, dt, n, (t_in, u_in), (stamps, y_out), tolerance=tol)
    if o.output == 'following_error':
        topic = r.command_topic_of('position_command')
        target = _input_series(r, topic, 'position')
        if not len(target[0]):
            raise RunError(f'{path}: the output following_error needs position commands; '
                           f'none on {topic}')
        y = _angle_per_metre(r) * welch.held(*target, t0 + dt * np.arange(n) - dt) - y
    u, y, dropped = _window(path, r.input, u, y, dt / NS)
    try:
        resp = welch.welch_response(
            u, y, dt / NS, r.input, o.output, o.fmin, o.fmax, o.segments,
            notes=[f'recording {path}: {r.input} from {r.command_topic} (held from its log '
                   f'times), {o.output} from the states on {r.force_topic or r.state_topic} '
                   f'(stamps), {len(u)} steps of {dt / NS:g} s'
                   + (f', {dropped} missing states interpolated' if dropped else '')])
    except ValueError as exc:
        raise RunError(f'{path}: {exc}') from None
    if len(resp.frequency) < MIN_BINS:
        raise RunError(f'{path}: no broadband input: {r.input} has power in '
                       f'{len(resp.frequency)} frequency bins of the band (need '
                       f'{MIN_BINS}); record an `excite chirp` or `excite multisine` run')
    return resp


def _angle_per_metre(r):
    """Return h 2 pi / l [rad/m]: motor angle per nut travel (NutMap's k), of the recorded axis."""
    p = r.o.params
    if p is None and r.meta is not None:
        try:
            p = params_from_record(r.meta)[0]
        except ParameterError as exc:
            raise RunError(f'{r.path}: recorded {exc}') from None
    if p is None:
        raise RunError(f'{r.path}: the output following_error of a foreign recording needs '
                       'the axis (hand and lead): give RecordingOptions.params')
    return p.hand_sign * 2.0 * math.pi / p.lead


def _window(path, name, u, y, dt):
    """
    Return (u, y, states interpolated) over the excitation, MARGIN_S before and after it.

    RunError when the input never changes (no excitation) or most states are missing.
    """
    ok = np.flatnonzero(np.isfinite(u))
    if not len(ok):
        raise RunError(f'{path}: no {name} command before the last state')
    first = ok[0]
    changes = np.flatnonzero(np.diff(u[first:]) != 0.0)
    if not len(changes):
        raise RunError(f'{path}: no excitation: {name} holds {u[first]:g} throughout; record '
                       'an `excite chirp` or `excite multisine` run')
    m = int(round(MARGIN_S / dt))
    a = max(first, first + changes[0] - m)
    b = min(len(u), first + changes[-1] + 2 + m)
    u, y = u[a:b], y[a:b]
    have = np.flatnonzero(np.isfinite(y))
    if len(have) < 0.5 * len(y):
        raise RunError(f'{path}: {len(y) - len(have)} of the {len(y)} steps of the excitation '
                       'have no state')
    u, y = u[have[0]:have[-1] + 1], y[have[0]:have[-1] + 1]
    gaps = ~np.isfinite(y)
    if gaps.any():
        k = np.arange(len(y))
        y = np.interp(k, k[~gaps], y[~gaps])
    return u, y, int(gaps.sum())
