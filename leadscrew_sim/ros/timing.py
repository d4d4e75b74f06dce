"""Deadline timing of the node's loop: absolute-deadline sleeps, lateness statistics."""
import array
import ctypes
import ctypes.util
import math
import time

NS = 1_000_000_000

__all__ = ['clock_pair', 'DeadlineSleeper', 'LoopStats', 'percentiles']


def clock_pair(tries=5):
    """
    Return (system time, CLOCK_MONOTONIC time) [ns] of one instant.

    The system time is read between two monotonic readings; the tightest of
    ``tries`` brackets wins and its midpoint is the monotonic instant (within
    a few microseconds of the system reading).
    """
    best = None
    for _ in range(tries):
        a = time.monotonic_ns()
        wall = time.time_ns()
        b = time.monotonic_ns()
        if best is None or b - a < best[0]:
            best = (b - a, wall, (a + b) // 2)
    return best[1], best[2]


class _Timespec(ctypes.Structure):
    _fields_ = [('tv_sec', ctypes.c_long), ('tv_nsec', ctypes.c_long)]


class DeadlineSleeper:
    """
    Sleep until an absolute CLOCK_MONOTONIC deadline (clock_nanosleep, TIMER_ABSTIME).

    Also sets the thread's timer slack to 1 ns (prctl PR_SET_TIMERSLACK).
    Falls back to time.sleep if libc cannot be loaded.
    """

    CLOCK_MONOTONIC = 1
    TIMER_ABSTIME = 1
    PR_SET_TIMERSLACK = 29

    def __init__(self):
        """Load libc and lower the timer slack."""
        self._ts = _Timespec()
        self._fn = None
        try:
            libc = ctypes.CDLL(ctypes.util.find_library('c') or 'libc.so.6', use_errno=True)
            fn = libc.clock_nanosleep
            fn.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.POINTER(_Timespec),
                           ctypes.c_void_p]
            fn.restype = ctypes.c_int
            self._fn = fn
            self._ref = ctypes.byref(self._ts)
            libc.prctl(self.PR_SET_TIMERSLACK, ctypes.c_ulong(1), ctypes.c_ulong(0),
                       ctypes.c_ulong(0), ctypes.c_ulong(0))
        except (OSError, AttributeError):
            self._fn = None

    def sleep_until(self, deadline_ns):
        """Sleep until time.monotonic_ns() >= deadline_ns (may return early on a signal)."""
        if self._fn is None:
            delay = deadline_ns - time.monotonic_ns()
            if delay > 0:
                time.sleep(delay / NS)
            return
        self._ts.tv_sec, self._ts.tv_nsec = divmod(deadline_ns, NS)
        self._fn(self.CLOCK_MONOTONIC, self.TIMER_ABSTIME, self._ref, None)


def percentiles(values, qs=(50, 99)):
    """Return {'p50': .., 'p99': .., 'max': ..} of a sequence (nearest rank)."""
    if not values:
        return {f'p{q}': None for q in qs} | {'max': None}
    s = sorted(values)
    out = {f'p{q}': s[min(len(s) - 1, max(0, math.ceil(q / 100.0 * len(s)) - 1))] for q in qs}
    out['max'] = s[-1]
    return out


class LoopStats:
    """
    Tick counters and lateness of the main loop: a one-second diagnostics window and the run.

    ``keep_all`` keeps every lateness sample of the run (for the stats file).
    """

    def __init__(self, keep_all=False):
        """Start with no ticks."""
        self.overruns = 0               # ticks (stalls) due more steps than the catch-up limit
        self.skipped_steps = 0          # steps of those stalls integrated but not published
        self.late_ticks = 0             # ticks at least one period late
        self.catchup_steps = 0
        self.lateness = array.array('q')        # current diagnostics window [ns]
        self.lateness_all = array.array('q') if keep_all else None
        self.win_start = time.monotonic_ns()
        self.win_ticks = 0
        self.achieved_rate = 0.0
        self.run_start = None
        self.run_end = None
        self.run_ticks = 0

    def late(self, late_ns):
        """Count the lateness of one tick start behind its deadline [ns]."""
        self.lateness.append(late_ns)
        if self.lateness_all is not None:
            self.lateness_all.append(late_ns)

    def steps(self, n):
        """Count n steps taken in one tick."""
        self.win_ticks += n
        self.run_ticks += n

    def catch_up(self, due, steps):
        """Count a tick that was due ``due`` steps and took ``steps``."""
        if due > 1:
            self.late_ticks += 1
            self.catchup_steps += steps - 1
        if due > steps:
            self.overruns += 1
            self.skipped_steps += due - steps

    def window(self, now_ns):
        """Close the diagnostics window at now_ns; return its lateness percentiles [ns]."""
        window = (now_ns - self.win_start) / NS
        self.achieved_rate = self.win_ticks / window if window > 0 else 0.0
        pct = percentiles(self.lateness)
        self.lateness = array.array('q')
        self.win_start, self.win_ticks = now_ns, 0
        return pct

    def run_stats(self):
        """Return the counters and lateness of the run so far (the stats file's keys)."""
        end = self.run_end or time.monotonic_ns()
        elapsed = (end - self.run_start) / NS if self.run_start else 0.0
        lat = self.lateness_all if self.lateness_all is not None else self.lateness
        pct = percentiles(lat)
        return dict(
            ticks=self.run_ticks, elapsed_s=elapsed,
            achieved_rate=self.run_ticks / elapsed if elapsed > 0 else 0.0,
            lateness_p50_ns=pct['p50'], lateness_p99_ns=pct['p99'],
            lateness_max_ns=pct['max'], lateness_samples=len(lat),
            overruns=self.overruns, skipped_steps=self.skipped_steps,
            late_ticks=self.late_ticks, catchup_steps=self.catchup_steps)
