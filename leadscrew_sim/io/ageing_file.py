"""
The ageing state file: one axis's wear, lubricant and temperature across runs.

A HIL campaign wears one axis over many runs: the node loads the state at
start and writes it at shutdown and periodically (``ageing_state_file``);
simulate's ``ageing_from`` option reads a recording instead. The file is JSON:

- ``format``: :data:`FORMAT`;
- ``preset`` and ``axis``: the preset and the fields that make the axis what
  it is (:data:`AXIS_FIELDS`), so a file is never loaded into another axis;
- ``state``: the ageing state (:data:`leadscrew_sim.core.ageing.STATE_FIELDS`);
- ``sim_time``: the node's time when it was written [s], for the reader;
- ``sha256``: the digest of the canonical JSON of the rest.

:func:`write_state` writes a temporary file beside the target, syncs it and
renames it over the target, so a reader sees the old file or the new one,
never a half-written one; the digest refuses a file damaged otherwise.
"""
import hashlib
import json
import os
import tempfile

from ..core.ageing import check_state
from ..core.errors import LeadscrewError

FORMAT = 'leadscrew_sim ageing state 1'

#: The parameters that identify an axis: a state file of another axis is refused.
AXIS_FIELDS = ('thread_form', 'hand', 'major_diameter', 'pitch', 'starts', 'pitch_diameter',
               'backlash', 'anti_backlash')


class AgeingFileError(LeadscrewError, OSError):
    """An ageing state file that cannot be read, is damaged or belongs to another axis."""


def _digest(body):
    return hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()


def _axis(params):
    return {name: getattr(params, name) for name in AXIS_FIELDS}


def write_state(path, state, params, preset, sim_time=0.0):
    """
    Write the ageing state ``state`` of the axis ``params`` (preset ``preset``) atomically.

    Raises AgeingFileError if the directory cannot take the file.
    """
    body = {'format': FORMAT, 'preset': str(preset), 'axis': _axis(params),
            'state': check_state(state), 'sim_time': float(sim_time)}
    body['sha256'] = _digest(body)
    folder = os.path.dirname(os.path.abspath(path))
    try:
        fd, tmp = tempfile.mkstemp(prefix='.ageing-', suffix='.tmp', dir=folder)
        try:
            with os.fdopen(fd, 'w') as fh:
                json.dump(body, fh, indent=1, sort_keys=True)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, path)
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise
        dfd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    except OSError as exc:
        raise AgeingFileError(f'ageing_state_file {path!r}: cannot write it: '
                              f'{exc.strerror or exc}') from None


def read_state(path, params, preset):
    """
    Return the ageing state in the file ``path`` for the axis ``params`` of preset ``preset``.

    Raises AgeingFileError (one line naming the file and the reason) if the
    file cannot be read, is not a complete state file, or belongs to another
    preset or axis.
    """
    where = f'ageing_state_file {path!r}'
    try:
        with open(path) as fh:
            body = json.load(fh)
    except OSError as exc:
        raise AgeingFileError(f'{where}: cannot read it: {exc.strerror or exc}') from None
    except ValueError as exc:
        raise AgeingFileError(f'{where}: not a complete state file ({exc})') from None
    if not isinstance(body, dict) or body.get('format') != FORMAT:
        raise AgeingFileError(f'{where}: not a state file of format {FORMAT!r}')
    digest = body.pop('sha256', None)
    if digest != _digest(body):
        raise AgeingFileError(f'{where}: its sha256 does not match its contents (damaged)')
    if body.get('preset') != str(preset):
        raise AgeingFileError(f"{where}: written for preset {body.get('preset')!r}, this axis "
                              f'is {preset!r}')
    axis = _axis(params)
    other = {k: v for k, v in (body.get('axis') or {}).items() if axis.get(k) != v}
    if other or set(body.get('axis') or {}) != set(axis):
        raise AgeingFileError(f'{where}: written for another axis ({other or body.get("axis")}'
                              f' against {({k: axis[k] for k in other} or axis)})')
    try:
        return check_state(body.get('state'), 'state file')
    except LeadscrewError as exc:
        raise AgeingFileError(f'{where}: {exc}') from None
