"""``info`` (``summary``): one screen about a recording (any ros2-profile MCAP)."""
import os

import numpy as np

from ..offline.options import NS, open_recording, Progress, RunError
from ..offline.replay.resim import Resim
from ..io import cdr as C, messages as M
from ..io.run_file import PARAMS_RECORD, params_from_record
from ..offline.run_events import EventLog, recorded_events
from .event_lines import print_events
from ..offline.foreign.survey import foreign_lines

HELP = 'one screen about a recording'


def add_arguments(p):
    """Add the options of ``info`` to parser ``p``."""
    p.add_argument('file', help='the recording (any ros2-profile MCAP, or a rosbag2 bag '
                   'directory)')
    p.add_argument('--no-resim', action='store_true',
                   help='skip the re-simulation (stick fraction, energy)')
    p.add_argument('--figures', metavar='PROFILE', nargs='?', const='auto',
                   help='also print the derived figures of an identification run (breakaway, '
                        'sweep, reversals, iso230; without a name: the profile simulate '
                        '--excite recorded)')
    p.add_argument('--quiet', '-q', action='store_true', help='no progress bar')


def run(args):
    """Print one screen about a recording; return the exit status."""
    rec = open_recording(args.file)
    rec.require_ros2()
    meta = rec.record(PARAMS_RECORD)
    figures = _figures_profile(args, rec) if meta is not None else None
    _print_channels(args, rec)
    if meta is None:
        print('(not a leadscrew_sim recording)')
        for line in foreign_lines(rec):
            print(line)
        return 0
    print(f'leadscrew_sim run: preset {meta.get("preset", "?")}, '
          f'{meta.get("update_rate", "?")} Hz, clock_mode {meta.get("clock_mode", "?")}')
    _print_states(rec)
    timing = {}
    for _name, data in rec.metadata:
        for key in ('overruns', 'late_ticks', 'skipped_steps', 'catchup_steps'):
            if key in data:
                timing[key] = data[key]
    print('timing: ' + (', '.join(f'{k} {v}' for k, v in timing.items()) if timing else
                        'no overrun/late-tick counts in the metadata'))
    recorded = rec.role_topic('sim/thread_state')
    if recorded:
        _print_recorded(rec)
    _print_ageing(rec)
    if args.no_resim:
        params, _missing = params_from_record(meta)
        print_events(recorded_events(rec, meta, params))
    else:
        _print_resim(args, rec, energy=not recorded)
    if figures:
        _print_figures(args, rec, meta, figures)
    return 0


def _figures_profile(args, rec):
    """Return the profile name of ``--figures`` (None without it); check it first."""
    from ..analysis.excitation.profiles import PROFILES
    from ..io.run_file import CLI_RECORD
    name = args.figures
    if name == 'auto':
        source = (rec.record(CLI_RECORD) or {}).get('torque_input', '')
        name = source.split()[0][len('excite='):] if source.startswith('excite=') else ''
        if not name:
            raise RunError(f'{args.file}: no --excite profile recorded; give --figures '
                           f'PROFILE ({", ".join(PROFILES)})')
    if name is not None and name not in PROFILES:
        raise RunError(f'--figures {name!r}: no such profile ({", ".join(PROFILES)})')
    if name == 'warmup':
        raise RunError(f'--figures warmup: the warm-up\'s figure is the drift at its stops '
                       f'(leadscrew_sim plot {args.file})')
    if name is not None and not getattr(PROFILES[name], 'figures', True):
        raise RunError(f'--figures {name}: a frequency-response profile has no derived '
                       f'figures (leadscrew_sim freqresp {args.file})')
    return name


def _print_figures(args, rec, meta, name):
    """Print the derived figures of an identification profile run (core.figures)."""
    from ..analysis import figures as F
    from .figure_lines import format_figures
    from ..analysis.excitation.profiles import PROFILES
    from ..io.run_file import params_from_record
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
        raise RunError(f'{args.file}: --figures {name} needs {kind}_command and joint_states '
                       'messages')
    t, tq, w, x, v = (np.array(c) for c in zip(*rows))
    run = dict(time=t, command=F.hold_series(cmd_t, cmd_v, t), motor_torque=tq,
               motor_velocity=w, nut_position=x, nut_velocity=v)
    params, _missing = params_from_record(meta)
    print(f'derived figures of the {name} run (core.figures, from joint_states and '
          f'{kind}_command):')
    for line in format_figures(F.derived_figures(name, run, load=F.axial_load(params))):
        print('  ' + line)


def _print_channels(args, rec):
    """Print the file, its duration and the message count and rate [Hz] of each channel."""
    st = rec.statistics()
    size = rec.size() if hasattr(rec, 'size') else os.path.getsize(args.file)
    counts = dict(st.channel_message_counts) if st else {}
    t_first = st.message_start_time if st and st.message_count else 0
    t_last = st.message_end_time if st and st.message_count else 0
    kind = (f'rosbag2 bag, {rec.storage} storage, {len(rec.files)} file(s)'
            if hasattr(rec, 'files') else 'MCAP file')
    print(f'file:      {args.file} ({kind}, {size} B), profile {rec.profile!r}, '
          f'library {rec.header.library!r}')
    print(f'duration:  {(t_last - t_first) / NS:.6f} s (log time {t_first / NS:.6f} .. '
          f'{t_last / NS:.6f} s), {st.message_count if st else 0} messages')
    print(f'{"topic":<28} {"type":<34} {"count":>8} {"rate Hz":>9}')
    span = (t_last - t_first) / NS
    for cid, ch in sorted(rec.channels.items(), key=lambda c: c[1].topic):
        n = counts.get(cid, 0)
        rate = f'{(n - 1) / span:.1f}' if n > 1 and span > 0 else '-'
        print(f'{ch.topic:<28} {rec.topic_types.get(ch.topic, ""):<34} {n:>8} {rate:>9}')


def _print_states(rec):
    """Print the range of the nut position [m] and the largest velocities and torque."""
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
    if xs:
        print(f'nut position: min {min(xs):.6g} m, max {max(xs):.6g} m, '
              f'final {xs[-1]:.6g} m')
    if vs:
        print(f'max |velocity|: nut {max(vs):.6g} m/s, screw {max(ws):.6g} rad/s')
    if tqs:
        print(f'max |motor torque|: {max(tqs):.6g} N m')


def _shares(sticks, contacts):
    """Return the stuck share of the loaded steps and the share of each contact side."""
    loaded = [s for s in sticks if s >= 0]
    stick = sum(1 for s in loaded if s == 1) / len(loaded) if loaded else 0.0
    n = max(1, len(contacts))
    side = {name: sum(1 for c in contacts if c == k) / n
            for k, name in ((1, 'leading'), (-1, 'trailing'), (0, 'backlash'))}
    return stick, side


def _print_energy(source, stick, side, e):
    residual = (e['input_work'] + e['external_work'] - e['kinetic'] - e['potential']
                - e['spring'] - e['friction_dissipation'] - e['damping_dissipation'])
    print(f'({source}) thread stuck {100 * stick:.1f}% of loaded steps; contact ' +
          ', '.join(f'{k} {100 * v:.1f}%' for k, v in side.items()))
    print(f'energy: input work {e["input_work"]:.6g} J, friction dissipated '
          f'{e["friction_dissipation"]:.6g} J, damping dissipated '
          f'{e["damping_dissipation"]:.6g} J (balance residual {residual:.3g} J)')


def _print_recorded(rec):
    """Print the stick and contact shares and the energy balance [J] recorded in the file."""
    topic = rec.role_topic('sim/thread_state')
    sticks, contacts, last = [], [], None
    for _t, tp, data in rec.messages:
        if tp == topic:
            _stamp, last = M.decode_analysis(data)
            sticks.append(last['stick_a'])
            contacts.append(last['contact_a'])
    if last is not None:
        _print_energy('recorded in sim/thread_state', *_shares(sticks, contacts), last)


def _print_ageing(rec):
    """Print how the axis aged over the recording (its sim/ageing), if it did."""
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
        return
    print(f'ageing: wear leading {first["wear_leading"] * 1e6:.4g} -> '
          f'{last["wear_leading"] * 1e6:.4g} um, trailing {first["wear_trailing"] * 1e6:.4g} '
          f'-> {last["wear_trailing"] * 1e6:.4g} um; backlash {first["backlash"] * 1e6:.4g} -> '
          f'{last["backlash"] * 1e6:.4g} um; lubricant {first["lubricant"]:.4g} -> '
          f'{last["lubricant"]:.4g} (mu_k {last["mu_k"]:.4g}); screw {t_lo:.4g} .. '
          f'{t_hi:.4g} degC, growth at the nut {last["thermal_growth"] * 1e6:.4g} um')


def _print_resim(args, rec, energy=True):
    """Print the events of a re-simulation; with ``energy`` its stick, contact and energy too."""
    sim = Resim(rec)
    model = sim.model()
    log = EventLog(sim.params, sim.dt_ns)
    sticks, contacts = [], []
    for _seg, cols in sim.blocks(model, progress=Progress(sim.n_steps, 'info', args.quiet),
                                 log=log):
        if energy:
            sticks += cols['stick_a'].tolist()
            contacts += cols['contact'].tolist()
    if contacts:
        _print_energy('re-simulated from the recorded parameters and commands',
                      *_shares(sticks, contacts), model.energy())
    print_events(log.events())
