"""The playback schedule: absolute CLOCK_MONOTONIC deadlines."""
import ctypes
import ctypes.util
import time

NS = 1_000_000_000

__all__ = ['Sleeper']


class _Timespec(ctypes.Structure):
    _fields_ = [('tv_sec', ctypes.c_long), ('tv_nsec', ctypes.c_long)]


class Sleeper:
    """Absolute CLOCK_MONOTONIC deadlines (clock_nanosleep TIMER_ABSTIME; time.sleep fallback)."""

    def __init__(self):
        """Load libc."""
        self._ts = _Timespec()
        try:
            libc = ctypes.CDLL(ctypes.util.find_library('c') or 'libc.so.6')
            self._fn = libc.clock_nanosleep
            self._ref = ctypes.byref(self._ts)
        except (OSError, AttributeError):
            self._fn = None

    def until(self, deadline_ns):
        """Sleep until time.monotonic_ns() >= deadline_ns."""
        while True:
            now = time.monotonic_ns()
            if now >= deadline_ns:
                return
            if self._fn is None:
                time.sleep((deadline_ns - now) / NS)
            else:
                self._ts.tv_sec, self._ts.tv_nsec = divmod(deadline_ns, NS)
                self._fn(1, 1, self._ref, None)        # CLOCK_MONOTONIC, TIMER_ABSTIME
