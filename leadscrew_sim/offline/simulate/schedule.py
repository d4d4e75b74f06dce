"""
The fault schedule of simulate's ``faults`` option: parameter changes at given times.

Each line is ``time,parameter,value`` (s, a physics or ``fault.*`` parameter,
a YAML scalar); ``#`` starts a comment and a first line that is not a time
is a header. A change at time t acts from the first step that starts at or
after t, as a ``ros2 param set`` between two ticks of the node does, and it
is recorded as a parameter update with that step's log time, so ``resim``
applies it at the same step. ``time,clear_fault,true`` clears a latched
drive fault before that step, as the node's ``~/clear_fault`` does (nothing
while ``fault.drive_fault`` is true), and is recorded as the node records it.
"""
import math

from ..options import parse_scalar, RunError
from ...core.fields import field_name
from ...core.params import ParameterError, ScrewParams

#: The key of a schedule's changes that clears a latched drive fault (``~/clear_fault``).
CLEAR_FAULT = 'clear_fault'


def read_schedule(path, params, dt_ns):
    """
    Return [(step, {field name: value})] of a schedule file, in step order.

    A drive fault clearing is the key :data:`CLEAR_FAULT` (value True).

    Every change is validated on top of the ones before it, so a bad line is
    reported with its number before anything runs.

    Parameters
    ----------
    path : str
        The schedule file.
    params : ScrewParams
        The parameters at the start of the run.
    dt_ns : int
        The step [ns].

    """
    try:
        fh = open(path, newline='')
    except OSError as exc:
        raise RunError(f'<<faults>> {path}: {exc.strerror or exc}') from None
    names = set(ScrewParams.names())
    steps = {}
    last_t = -math.inf
    first = True                                    # the first line with content
    with fh:
        for lineno, line in enumerate(fh, 1):
            text = line.split('#', 1)[0].strip()
            if not text:
                continue
            cells = [c.strip() for c in text.split(',')]
            where = f'<<faults>> {path}, line {lineno}'
            header, first = first, False
            try:
                t = float(cells[0])
            except ValueError:
                if header:
                    continue                        # a header line
                raise RunError(f'{where}: expected "time,parameter,value", got '
                               f'{text[:60]!r}') from None
            if len(cells) != 3:
                raise RunError(f'{where}: expected "time,parameter,value", got {text[:60]!r}')
            if not (math.isfinite(t) and t >= 0.0):
                raise RunError(f'{where}: time {cells[0]} s must be finite and >= 0')
            if t < last_t:
                raise RunError(f'{where}: time {t} s goes backwards (previous {last_t} s)')
            last_t = t
            step = max(0, math.ceil(t * 1e9 / dt_ns - 1e-9))
            if cells[1] in (CLEAR_FAULT, '~/clear_fault'):
                if parse_scalar(cells[2]) is not True:
                    raise RunError(f'{where}: {cells[1]} takes the value true')
                steps.setdefault(step, {})[CLEAR_FAULT] = True
                continue
            name = field_name(cells[1])
            if name not in names:
                raise RunError(f"{where}: unknown parameter '{cells[1]}'")
            if ScrewParams.field_info()[name][2]['read_only']:
                raise RunError(f"{where}: '{cells[1]}' is read-only while the axis runs")
            value = parse_scalar(cells[2])
            try:
                params = ScrewParams.from_dict({name: value}, base=params)
            except ParameterError as exc:
                raise RunError(f'{where}: {exc}') from None
            steps.setdefault(step, {})[name] = getattr(params, name)
    return sorted(steps.items())
