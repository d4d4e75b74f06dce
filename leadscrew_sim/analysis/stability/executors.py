"""
Running the cases of a grid: in this process, on local worker processes, or on Dask.

The work is spread by the analyses' one executor (:func:`..executors.map_batches`),
which the frequency response's sine dwell shares.

The cases go out in batches: runs of cases with the cases of one parameter
set together (:func:`grouped_order`), so that a batch builds each set's
parameters and model once and resets the model between its cases. Each batch
returns its rows and the rows are put back in case order, so the table is the
same, bit for bit, however the work was distributed: a reset model is a new
model, and the model is deterministic.

numba's on-disk cache is not safe against several processes compiling and
writing the same entries at once (numba's GitHub #4807), so the parent warms the
kernel before it starts any local worker: it compiles (or loads) and caches
every function a case uses, and the workers never write the cache. Local
workers are forked from the warmed parent where the platform has fork and
the parent runs no other Python thread (they inherit its compiled kernel:
about 0.2 s to start two, against 5 s for spawned ones that import and load
everything again); otherwise spawned. Either way each worker warms its
kernel once, in its initializer, before its first batch (a no-op when
forked warm). Dask workers warm theirs on their first batch (once per
process); the client warms the cache before it submits, which covers workers
that share the client's NUMBA_CACHE_DIR. Warming also sets glibc's malloc
to keep freed memory (:func:`keep_freed_memory`), in every process.

Ctrl-C (KeyboardInterrupt) stops the run: the finished rows are kept and the
result says it is incomplete. An unreachable Dask scheduler fails within
SCHEDULER_TIMEOUT seconds.
"""
import ctypes
import os
import sys

import numpy as np

from ..executors import map_batches, SCHEDULER_TIMEOUT

__all__ = ['grouped_order', 'identical', 'keep_freed_memory', 'run_batch', 'run_cases',
           'SCHEDULER_TIMEOUT', 'warm']

BATCHES_PER_WORKER = 16     #: batches per worker (load balance against per-batch cost)
_WARM = []                  # set once this process has warmed its kernel


def keep_freed_memory():
    """
    Have glibc's malloc keep freed blocks up to 32 MiB in its heap (once per process).

    A run's record array is mapped afresh and touched page by page when glibc
    returns freed memory eagerly; Dask's nanny starts its workers with
    MALLOC_TRIM_THRESHOLD_=65536, which made the same runs 2.6 times slower
    there. The settings of leadscrew_sim.offline.options.keep_freed_memory;
    elsewhere than glibc nothing changes. Returns True when they were taken.
    """
    try:
        mallopt = ctypes.CDLL(None).mallopt
        return bool(mallopt(-3, 32 << 20) and mallopt(-1, 512 << 20))   # MMAP, TRIM
    except (OSError, AttributeError):
        return False


def warm():
    """Compile or load the kernel and the analysis once in this process (a tiny case)."""
    if _WARM:
        return
    keep_freed_memory()
    from ...core.params import ScrewParams
    from .grid import run_case
    run_case(ScrewParams(), {}, 1e-3, 'velocity', 'both', 0.01)
    run_case(ScrewParams(coupling_stiffness=2.0), {}, 1e-3, 'ideal', 'both', 0.01)
    _WARM.append(True)


def run_batch(base, cases, speed, drive, method, duration):
    """
    Return the rows of a batch of cases (warming this process's kernel first).

    Parameters
    ----------
    base : ScrewParams
        The base parameters.
    cases : list of dict
        Swept name -> value, one per case.
    speed : float or None
        Nut speed [m/s] unless swept.
    drive : str
        'velocity' or 'ideal'.
    method : str
        'linear', 'nonlinear' or 'both'.
    duration : float
        Length of each nonlinear run [s].

    """
    from .grid import run_case
    warm()
    cache = {}
    return [run_case(base, c, speed, drive, method, duration, cache) for c in cases]


def grouped_order(cases):
    """
    Return the case indices with the cases of one parameter set together (stable).

    Cases that differ in speed only share their parameters and, within a
    batch, their model (reset between cases): grouping them makes each set's
    parameters and model be built about once, whatever the order of the axes.
    """
    def key(i):
        return tuple(sorted((k, v) for k, v in cases[i].items() if k != 'speed'))
    return sorted(range(len(cases)), key=key)


class _Progress:
    """A text progress bar on stderr, drawn only when stderr is a terminal."""

    def __init__(self, total, enabled):
        self.total, self.done = total, 0
        self.on = enabled and sys.stderr.isatty()

    def add(self, k):
        self.done += k
        if self.on:
            w = 30
            f = int(w * self.done / max(1, self.total))
            sys.stderr.write(f'\r[{"#" * f}{"." * (w - f)}] {self.done}/{self.total} cases')
            sys.stderr.flush()

    def close(self):
        if self.on:
            sys.stderr.write('\n')


def run_cases(base, cases, speed, drive='velocity', method='both', duration=2.0,
              workers=None, scheduler=None, progress=False):
    """
    Run every case and return (rows, complete): rows in case order, None where not run.

    Parameters
    ----------
    base : ScrewParams
        The base parameters.
    cases : list of dict
        Swept name -> value, one per case.
    speed : float or None
        Nut speed [m/s] unless swept.
    drive : str
        'velocity' or 'ideal'.
    method : str
        'linear', 'nonlinear' or 'both'.
    duration : float
        Length of each nonlinear run [s].
    workers : int, optional
        Local worker processes (default: the number of cores; 1: this process).
    scheduler : str, optional
        A Dask scheduler address (tcp://HOST:PORT): run there instead.
    progress : bool
        Draw a progress bar on stderr if it is a terminal.

    """
    workers = (os.cpu_count() or 1) if workers is None else int(workers)
    if workers < 1:
        from ...core.params import ParameterError
        raise ParameterError('workers', f'{workers} is below the allowed minimum 1')
    rows = [None] * len(cases)
    order = grouped_order(cases)
    by_params = [cases[j] for j in order]
    bar = _Progress(len(cases), progress)

    def put(a, b, batch_rows):
        for j, row in zip(order[a:b], batch_rows):
            rows[j] = row
        bar.add(b - a)

    complete = True
    try:
        map_batches(run_batch, lambda a, b: (base, by_params[a:b], speed, drive, method,
                                             duration),
                    len(cases), put, workers=workers, scheduler=scheduler, warm=warm,
                    per_worker=BATCHES_PER_WORKER)
    except KeyboardInterrupt:
        complete = False
    finally:
        bar.close()
    return rows, complete


def identical(rows_a, rows_b):
    """Return True if two row lists are equal bit for bit (NaN equal to NaN)."""
    if len(rows_a) != len(rows_b):
        return False
    for a, b in zip(rows_a, rows_b):
        if a.keys() != b.keys():
            return False
        for k in a:
            x, y = a[k], b[k]
            if isinstance(x, float) and isinstance(y, float):
                if np.float64(x).tobytes() != np.float64(y).tobytes():
                    return False
            elif x != y:
                return False
    return True
