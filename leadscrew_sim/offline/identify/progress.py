"""
The progress of ``identify`` on a terminal: the stage, the re-simulations so far, the misfit.

A fit takes thousands of re-simulations (tens of seconds); :class:`FitProgress`
redraws one status line on stderr at most twice a second, and only when
stderr is a terminal (a pipe or a file gets nothing).
"""
import sys
import time

import numpy as np


class FitProgress:
    """
    A status line on a terminal, updated by :class:`.problem.Problem` as it re-simulates.

    Parameters
    ----------
    stream : file, optional
        Where to draw (default ``sys.stderr``); nothing unless it is a tty.
    interval : float
        Least wall time [s] between two redraws.

    """

    def __init__(self, stream=None, interval=0.5):
        """Draw nothing until the first update after ``interval`` s."""
        self.stream = sys.stderr if stream is None else stream
        isatty = getattr(self.stream, 'isatty', None)
        self.on = bool(isatty and isatty())
        self.interval = interval
        self.next = time.monotonic() + interval
        self.shown = False

    def update(self, stage, evaluations, rms):
        """
        Redraw with the fit's ``stage``, its re-simulations so far and each signal's RMS/sigma.

        Parameters
        ----------
        stage : str
            What the fit does now.
        evaluations : int
            Re-simulations so far.
        rms : dict
            Signal name -> residual RMS / noise level of the last whole-run comparison.

        """
        now = time.monotonic()
        if not self.on or now < self.next:
            return
        self.next = now + self.interval
        misfit = ', '.join(f'{n} {v:.3g}' for n, v in rms.items()) or '-'
        line = f'identify: {stage}; {evaluations} re-simulations; RMS/sigma {misfit}'
        self.stream.write('\r\x1b[K' + line[:160])
        self.stream.flush()
        self.shown = True

    def done(self):
        """Clear the status line (the report follows)."""
        if self.shown:
            self.stream.write('\r\x1b[K')
            self.stream.flush()
            self.shown = False


def rms_per_signal(names, r):
    """Return {name: RMS} of the weighted residual rows ``r`` over their compared samples."""
    m = np.asarray(r)
    n = np.maximum(1, np.count_nonzero(m, axis=1))
    return {name: float(v) for name, v in zip(names, np.sqrt((m ** 2).sum(axis=1) / n))}
