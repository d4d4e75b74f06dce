"""The report lines of the derived figures of a run (``info --figures``)."""


def format_figures(figures):
    """
    Return report lines of :func:`derived_figures` results.

    Parameters
    ----------
    figures : dict
        What :func:`derived_figures` returned.

    """
    lines = []
    for s, b in sorted(figures.get('breakaway', {}).items(), reverse=True):
        sign = '+' if s > 0 else '-'
        lines.append(f'breakaway toward {sign}theta: ' + (
            'no motion' if b is None else f'{b.torque:+.6g} N m at t={b.time:.3f} s '
            f'(ramp from {b.center:+.6g} N m)'))
    if 'stribeck' in figures:
        lines.append('Stribeck points: command [m/s], mean nut speed [m/s], mean torque '
                     '[N m] (std)')
        for p in figures['stribeck']:
            lines.append(f'  {p.command:+.4e}  {p.speed:+.4e}  {p.torque:+.6f} '
                         f'({p.torque_std:.2e})')
    if 'efficiency' in figures:
        rows, best = figures['efficiency']
        for kind in ('forward', 'backdrive'):
            if kind in best:
                note = ' (<= 0: self-locking in motion)' if best[kind] <= 0.0 else ''
                lines.append(f'{kind} efficiency at the fastest level: {best[kind]:.4f}{note}')
        if not rows:
            lines.append('efficiency: undefined (no axial load)')
    if 'reversal' in figures:
        r = figures['reversal']
        if r is None:
            lines.append('reversal error: no target approached from both sides')
        else:
            lines.append(f'reversal error (ISO 230-2): mean B = {r.mean_reversal * 1e6:+.3f} '
                         f'um, max |B_i| = {r.max_reversal * 1e6:.3f} um over '
                         f'{len(r.targets)} targets')
    return lines
