"""
One executor for the analyses' independent runs: this process, local workers, or Dask.

The stability grid's cases and the frequency response's sine-dwell points
are many independent runs. :func:`map_batches` cuts them into contiguous
batches, runs each batch as one call (so a batch pays the task overhead once:
0.2-1 ms a task on Dask), and hands every finished batch to the caller in
place, so the result is the same, bit for bit, however the work was spread:

- ``workers`` 1 (or a single batch): in this process, batch after batch;
- ``workers`` > 1: a local process pool, forked from this process once it
  has warmed its kernel where the platform has fork and no other Python
  thread runs (spawned otherwise), each worker warming once in its
  initializer;
- ``scheduler``: a Dask scheduler, batches sized by its threads, results
  collected in submission order.

numba's on-disk cache is not safe against several processes writing it at
once, so the caller's ``warm`` runs here before any worker starts: the
workers only read the cache. A Ctrl-C (KeyboardInterrupt) leaves the batches
already handed over with the caller. An unreachable scheduler fails within
:data:`SCHEDULER_TIMEOUT` seconds.
"""
import concurrent.futures as cf
import math
import multiprocessing
import threading

from ..core.params import ParameterError

__all__ = ['batches', 'map_batches', 'SCHEDULER_TIMEOUT', 'start_method']

SCHEDULER_TIMEOUT = 8.0     #: seconds to reach a Dask scheduler (the error comes within 10 s)
START_METHOD = None        #: local workers' start method; None: fork if safe, else spawn
DASK_THREADS_UNKNOWN = 8    #: workers assumed when a Dask scheduler reports none yet


def start_method():
    """Return 'fork' where it exists and this process runs no other Python thread, else 'spawn'."""
    if START_METHOD:
        return START_METHOD
    if 'fork' in multiprocessing.get_all_start_methods() and threading.active_count() == 1:
        return 'fork'
    return 'spawn'


def batches(n, workers, per_worker):
    """Return [(start, stop)] spans cutting n runs into about ``per_worker`` per worker."""
    size = max(1, math.ceil(n / (max(1, workers) * per_worker)))
    return [(i, min(n, i + size)) for i in range(0, n, size)]


def dask_client(scheduler):
    """Return a client of the Dask scheduler ``scheduler`` (ParameterError if none is reached)."""
    try:
        from distributed import Client
    except ImportError:
        raise ParameterError('scheduler', 'needs dask[distributed] (pip install '
                             '-r requirements.txt)') from None
    try:
        return Client(scheduler, timeout=SCHEDULER_TIMEOUT, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ParameterError('scheduler', f'{scheduler!r}: no Dask scheduler reached within '
                             f'{SCHEDULER_TIMEOUT:g} s ({type(exc).__name__})') from None


def map_batches(fn, args_of, n, put, *, workers=1, scheduler=None, warm=None,
                per_worker=4):
    """
    Run ``fn(*args_of(a, b))`` for contiguous spans of ``n`` runs; ``put(a, b, result)`` each.

    Parameters
    ----------
    fn : callable
        A module-level function (a process or Dask worker imports it) that
        runs the runs ``a .. b - 1`` and returns their results.
    args_of : callable
        (a, b) -> the arguments of ``fn`` for that span (picklable).
    n : int
        Number of runs.
    put : callable
        (a, b, result): called in this process as each span finishes.
    workers : int
        Local worker processes (1: this process).
    scheduler : str, optional
        A Dask scheduler address (tcp://HOST:PORT): run there instead.
    warm : callable, optional
        Compiles the kernel in a process (module level: also the workers'
        initializer); run here before any worker starts.
    per_worker : int
        Spans per worker (load balance against per-span cost).

    """
    warm = warm or _nothing
    if scheduler is not None:
        client = dask_client(scheduler)
        try:
            warm()
            threads = sum(client.nthreads().values()) or DASK_THREADS_UNKNOWN
            spans = batches(n, threads, per_worker)
            futs = [client.submit(fn, *args_of(a, b), pure=False) for a, b in spans]
            for fut, (a, b) in zip(futs, spans):      # collected in submission order
                put(a, b, fut.result())
        finally:
            client.close()
        return
    spans = batches(n, workers, per_worker)
    if workers <= 1 or len(spans) <= 1:
        for a, b in spans:
            put(a, b, fn(*args_of(a, b)))
        return
    warm()                      # fill numba's cache before any worker starts
    ctx = multiprocessing.get_context(start_method())
    pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=warm)
    try:
        futs = {pool.submit(fn, *args_of(a, b)): (a, b) for a, b in spans}
        for fut in cf.as_completed(futs):
            a, b = futs[fut]
            put(a, b, fut.result())
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _nothing():
    """Warm nothing (the default ``warm``)."""
