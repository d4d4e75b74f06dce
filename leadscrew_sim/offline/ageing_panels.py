"""
The ageing row of ``plot``: drift at a warm-up's stops beside the screw temperature, wear.

:func:`ageing_arrays` reads an own recording's ``sim/ageing``, its true nut
position and its position commands; :func:`drift_panel` and
:func:`wear_panel` draw them on matplotlib axes (SI units shown in um, degC).
"""
import numpy as np

from .options import NS
from ..analysis.figures import hold_series, thermal_drift
from ..io import cdr as C, messages as M


def ageing_arrays(rec, sim):
    """
    Return the ageing arrays of an own recording (None when its axis does not age).

    time [s], the fields of sim/ageing, the true nut position in the frame
    [m] (nut position plus thermal growth) and the measurement stops of a
    warm-up run (figures.thermal_drift of the position commands).
    """
    topic = rec.role_topic('sim/ageing')
    truth_topic = rec.role_topic('sim/joint_states')
    if not (topic and truth_topic):
        return None
    ageing, truth = {}, {}
    cmd_topic = rec.role_topic('position_command')
    cmd_t, cmd_v = [], []
    for log_time, name, data in rec.messages:
        if name == topic:
            stamp, v = M.decode_ageing(data)
            ageing[stamp] = v
        elif name == truth_topic:
            stamp, _names, pos, _vel, _eff = C.decode_joint_state(data)
            truth[stamp] = pos[2]
        elif name == cmd_topic:
            cmd_t.append(log_time)
            cmd_v.append(C.decode_float64(data))
    stamps = sorted(set(ageing) & set(truth))
    if not stamps:
        return None
    out = {name: np.array([ageing[s][name] for s in stamps]) for name in M.AGEING_VALUES}
    moved = (np.ptp(out['screw_temperature']) > 1e-6 or out['wear_leading'].max() > 0.0
             or out['wear_trailing'].max() > 0.0 or out['lubricant'].min() < 1.0)
    if not moved:
        return None
    start = sim.t0 if 't0_ns' in sim.meta else int(stamps[0]) - sim.dt_ns
    out['time'] = (np.array(stamps, dtype=np.int64) - start) / NS
    out['frame_position'] = np.array([truth[s] for s in stamps]) + out['thermal_growth']
    out['stops'] = []
    if cmd_t:
        command = hold_series((np.array(cmd_t, dtype=np.int64) - start) / NS, cmd_v,
                              out['time'])
        out['stops'] = thermal_drift(out['time'], command, out['frame_position'])
    return out


def drift_panel(ax, a, p):
    """Drift at the stops [um] and the screw temperature [degC] over time [s]."""
    t = a['time']
    if a['stops']:
        targets = sorted({round(r[1], 9) for r in a['stops']})
        for i, x in enumerate(targets):
            rows = [r for r in a['stops'] if round(r[1], 9) == x]
            first = rows[0]
            ax.plot([r[0] for r in rows], [(r[2] - first[2]) * 1e6 for r in rows], 'o',
                    color=f'C{i}', ms=4, label=f'drift at {x * 1e3:g} mm [um]')
            growth = p.thermal_expansion * (a['screw_temperature'] - p.ambient_temperature) \
                * (x - p.fixed_bearing_x)
            ax.plot(t, (growth - growth[first[3]]) * 1e6, '-', color=f'C{i}', lw=0.7,
                    alpha=0.6, label=f'alpha dT (x - x_fixed) at {x * 1e3:g} mm [um]')
        ax.set_title('warm-up drift at the stops since the first (ISO 230-3), the screw\'s '
                     'growth overlaid', fontsize=9)
    else:
        ax.plot(t, a['thermal_growth'] * 1e6, 'C0', lw=0.8, label='thermal growth at the nut '
                '[um]')
        ax.set_title('thermal growth at the nut (no measurement stops)', fontsize=9)
    ax.set_xlabel('time [s]')
    ax.set_ylabel('drift, growth [um]')
    ax2 = ax.twinx()
    temp = a['screw_temperature']
    ax2.plot(t, temp, 'k--', lw=0.8, label='screw temperature [degC]')
    lo, span = float(temp.min()), max(float(np.ptp(temp)), 1e-3)
    ax2.set_ylim(lo - 0.05 * span, lo + 1.6 * span)   # above the drift, not across it
    ax2.set_ylabel('screw temperature [degC]')
    lines = ax.get_lines() + ax2.get_lines()
    ax.legend(lines, [ln.get_label() for ln in lines], fontsize=7, loc='best')


def wear_panel(ax, a):
    """Flank wear and effective backlash [um], lubricant [-] over time [s]."""
    t = a['time']
    ax.plot(t, a['wear_leading'] * 1e6, 'C3', lw=0.8, label='wear, leading flanks [um]')
    ax.plot(t, a['wear_trailing'] * 1e6, 'C4', lw=0.8, label='wear, trailing flanks [um]')
    ax.plot(t, a['backlash'] * 1e6, 'k', lw=1.0, label='effective backlash [um]')
    ax.set_xlabel('time [s]')
    ax.set_ylabel('wear, backlash [um]')
    ax2 = ax.twinx()
    ax2.plot(t, a['lubricant'], 'C2', lw=0.8, label='lubricant [-]')
    ax2.set_ylim(-0.05, 1.05)
    ax2.set_ylabel('lubricant [-]', color='C2')
    lines = ax.get_lines() + ax2.get_lines()
    ax.legend(lines, [ln.get_label() for ln in lines], fontsize=7, loc='best')
    ax.set_title('flank wear, backlash and lubricant', fontsize=9)
