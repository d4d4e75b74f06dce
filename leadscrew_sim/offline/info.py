"""
What one recording holds, as a result with named fields: the library behind ``info``.

:func:`info` reads a recording (a ros2-profile MCAP file or a rosbag2 bag)
and returns an :class:`InfoResult`: its channels and their rates, and, for a
leadscrew_sim run, the range of its states, its timing counts, the thread's
stick and contact shares with the energy balance (recorded, or from a
re-simulation), how the axis aged, its events and, on request, the derived
figures of an identification profile. A recording of another stack gets the
survey of its topics for the mapping instead.
"""
import dataclasses
import os

import numpy as np

from .foreign.survey import marked_lines
from .options import NS, open_recording, option_text, Progress, RunError
from .replay.resim import Resim
from .run_events import EventLog, recorded_events
from ..io import cdr as C, messages as M
from ..io.run_file import CLI_RECORD, PARAMS_RECORD, params_from_record

__all__ = ['ChannelInfo', 'info', 'InfoResult', 'ThreadShares']

#: The timing counts a node writes into the recording's metadata.
TIMING_KEYS = ('overruns', 'late_ticks', 'skipped_steps', 'catchup_steps')


@dataclasses.dataclass(frozen=True)
class ChannelInfo:
    """One channel: ``topic``, its ``type``, ``count`` messages, ``rate`` [Hz] (None: < 2)."""

    topic: str
    type: str
    count: int
    rate: float


@dataclasses.dataclass(frozen=True)
class ThreadShares:
    """
    The thread's states over a run and its energy balance.

    ``source``: where they come from (the recorded sim/thread_state or a
    re-simulation); ``stick``: the stuck share of the loaded steps [-];
    ``contact``: {leading, trailing, backlash: share of the steps [-]};
    ``energy``: the model's energy terms [J]; ``residual``: input and
    external work less everything stored and dissipated [J].
    """

    source: str
    stick: float
    contact: dict
    energy: dict
    residual: float


@dataclasses.dataclass
class InfoResult:
    """
    What :func:`info` found in a recording.

    ``path``; ``kind`` ('MCAP file' or the bag's storage and file count);
    ``size`` [B]; ``profile`` and ``library`` of the file; ``start``, ``end``
    and ``duration`` of its log time [s]; ``messages``; ``channels`` (a
    :class:`ChannelInfo` each, by topic). A leadscrew_sim run (``leadscrew``
    True) adds ``run`` (preset, update_rate [Hz], clock_mode), ``states``
    (nut_min, nut_max, nut_final [m], max_nut_speed [m/s], max_screw_speed
    [rad/s], max_motor_torque [N m]; only those recorded), ``timing`` (the
    node's overrun and late-tick counts), ``thread`` (:class:`ThreadShares`,
    None without either source), ``ageing`` (the first and last
    sim/ageing values, None without), ``events`` (time [s] and text each) and
    ``figures`` ({profile, kind, figures}: the derived figures, None unless
    asked). Another stack's recording has ``survey`` instead: the lines that
    describe its topics for the mapping, each option named by its keyword
    (:meth:`survey_text` names them otherwise, as ``info`` does by flags).
    """

    path: str
    kind: str
    size: int
    profile: str
    library: str
    start: float
    end: float
    duration: float
    messages: int
    channels: list
    leadscrew: bool = False
    run: dict = None
    states: dict = None
    timing: dict = None
    thread: ThreadShares = None
    ageing: dict = None
    events: list = None
    figures: dict = None
    survey: list = None
    marked: list = dataclasses.field(default=None, repr=False)

    def survey_text(self, name_of=None):
        """Return the survey's lines with each option named by ``name_of(keyword)``."""
        return [option_text(line, name_of) for line in self.marked or ()]


def info(recording, figures=None, resim=True, quiet=True):
    """
    Return what a recording holds (:class:`InfoResult`).

    Parameters
    ----------
    recording : str, path or Recording
        A ros2-profile MCAP file or a rosbag2 bag directory
        (``ls.open_recording``'s Recording: its path).
    figures : str, optional
        Also derive the figures of this identification profile (breakaway,
        sweep, reversals, iso230; 'auto': the profile the run's excite
        recorded). Only for a leadscrew_sim run.
    resim : bool
        Re-simulate the run for its events and, when the thread's states
        were not recorded, its stick share and energy balance.
    quiet : bool
        No progress bar (it shows on a terminal only).

    Raises
    ------
    RunError
        A recording that cannot be read, or ``figures`` naming no profile
        with derived figures.

    """
    path = str(getattr(recording, 'path', recording))
    if figures is not None and not isinstance(figures, str):
        raise RunError(f'<<figures>> {figures!r}: a profile name or \'auto\'')
    rec = open_recording(path)
    rec.require_ros2()
    out = _channels(path, rec)
    meta = rec.record(PARAMS_RECORD)
    if meta is None:
        out.marked = marked_lines(rec)
        out.survey = out.survey_text()
        return out
    name = _figures_profile(path, rec, figures)
    out.leadscrew = True
    out.run = {k: meta.get(k) for k in ('preset', 'update_rate', 'clock_mode')}
    out.states = _states(rec)
    out.timing = {k: data[k] for _name, data in rec.metadata for k in TIMING_KEYS
                  if k in data}
    recorded = rec.role_topic('sim/thread_state')
    if recorded:
        out.thread = _recorded_thread(rec)
    out.ageing = _ageing(rec)
    if not resim:
        params, _missing = params_from_record(meta)
        out.events = list(recorded_events(rec, meta, params))
    else:
        thread, out.events = _resim(rec, quiet, energy=not recorded)
        out.thread = out.thread or thread
    if name:
        out.figures = _figures(path, rec, meta, name)
    return out


def _channels(path, rec):
    """Return the InfoResult of the file alone: its size, span and channels."""
    st = rec.statistics()
    size = rec.size() if hasattr(rec, 'size') else os.path.getsize(path)
    counts = dict(st.channel_message_counts) if st else {}
    t_first = st.message_start_time if st and st.message_count else 0
    t_last = st.message_end_time if st and st.message_count else 0
    kind = (f'rosbag2 bag, {rec.storage} storage, {len(rec.files)} file(s)'
            if hasattr(rec, 'files') else 'MCAP file')
    span = (t_last - t_first) / NS
    channels = []
    for cid, ch in sorted(rec.channels.items(), key=lambda c: c[1].topic):
        n = counts.get(cid, 0)
        channels.append(ChannelInfo(ch.topic, rec.topic_types.get(ch.topic, ''), n,
                                    (n - 1) / span if n > 1 and span > 0 else None))
    return InfoResult(path=path, kind=kind, size=size, profile=rec.profile,
                      library=rec.header.library, start=t_first / NS, end=t_last / NS,
                      duration=span, messages=st.message_count if st else 0,
                      channels=channels)


def _figures_profile(path, rec, name):
    """Return the profile whose figures are asked (None: none); check it first."""
    from ..analysis.excitation.profiles import PROFILES
    if name == 'auto':
        source = (rec.record(CLI_RECORD) or {}).get('torque_input', '')
        name = source.split()[0][len('excite='):] if source.startswith('excite=') else ''
        if not name:
            raise RunError(f'{path}: no <<excite>> profile recorded; give <<figures>> '
                           f'PROFILE ({", ".join(PROFILES)})')
    if name is not None and name not in PROFILES:
        raise RunError(f'<<figures>> {name!r}: no such profile ({", ".join(PROFILES)})')
    if name == 'warmup':
        raise RunError(f'<<figures>> warmup: the warm-up\'s figure is the drift at its stops '
                       f'(leadscrew_sim plot {path})')
    if name is not None and not getattr(PROFILES[name], 'figures', True):
        raise RunError(f'<<figures>> {name}: a frequency-response profile has no derived '
                       f'figures (leadscrew_sim freqresp {path})')
    return name


def _figures(path, rec, meta, name):
    """Return {profile, kind, figures}: the derived figures of an identification run."""
    from ..analysis import figures as F
    from ..analysis.excitation.profiles import PROFILES
    kind = PROFILES[name].kind
    topic = rec.role_topic(f'{kind}_command')
    js_topic = rec.role_topic('joint_states')
    cmd_t, cmd_v, rows = [], [], []
    for t, tp, data in rec.messages:
        if tp == topic:
            cmd_t.append(t / NS)
            cmd_v.append(C.decode_float64(data))
        elif tp == js_topic:
            stamp, _n, pos, vel, eff = C.decode_joint_state(data)
            if len(pos) >= 2 and len(vel) >= 2 and eff:
                rows.append((stamp / NS, eff[0], vel[0], pos[1], vel[1]))
    if not cmd_t or not rows:
        raise RunError(f'{path}: <<figures>> {name} needs {kind}_command and joint_states '
                       'messages')
    t, tq, w, x, v = (np.array(c) for c in zip(*rows))
    run = dict(time=t, command=F.hold_series(cmd_t, cmd_v, t), motor_torque=tq,
               motor_velocity=w, nut_position=x, nut_velocity=v)
    params, _missing = params_from_record(meta)
    return {'profile': name, 'kind': kind,
            'figures': F.derived_figures(name, run, load=F.axial_load(params))}


def _states(rec):
    """Return the range of the nut position [m] and the largest speeds and torque."""
    js_topic = rec.role_topic('joint_states')
    xs, vs, ws, tqs = [], [], [], []
    for _t, topic, data in rec.messages:
        if topic == js_topic:
            _s, _names, pos, vel, eff = C.decode_joint_state(data)
            if len(pos) >= 2:
                xs.append(pos[1])
            if len(vel) >= 2:
                vs.append(abs(vel[1]))
                ws.append(abs(vel[0]))
            if eff:
                tqs.append(abs(eff[0]))
    out = {}
    if xs:
        out.update(nut_min=min(xs), nut_max=max(xs), nut_final=xs[-1])
    if vs:
        out.update(max_nut_speed=max(vs), max_screw_speed=max(ws))
    if tqs:
        out.update(max_motor_torque=max(tqs))
    return out


def _shares(source, sticks, contacts, e):
    """Return the ThreadShares of the steps' stick flags and contact sides, energy ``e``."""
    loaded = [s for s in sticks if s >= 0]
    stick = sum(1 for s in loaded if s == 1) / len(loaded) if loaded else 0.0
    n = max(1, len(contacts))
    side = {name: sum(1 for c in contacts if c == k) / n
            for k, name in ((1, 'leading'), (-1, 'trailing'), (0, 'backlash'))}
    residual = (e['input_work'] + e['external_work'] - e['kinetic'] - e['potential']
                - e['spring'] - e['friction_dissipation'] - e['damping_dissipation'])
    return ThreadShares(source, stick, side, dict(e), residual)


def _recorded_thread(rec):
    """Return the ThreadShares recorded in sim/thread_state (None: no message)."""
    topic = rec.role_topic('sim/thread_state')
    sticks, contacts, last = [], [], None
    for _t, tp, data in rec.messages:
        if tp == topic:
            _stamp, last = M.decode_analysis(data)
            sticks.append(last['stick_a'])
            contacts.append(last['contact_a'])
    if last is None:
        return None
    return _shares('recorded in sim/thread_state', sticks, contacts, last)


def _ageing(rec):
    """Return the first and last sim/ageing values and the screw's temperature range."""
    topic = rec.role_topic('sim/ageing')
    first = last = None
    t_lo = t_hi = None
    for _t, tp, data in rec.messages:
        if tp == topic:
            _stamp, last = M.decode_ageing(data)
            first = first or last
            temp = last['screw_temperature']
            t_lo = temp if t_lo is None else min(t_lo, temp)
            t_hi = temp if t_hi is None else max(t_hi, temp)
    if first is None:
        return None
    return {'first': first, 'last': last, 'temperature_range': (t_lo, t_hi)}


def _resim(rec, quiet, energy=True):
    """Return (ThreadShares or None, events) of a re-simulation of the recording."""
    sim = Resim(rec)
    model = sim.model()
    log = EventLog(sim.params, sim.dt_ns)
    sticks, contacts = [], []
    for _seg, cols in sim.blocks(model, progress=Progress(sim.n_steps, 'info', quiet),
                                 log=log):
        if energy:
            sticks += cols['stick_a'].tolist()
            contacts += cols['contact'].tolist()
    thread = None
    if contacts:
        thread = _shares('re-simulated from the recorded parameters and commands', sticks,
                         contacts, model.energy())
    return thread, list(log.events())
