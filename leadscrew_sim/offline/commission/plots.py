"""The report's figures: matplotlib (Agg) PNGs as data URIs, every axis labelled with its unit."""
import base64
import io

import numpy as np


def _fig(rows=1, height=3.2):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(rows, 1, figsize=(8.0, height * rows), squeeze=False)
    return plt, fig, axes[:, 0]


def _uri(plt, fig):
    """Return the figure as a PNG data URI and close it."""
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format='png', dpi=80)
    plt.close(fig)
    return 'data:image/png;base64,' + base64.b64encode(buf.getvalue()).decode('ascii')


def twin(ctx, windows):
    """Return measured and twin nut position over the held-out parts, and their difference [um]."""
    plt, fig, (ax, axe) = _fig(2)
    m = ctx.measured
    parts = list(windows)
    for part in parts:
        a, b = windows[part]
        k = m.window(a, b)
        tw = np.interp(m.time[k], ctx.twin_time, ctx.twin['nut_position'])
        ax.plot(m.time[k], m.nut_position[k] * 1e3, '.', ms=1.0, color='0.4',
                label='measured' if part == parts[0] else None)
        ax.plot(m.time[k], tw * 1e3, lw=0.8, color='C1',
                label='twin' if part == parts[0] else None)
        axe.plot(m.time[k], (m.nut_position[k] - tw) * 1e6, lw=0.5, label=part)
    sigma = ctx.noise.get('nut_position')
    if sigma:
        for s in (1, -1):
            axe.axhline(s * sigma * 1e6, color='k', lw=0.5, ls='--')
    ax.set_ylabel('nut position [mm]')
    ax.legend(loc='best', fontsize=8)
    axe.set_ylabel('measured - twin [um]')
    axe.set_xlabel('time [s]')
    axe.legend(loc='best', fontsize=8)
    return _uri(plt, fig)


def stribeck(section):
    """Return the mean motor torque against nut speed on the sweep's levels, measured and twin."""
    plt, fig, (ax,) = _fig(1)
    for key, style, label in (('stribeck', 'o', 'measured'), ('stribeck_twin', 'x-', 'twin')):
        pts = section.get(key) or []
        for sign in (1, -1):
            sel = [q for q in pts if np.sign(q['command']) == sign]
            if sel:
                ax.semilogx([abs(q['speed']) for q in sel], [q['torque'] for q in sel], style,
                            label=f'{label}, {"+" if sign > 0 else "-"}x')
    ax.set_xlabel('|nut speed| [m/s]')
    ax.set_ylabel('mean motor torque [N m]')
    ax.legend(loc='best', fontsize=8)
    return _uri(plt, fig)


def reversal(section):
    """Return the mean deviation from each target approached from below and from above [um]."""
    plt, fig, (ax,) = _fig(1)
    for key, marker in (('measured', 'o'), ('twin', 'x')):
        r = section.get(key)
        if r:
            x = np.array(r['targets']) * 1e3
            ax.plot(x, np.array(r['mean_up']) * 1e6, marker + '-', label=f'{key}, from below')
            ax.plot(x, np.array(r['mean_down']) * 1e6, marker + '--', label=f'{key}, from above')
    ax.set_xlabel('target position [mm]')
    ax.set_ylabel('mean deviation [um]')
    ax.legend(loc='best', fontsize=8)
    return _uri(plt, fig)


def bode(section):
    """Return magnitude, phase and coherence: the chirp's H1 and the twin's linear model."""
    plt, fig, (am, ap, ac) = _fig(3, 2.4)
    lin, meas = section.get('linear'), section.get('measured')
    for d, style, label in ((meas, '.', 'measured H1'), (lin, '-', 'twin linear model')):
        if d:
            am.semilogx(d['frequency'], d['magnitude_db'], style, ms=2, label=label)
            ap.semilogx(d['frequency'], np.mod(d['phase_deg'], 360.0) - 360.0, style, ms=2,
                        label=label)
    if meas:
        ac.semilogx(meas['frequency'], meas['coherence'], '.', ms=2)
    ny = section.get('drive_nyquist_hz')
    for ax in (am, ap, ac):
        if ny:
            ax.axvline(ny, color='k', lw=0.5, ls=':')
    am.set_ylabel('|H| [dB re 1 rad/m]')
    am.set_title('motor velocity [rad/s] / velocity command [m/s]', fontsize=9)
    ap.set_ylabel('phase [deg]')
    ac.set_ylabel('coherence [-]')
    ac.set_xlabel('frequency [Hz]')
    am.legend(loc='best', fontsize=8)
    return _uri(plt, fig)


def stability(section):
    """Return the sign of the growth rate of steady sliding over nut speed and mu_s."""
    plt, fig, (ax,) = _fig(1)
    v = np.array(section['speeds'])
    mu = np.array(section['mu_s'])
    g = np.array([[np.nan if x is None else x for x in row] for row in section['growth_rate']])
    if len(mu) > 1:
        mesh = ax.pcolormesh(v, mu, np.sign(g), cmap='coolwarm', vmin=-1, vmax=1,
                             shading='nearest')
        fig.colorbar(mesh, ax=ax, label='sign of growth [-]')
        ax.set_ylabel('mu_s [-]')
    else:
        ax.semilogx(v, g[0], '-')
        ax.axhline(0.0, color='k', lw=0.5)
        ax.set_ylabel('growth rate [1/s]')
    ax.set_xscale('log')
    for s in section.get('operating_speeds', []):
        ax.axvline(s, color='k', lw=0.6, ls='--')
    ax.set_xlabel('nut speed [m/s] (dashed: the recorded levels)')
    return _uri(plt, fig)


def pullout(section):
    """Return the pull-out torque and load line against the step rate."""
    plt, fig, (ax,) = _fig(1)
    rows = section['curve']
    r = [x['step_rate'] for x in rows]
    ax.plot(r, [x['pullout_torque'] for x in rows], 'o-', label='pull-out torque')
    ax.plot(r, [x['load_torque'] for x in rows], 's--', label='load line')
    ax.axvline(section['max_step_rate'], color='k', lw=0.6, ls=':', label='max_step_rate')
    if section.get('knee'):
        ax.axvline(section['knee'], color='0.5', lw=0.6, ls='-.', label='knee')
    if section.get('loses_steps_at'):
        ax.axvline(section['loses_steps_at'], color='r', lw=0.8, label='loses steps')
    ax.set_xlabel('step rate [full steps/s]')
    ax.set_ylabel('torque [N m]')
    ax.legend(loc='best', fontsize=8)
    return _uri(plt, fig)
