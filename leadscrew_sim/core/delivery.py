"""
How the sensor states reach the controller: ``state_delay`` ticks late, a seeded share lost.

A sample is taken at the end of tick k and stamped with that time; it is
delivered at the end of tick ``k + state_delay`` (so a subscriber sees the
truth of ``state_delay`` ticks ago, with its own stamp), unless
``fault.state_drop_rate`` loses it: sample k is lost when
:func:`.sensors.uniform` of the state-drop stream at counter k is below the
rate, so the same seed loses the same samples in the node, ``resim`` and
``simulate``. Stamps of the delivered samples show the gaps. The truth
topics never pass through here.
"""
import collections

import numpy as np

from .engine.sensors import STREAM_STATE_DROP, uniform


class StateDelivery:
    """
    The line of sensor samples between the axis and its controller.

    Parameters
    ----------
    params : ScrewParams, optional
        Its ``state_delay`` [ticks], ``fault_state_drop_rate`` and
        ``sensor_seed`` (default: no delay, no loss).

    """

    def __init__(self, params=None):
        """Start with an empty line."""
        self.delay, self.drop_rate, self.seed = 0, 0.0, 0
        self.dropped = 0            # samples lost so far
        self._line = collections.deque()
        if params is not None:
            self.set_faults(params)

    def set_faults(self, params):
        """
        Take the delay and the loss from a parameter set (samples in the line keep their time).

        Parameters
        ----------
        params : ScrewParams
            ``state_delay`` [ticks], ``fault_state_drop_rate`` (0..1), ``sensor_seed``.

        """
        self.delay = int(params.state_delay)
        self.drop_rate = float(params.fault_state_drop_rate)
        self.seed = int(params.sensor_seed)

    def reset(self):
        """Forget the samples under way (as after ``~/reset``)."""
        self._line.clear()

    def sample(self, tick, stamp_ns, values):
        """
        Put the sample of tick ``tick`` in the line, unless it is lost.

        Parameters
        ----------
        tick : int
            The tick's number since start (the counter of the loss decisions).
        stamp_ns : int
            Its sampling time [ns].
        values : tuple of float
            What the sensors report (``LeadScrewModel.joint_values()``).

        """
        if self.drop_rate > 0.0 and uniform(self.seed, STREAM_STATE_DROP, tick) < self.drop_rate:
            self.dropped += 1
            return
        self._line.append((tick + self.delay, stamp_ns, values))

    def pending(self):
        """Return True while samples are under way."""
        return bool(self._line)

    def due(self, tick):
        """
        Return [(stamp_ns, values)] of the samples delivered at the end of a tick.

        Parameters
        ----------
        tick : int
            The tick's number since start.

        """
        line = self._line
        out = []
        while line and line[0][0] <= tick:
            _due, stamp, values = line.popleft()
            out.append((stamp, values))
        return out


def lost_samples(seed, rate, first, n):
    """
    Return a bool array: which of the samples ``first .. first + n - 1`` the loss takes.

    The same decisions as :meth:`StateDelivery.sample`, for a block of ticks.

    Parameters
    ----------
    seed : int
        ``sensor_seed``.
    rate : float
        ``fault_state_drop_rate`` (0..1).
    first : int
        Counter of the first sample.
    n : int
        Number of samples.

    """
    if rate <= 0.0:
        return np.zeros(n, dtype=bool)
    return np.array([uniform(seed, STREAM_STATE_DROP, k) < rate
                     for k in range(first, first + n)], dtype=bool)
