"""
The sine dwell's frequencies in parallel, on the analyses' one executor.

Each (frequency, amplitude) point is one run on its own model, so the points
go out in contiguous batches through :func:`..executors.map_batches` (as the
stability cases do: in this process, on local worker processes forked from
the warmed parent, or on a Dask scheduler) and come back in point order: the
result is the same, bit for bit, however the work was distributed. The
warming is the stability analysis's (:func:`..stability.executors.warm`).
"""
import os

from ...core.params import ParameterError
from ..executors import map_batches
from ..stability import executors as ex
from .sine import sine_point

__all__ = ['run_points']

BATCHES_PER_WORKER = 4      #: batches per worker (load balance against per-batch cost)


def run_batch(params, tasks):
    """Return the sine dwell points of a batch of tasks (keyword dicts of sine_point)."""
    ex.warm()
    return [sine_point(params, **t) for t in tasks]


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
    if scheduler is None and (workers == 1 or len(tasks) <= 1):
        return [sine_point(params, **t) for t in tasks]     # no warming, no batches
    out = [None] * len(tasks)

    def put(a, b, points):
        out[a:b] = points

    map_batches(run_batch, lambda a, b: (params, tasks[a:b]), len(tasks), put,
                workers=workers, scheduler=scheduler, warm=ex.warm,
                per_worker=BATCHES_PER_WORKER)
    return out
