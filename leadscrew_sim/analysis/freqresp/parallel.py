"""
The sine dwell's frequencies in parallel, on the stability analysis's executors.

Each (frequency, amplitude) point is one run on its own model, so the points
go out in contiguous batches (as the stability cases do: in this process, on
local worker processes forked from the warmed parent, or on a Dask
scheduler) and come back in point order: the result is the same, bit for
bit, however the work was distributed. The warming, the start method and the
scheduler timeout are those of :mod:`..stability.executors`.
"""
import concurrent.futures as cf
import math
import multiprocessing
import os

from ...core.params import ParameterError
from ..stability import executors as ex
from .sine import sine_point

__all__ = ['run_points']

BATCHES_PER_WORKER = 4      #: batches per worker (load balance against per-batch cost)


def run_batch(params, tasks):
    """Return the sine dwell points of a batch of tasks (keyword dicts of sine_point)."""
    ex.warm()
    return [sine_point(params, **t) for t in tasks]


def _spans(n, workers):
    size = max(1, math.ceil(n / (max(1, workers) * BATCHES_PER_WORKER)))
    return [(i, min(n, i + size)) for i in range(0, n, size)]


def _local(params, tasks, spans, workers, out):
    ex.warm()                   # the parent fills numba's cache before any worker starts
    ctx = multiprocessing.get_context(ex.START_METHOD or ex._start_method())
    pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=ex.warm)
    try:
        futs = {pool.submit(run_batch, params, tasks[a:b]): (a, b) for a, b in spans}
        for fut in cf.as_completed(futs):
            a, b = futs[fut]
            out[a:b] = fut.result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _dask(params, tasks, spans, scheduler, out):
    try:
        from distributed import Client
    except ImportError:
        raise ParameterError('scheduler', 'needs dask[distributed] (pip install '
                             '-r requirements.txt)') from None
    try:
        client = Client(scheduler, timeout=ex.SCHEDULER_TIMEOUT, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ParameterError('scheduler', f'{scheduler!r}: no Dask scheduler reached within '
                             f'{ex.SCHEDULER_TIMEOUT:g} s ({type(exc).__name__})') from None
    try:
        ex.warm()
        futs = [client.submit(run_batch, params, tasks[a:b], pure=False) for a, b in spans]
        for fut, (a, b) in zip(futs, spans):
            out[a:b] = fut.result()
    finally:
        client.close()


def run_points(params, tasks, workers=None, scheduler=None):
    """
    Return the sine dwell points of every task, in task order.

    Parameters
    ----------
    params : ScrewParams
        The axis.
    tasks : list of dict
        Keyword arguments of :func:`.sine.sine_point` (all but params).
    workers : int, optional
        Local worker processes (default: the cores; 1: this process).
    scheduler : str, optional
        A Dask scheduler address (tcp://HOST:PORT).

    """
    workers = (os.cpu_count() or 1) if workers is None else int(workers)
    if workers < 1:
        raise ParameterError('workers', f'{workers} is below the allowed minimum 1')
    out = [None] * len(tasks)
    if scheduler is not None:
        _dask(params, tasks, _spans(len(tasks), 8), scheduler, out)
    elif workers == 1 or len(tasks) <= 1:
        out[:] = [sine_point(params, **t) for t in tasks]
    else:
        _local(params, tasks, _spans(len(tasks), workers), workers, out)
    return out
