"""
The twin against the real axis: a foreign recording's commands through the model, compared.

:func:`twin_comparison` replays the mapped commands with the user's
parameters (ideal sensors: the twin's states are its truth, so a difference
is the axis's sensor noise plus what the model does not explain) and
compares each measured signal with the twin's at the state's stamp
(:mod:`.replay`): RMS and largest difference over the run and per segment
of motion between rests. The screw angle is compared with its mean
difference removed (an encoder's zero is arbitrary); the nut position as
measured (the twin starts at the first measured nut position).

The segments of motion between rests are those of :mod:`.segments`.
"""
import dataclasses

import numpy as np

from .forces import forces_text
from .replay import at_times, ForeignReplay, OFFSET_SIGNALS
from .segments import motion_segments
from .states import COLUMNS, UNITS
from ..options import NS, option_text
from ...analysis.identify import fit as ident
from ...core.params import ScrewParams


@dataclasses.dataclass
class TwinComparison:
    """
    Measured states against the twin's.

    Attributes
    ----------
    time : numpy.ndarray
        The compared states' stamps [s] from the grid start.
    t0_ns : int
        The grid start [ns] (the recording's time base: epoch ns for a robot's bag).
    measured, twin : dict
        Signal -> values at ``time`` [unit of :attr:`units`] (the screw angle of
        the twin shifted by the mean difference).
    units : dict
        Signal -> unit.
    rms, max : dict
        Signal -> RMS and largest absolute difference over the run [unit].
    segments : list of dict
        Per segment of motion: ``start``, ``end`` [s from the grid start],
        ``n`` states, and ``rms``, ``max`` {signal: [unit]}.
    delay : Delay
        The command-to-state delay used.
    replay : ForeignReplay
        The mapped recording (grid, commands, states).

    """

    time: np.ndarray
    t0_ns: int
    measured: dict
    twin: dict
    units: dict
    rms: dict
    max: dict
    segments: list
    delay: object
    replay: object

    def arrays(self):
        """Return (signals, rms array, max array, per-segment (n_seg, n_sig) rms and max)."""
        names = list(self.measured)
        rms = np.array([self.rms[s] for s in names])
        mx = np.array([self.max[s] for s in names])
        seg_rms = np.array([[g['rms'][s] for s in names] for g in self.segments])
        seg_max = np.array([[g['max'][s] for s in names] for g in self.segments])
        return names, rms, mx, seg_rms, seg_max


def twin_comparison(source, params, mapping=None, estimate_delay=True):
    """
    Replay a foreign recording's commands through the model with ``params``; compare the states.

    Parameters
    ----------
    source : ForeignReplay or Recording
        The mapped recording, or an open recording with ``mapping``.
    params : ScrewParams
        The twin's parameters (sensors made ideal for the comparison).
    mapping : Mapping, optional
        With a Recording: how it maps (:class:`.mapping.Mapping`).
    estimate_delay : bool
        Estimate the command-to-state delay when the mapping does not set it.

    Returns
    -------
    TwinComparison

    """
    ideal = ScrewParams.from_dict(ident.noiseless_sensors(params), base=params)
    rep = source if isinstance(source, ForeignReplay) else \
        ForeignReplay(mapping, source, ideal, estimate_delay=estimate_delay)
    cols = rep.replay({}, interpolate=False)
    st = rep.states
    rel = st.stamps - rep.t0
    measured, twin, rms, mx = {}, {}, {}, {}
    inside = (rel >= rep.dt_ns) & (rel < rep.n_steps * rep.dt_ns)
    for name, y in st.values.items():
        sim = at_times(cols, COLUMNS[name], rep.dt_ns, rel)
        ok = inside & np.isfinite(y) & np.isfinite(sim)
        if not ok.any():
            continue
        if name in OFFSET_SIGNALS:
            sim = sim + np.mean(y[ok] - sim[ok])
        measured[name], twin[name] = np.where(ok, y, np.nan), np.where(ok, sim, np.nan)
    if not measured:
        from ..options import RunError
        raise RunError(f'{rep.path}: no recorded state lies within the re-simulated time')
    for name in measured:
        d = measured[name] - twin[name]
        d = d[np.isfinite(d)]
        rms[name], mx[name] = float(np.sqrt(np.mean(d ** 2))), float(np.abs(d).max())
    time = rel / NS
    segments = []
    for a, b in motion_segments(time, st.values, inside):
        seg = {'start': float(time[a]), 'end': float(time[b - 1]), 'n': int(b - a),
               'rms': {}, 'max': {}}
        for name in measured:
            d = (measured[name] - twin[name])[a:b]
            d = d[np.isfinite(d)]
            seg['rms'][name] = float(np.sqrt(np.mean(d ** 2))) if len(d) else float('nan')
            seg['max'][name] = float(np.abs(d).max()) if len(d) else float('nan')
        segments.append(seg)
    return TwinComparison(time, rep.t0, measured, twin, {n: UNITS[n] for n in measured},
                          rms, mx, segments, rep.delay, rep)


def report_lines(comp, label='', name_of=None):
    """
    Return the report lines of a :class:`TwinComparison`.

    ``name_of(keyword)``: the name of an option a line names (default its keyword;
    :func:`leadscrew_sim.offline.options.option_text`).
    """
    rep = comp.replay
    st = rep.states
    med, lo, hi = st.intervals()
    lines = [f'twin of {rep.path}{label}: {len(st)} states on {rep.state_topic} '
             f'(intervals median {med * 1e3:.3f} ms, {lo * 1e3:.3f} .. {hi * 1e3:.3f} ms, '
             f'{st.gaps()} gaps), commands from {rep.command_topic} '
             f'({rep.commands.ctype}, {len(rep.commands.times)} taken, '
             f'{rep.commands.skipped} non-finite skipped); {forces_text(rep.forces)}'
             f'{rep.n_steps} steps at {NS / rep.dt_ns:g} Hz',
             option_text(comp.delay.line(), name_of),
             f'{"signal":<16} {"unit":<6} {"rms diff":>12} {"max |diff|":>12} {"n":>8}']
    for name in comp.measured:
        n = int(np.count_nonzero(np.isfinite(comp.measured[name] - comp.twin[name])))
        lines.append(f'{name:<16} {comp.units[name]:<6} {comp.rms[name]:12.4g} '
                     f'{comp.max[name]:12.4g} {n:>8}')
    if any(name in OFFSET_SIGNALS for name in comp.measured):
        lines.append('(screw_angle compared with its mean difference removed: the '
                     "encoder's zero is arbitrary)")
    lines.append(f'segments between rests: {len(comp.segments)}')
    for i, seg in enumerate(comp.segments):
        lines.append(f'  {i + 1:3d}  {seg["start"]:9.3f} .. {seg["end"]:9.3f} s  '
                     f'{seg["n"]:7d} states  ' + ', '.join(
                         f'{name} rms {seg["rms"][name]:.3g} max {seg["max"][name]:.3g} '
                         f'{comp.units[name]}' for name in comp.measured))
    return lines


def plot_twin(comp, path):
    """Write a PNG: each measured signal over the twin's, and their difference, against time."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    names = list(comp.measured)
    fig, axes = plt.subplots(len(names), 2, figsize=(12, 2.6 * len(names)), squeeze=False,
                             sharex=True)
    for row, name in zip(axes, names):
        unit = comp.units[name]
        row[0].plot(comp.time, comp.measured[name], '.', ms=1.5, label='measured')
        row[0].plot(comp.time, comp.twin[name], '-', lw=0.8, label='twin')
        row[0].set_ylabel(f'{name} [{unit}]')
        row[0].legend(loc='best', fontsize=7)
        row[1].plot(comp.time, comp.measured[name] - comp.twin[name], '.', ms=1.5)
        row[1].set_ylabel(f'measured - twin [{unit}]')
        for seg in comp.segments:
            row[1].axvspan(seg['start'], seg['end'], color='0.9', zorder=0)
    for ax in axes[-1]:
        ax.set_xlabel(f'time from the grid start [s] (t0 = {comp.t0_ns / NS:.6f} s)')
    fig.suptitle(f'measured vs twin: {comp.replay.path}', fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
