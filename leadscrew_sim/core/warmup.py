"""
The compiled kernel made ready before a run: loaded from numba's cache, or compiled once.

The first run on a machine compiles the kernel (about half a minute); every
later one loads it from the cache (:mod:`leadscrew_sim.core.engine.cache`).
:func:`kernel_ready` says which it does, before and after, so a first start
is never silent.
"""
import time

from .engine import cache


def kernel_ready(report=None, params=None, always=True):
    """
    Load or compile every kernel entry point the model uses, with one line before and after.

    Parameters
    ----------
    report : callable, optional
        ``report(text)`` is called with one line before and one after (e.g. a
        logger's info, or a print to stderr); None: silent.
    params : ScrewParams, optional
        The axis to warm up with (default, and for a stepper, the tr12x3
        preset): every preset shares the same compiled code.
    always : bool
        Report a load from the cache too; False: report only a compile.

    Returns
    -------
    dict
        seconds [s] taken, compiled (True when anything was compiled rather
        than loaded) and cache_dir.

    """
    from .engine import _jit, kernel
    from .model import LeadScrewModel
    from .presets import load_preset
    path = cache.use_cache_dir()
    cached = all(_cached(d) for d in (kernel.step, kernel.step_held, kernel.run_series))
    if report is not None and (always or not cached):
        report(f'loading the compiled kernel from {path}' if cached else
               f'compiling the kernel (once per machine and version, about 30 s) into {path}')
    t0 = time.monotonic()
    if params is None or params.drive_type == 'stepper':   # the torque path needs a servo
        params = load_preset('tr12x3')
    m = LeadScrewModel(params)
    m.advance(0.0)                        # step
    m.command('torque', effort=0.0)
    m.advance_held(0.0)                   # step_held
    m.run([0.0, 0.0])                     # run_series
    seconds = time.monotonic() - t0
    compiled = any(d.stats.cache_misses for d in _jit.DISPATCHERS
                   if hasattr(d, 'stats'))
    if report is not None and (always or not cached or compiled):
        report(f'kernel ready in {seconds:.1f} s ('
               + ('compiled and cached' if compiled else 'loaded from the cache') + ')')
    return dict(seconds=seconds, compiled=compiled, cache_dir=path)


def _cached(dispatcher):
    """Return True if numba's cache holds a valid entry of ``dispatcher`` (False if unknown)."""
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except Exception:  # noqa: B902 - numba's private cache API; unknown means no
        return False
