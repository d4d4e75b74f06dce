"""
``plot``: one PNG with four panels of a recording (forces from the file, or re-simulated).

A foreign recording (a real axis's bag, mapped by the options) is
re-simulated as its twin with ``--preset``/``--params``: the panels show the
twin, the first one the measured nut position over it. A recording of an
ageing axis (its ``sim/ageing`` changes) gets two more panels: the drift at
the measurement stops of a warm-up run (ISO 230-3) against time beside the
screw temperature, with the screw's growth at each stop overlaid, and the
wear, backlash and lubricant against time.
"""
from pathlib import Path

import numpy as np

from .args import add_mapping_arguments
from ..offline.foreign.mapping import Mapping
from ..offline.ageing_panels import ageing_arrays, drift_panel, wear_panel
from ..offline.options import load_params, NS, open_recording, parse_sets, Progress, RunError
from ..offline.replay.resim import Resim
from ..io import cdr as C, messages as M
from ..io.run_file import PARAMS_RECORD

HELP = 'four-panel PNG of a leadscrew_sim recording'

#: StepOutput fields the panels show.
COLUMNS = ('nut_position', 'nut_velocity', 'screw_angle', 'motor_torque', 'normal_leading',
           'normal_trailing', 'friction_force', 'contact', 'stuck')


def add_arguments(p):
    """Add the options of ``plot`` to parser ``p``."""
    p.add_argument('file', help='the recording (MCAP file or rosbag2 bag directory)')
    p.add_argument('--output', '-o', metavar='FILE.png', help='PNG path (default <stem>.png)')
    p.add_argument('--width', type=int, default=1200, help='image width [px] (default 1200)')
    p.add_argument('--height', type=int, default=900, help='image height [px] (default 900)')
    p.add_argument('--dpi', type=int, default=100,
                   help='resolution [dots per inch] (default 100)')
    p.add_argument('--quiet', '-q', action='store_true', help='no progress bar')
    g = add_mapping_arguments(p)
    g.add_argument('--preset', help='the twin\'s parameters: a preset (a foreign recording)')
    g.add_argument('--params', help='the twin\'s parameters: a ROS 2 parameter file')
    g.add_argument('--set', action='append', metavar='NAME=VALUE',
                   help='a parameter of the twin (repeatable; YAML scalar in its unit)')


def _recorded(rec):
    """Return (stamps [ns], the COLUMNS) from sim/joint_states and sim/thread_state, or None."""
    truth_topic, thread_topic = rec.role_topic('sim/joint_states'), rec.role_topic(
        'sim/thread_state')
    if not (truth_topic and thread_topic):
        return None
    truth, thread = {}, {}
    for _t, topic, data in rec.messages:
        if topic == truth_topic:
            stamp, _names, pos, vel, eff = C.decode_joint_state(data)
            truth[stamp] = (pos[1], pos[2], vel[2], eff[0])
        elif topic == thread_topic:
            stamp, v = M.decode_analysis(data)
            thread[stamp] = (v['normal_leading_a'], v['normal_trailing_a'], v['friction_a'],
                             v['contact_a'], v['stick_a'] == 1.0)
    stamps = sorted(set(truth) & set(thread))
    if not stamps:
        return None
    rows = [truth[s] + thread[s] for s in stamps]
    names = ('screw_angle', 'nut_position', 'nut_velocity', 'motor_torque', 'normal_leading',
             'normal_trailing', 'friction_force', 'contact', 'stuck')
    col = {name: np.array([r[i] for r in rows], dtype=float) for i, name in enumerate(names)}
    return np.array(stamps, dtype=np.int64), col


def run(args):
    """Write one PNG with four panels (from the file, or re-simulated for an older file)."""
    rec = open_recording(args.file)
    mapping = Mapping.from_args(args)
    measured = None
    if mapping.given or args.preset or args.params or rec.record(PARAMS_RECORD) is None:
        sim, t, col, measured = _twin(args, rec, mapping)
        source = f'of the twin ({sim.meta["preset"]}) re-simulated from the mapped commands'
        ageing = None
    else:
        sim, t, col, source = _own(args, rec)
        ageing = ageing_arrays(rec, sim)
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    rows = 2 if ageing is None else 3
    w_in, h_in = args.width / args.dpi, args.height / args.dpi * rows / 2
    fig, axs = plt.subplots(rows, 2, figsize=(w_in, h_in), dpi=args.dpi)
    fig.suptitle(f'{Path(args.file).name}: preset {sim.meta.get("preset", "?")}, '
                 f'{NS / sim.dt_ns:g} Hz', fontsize=10)
    _motion_panel(axs[0, 0], t, col, measured)
    _force_panel(axs[0, 1], t, col)
    _backlash_panel(axs[1, 0], col, sim.params)
    ax = axs[1, 1]
    ax.plot(col['nut_position'] * 1e3, col['nut_velocity'] * 1e3, 'C0', lw=0.6)
    ax.set_xlabel('nut position [mm]')
    ax.set_ylabel('nut velocity [mm/s]')
    ax.set_title('phase portrait', fontsize=9)
    if ageing is not None:
        drift_panel(axs[2, 0], ageing, sim.params)
        wear_panel(axs[2, 1], ageing)
    for a in axs.flat:
        a.grid(True, lw=0.3)
    fig.tight_layout()
    src = Path(args.file)
    out = args.output or (str(src) + '.png' if src.is_dir() else str(src.with_suffix('.png')))
    try:
        fig.savefig(out, dpi=args.dpi)
    except OSError as exc:
        raise RunError(f'cannot write {out}: {exc.strerror or exc}') from None
    plt.close(fig)
    size = f'{args.width}x{int(round(h_in * args.dpi))} px'
    print(f'wrote {out} ({size}; forces and contact {source})')
    if ageing is not None and ageing['stops']:
        first = {}
        drift = [(r[0], r[1], r[2] - first.setdefault(round(r[1], 9), r[2]))
                 for r in ageing['stops']]
        worst = max(drift, key=lambda r: abs(r[2]))
        print(f'warm-up drift at {len(drift)} stops since the first at each position: largest '
              f'{worst[2] * 1e6:+.2f} um at {worst[1] * 1e3:g} mm, t = {worst[0]:.1f} s; screw '
              f'{ageing["screw_temperature"][0]:.2f} .. '
              f'{ageing["screw_temperature"].max():.2f} degC')
    return 0


def _own(args, rec):
    """Return (Resim, time [s], the COLUMNS, source) of a leadscrew_sim recording."""
    sim = Resim(rec)
    recorded = _recorded(rec)
    if recorded is not None:
        stamps, col = recorded
        # time from the recording's start: its t0, else one step before its first state
        start = sim.t0 if 't0_ns' in sim.meta else int(stamps[0]) - sim.dt_ns
        t = (stamps - start) / NS
        source = 'recorded'
    else:
        model = sim.model()
        parts = [cols for _seg, cols in sim.blocks(
            model, progress=Progress(sim.n_steps, 'plot', args.quiet))]
        if not parts:
            raise RunError(f'{args.file}: no steps to plot')
        col = {name: np.concatenate([p[name] for p in parts]).astype(float)
               for name in COLUMNS}
        t = sim.dt_ns * np.arange(1, len(col['nut_position']) + 1) / NS   # from the start
        source = 're-simulated from the recorded parameters and commands'
    return sim, t, col, source


def _twin(args, rec, mapping):
    """Return (a stand-in for Resim, time [s], the COLUMNS, measured nut position) of a twin."""
    import types
    from ..offline.foreign.replay import ForeignReplay
    rec.require_ros2()
    if not (args.preset or args.params):
        raise RunError(f'{args.file}: not a leadscrew_sim recording: give the twin\'s '
                       'parameters (--preset NAME or --params FILE) and the mapping flags '
                       f'(`leadscrew_sim info {args.file}` prints those that fit)')
    phys, run_ov = parse_sets(args.set)
    if run_ov:
        raise RunError('plot --set accepts physics parameters only')
    params, label, _extra = load_params(args, phys)
    rep = ForeignReplay(mapping, rec, params, estimate_delay=True)
    cols = rep.replay({}, interpolate=False)
    col = {name: np.asarray(cols[name], dtype=float) for name in COLUMNS}
    t = rep.dt_ns * np.arange(1, rep.n_steps + 1) / NS
    x = rep.states.values.get('nut_position')
    measured = None if x is None else ((rep.states.stamps - rep.t0) / NS, x)
    sim = types.SimpleNamespace(params=rep.params, dt_ns=rep.dt_ns, meta={'preset': label})
    return sim, t, col, measured


def _motion_panel(ax, t, col, measured=None):
    """Nut position [mm], nut velocity [mm/s] and motor torque [mN m] over time [s]."""
    ax.plot(t, col['nut_position'] * 1e3, 'C0', lw=1, label='nut position [mm]')
    if measured is not None:
        ax.plot(measured[0], measured[1] * 1e3, '.', color='k', ms=1.5,
                label='measured nut position [mm]')
    ax.set_xlabel('time [s]')
    ax.set_ylabel('nut position [mm]', color='C0')
    ax2 = ax.twinx()
    ax2.plot(t, col['nut_velocity'] * 1e3, 'C1', lw=0.8, label='nut velocity [mm/s]')
    ax2.plot(t, col['motor_torque'] * 1e3, 'C2', lw=0.8, label='motor torque [mN m]')
    ax2.set_ylabel('velocity [mm/s], torque [mN m]')
    lines = ax.get_lines() + ax2.get_lines()
    ax.legend(lines, [ln.get_label() for ln in lines], fontsize=7, loc='best')
    ax.set_title('position, velocity, torque', fontsize=9)


def _force_panel(ax, t, col):
    """Thread normal and friction forces [N] over time [s], stick and contact side shaded."""
    stuck = col['stuck'] > 0.5
    ax.fill_between(t, 0, 1, where=stuck, color='0.85', step='post',
                    transform=ax.get_xaxis_transform(), label='stick')
    for c, name, color in ((1, 'leading flank', 'C3'), (-1, 'trailing flank', 'C4'),
                           (0, 'in backlash', 'C7')):
        ax.fill_between(t, 0.96, 1.0, where=col['contact'] == c, color=color, step='post',
                        transform=ax.get_xaxis_transform(), label=f'contact: {name}')
    ax.plot(t, col['normal_leading'], 'C3', lw=0.8, label='normal force, leading [N]')
    ax.plot(t, col['normal_trailing'], 'C4', lw=0.8, label='normal force, trailing [N]')
    ax.plot(t, col['friction_force'], 'k', lw=0.8, label='friction force [N]')
    ax.set_xlabel('time [s]')
    ax.set_ylabel('force [N]')
    ax.legend(fontsize=7, loc='best')
    ax.set_title('thread forces of nut A, stick shaded, contact side on top', fontsize=9)


def _backlash_panel(ax, col, p):
    """Nut position minus its nominal x(theta) [um] over the screw angle [rad]."""
    rt = p.lead_ratio
    dev = col['nut_position'] - rt * p.hand_sign * col['screw_angle']
    ax.plot(col['screw_angle'], dev * 1e6, 'C0', lw=0.8)
    ax.axhline(0.5 * p.backlash * 1e6, color='0.5', ls='--', lw=0.8)
    ax.axhline(-0.5 * p.backlash * 1e6, color='0.5', ls='--', lw=0.8)
    ax.set_xlabel('screw angle [rad]')
    ax.set_ylabel('x - x_nominal(theta) [um]')
    ax.set_title(f'backlash hysteresis (dashed: +-b/2, b = {p.backlash * 1e6:g} um)',
                 fontsize=9)
