"""
Where a recording left the axis's ageing: the start of simulate's ``ageing_from`` option.

A recording of leadscrew_sim ends with the ageing state in its
:data:`~leadscrew_sim.io.run_file.AGEING_END_RECORD` (simulate, and the node
when its recording closes). A file cut short has none; then the last
``sim/ageing`` message gives the state, with each summed wear put on the
flanks that wear first: a single nut's own, a split nut's preloaded ones
(nut A leading, half-nut B trailing), and the recording's start state holds
the rest.
"""
from ..options import RunError
from ...core.params import ParameterError
from ...io import messages as M
from ...io.ageing_file import AXIS_FIELDS
from ...io.mcap_reader import Recording
from ...io.run_file import (AGEING_END_RECORD, AGEING_KEY, ageing_from_record, PARAMS_RECORD,
                            params_from_record)


def ageing_at_end(path, params):
    """
    Return the ageing state (a dict) at the end of the recording ``path``, for axis ``params``.

    Raises RunError naming the file if it is not a leadscrew_sim recording,
    holds no ageing, or is of another axis (:data:`~leadscrew_sim.io.ageing_file.AXIS_FIELDS`).
    """
    rec = Recording(path, load_messages=False)
    meta = rec.record(PARAMS_RECORD)
    if meta is None:
        raise RunError(f'ageing_from {path!r}: not a leadscrew_sim recording (no parameters '
                       'record)')
    try:
        recorded, _missing = params_from_record(meta)
        start = ageing_from_record(meta)
    except ParameterError as exc:
        raise RunError(f'ageing_from {path!r}: recorded {exc}') from None
    other = {k: getattr(recorded, k) for k in AXIS_FIELDS
             if getattr(recorded, k) != getattr(params, k)}
    if other:
        raise RunError(f'ageing_from {path!r}: a recording of another axis ({other} against '
                       f'{ {k: getattr(params, k) for k in other} })')
    end = rec.record(AGEING_END_RECORD)
    try:
        if end is not None:
            return ageing_from_record({k: v for k, v in end.items() if k.startswith(AGEING_KEY)})
    except ParameterError as exc:
        raise RunError(f'ageing_from {path!r}: recorded {exc}') from None
    return _from_messages(rec, path, recorded, start)


def _from_messages(rec, path, recorded, start):
    topic = rec.role_topic('sim/ageing')
    if topic is None:
        raise RunError(f'ageing_from {path!r}: the recording holds no ageing (no end record, '
                       'no sim/ageing messages)')
    rec.load([topic])
    last = None
    for _t, t_name, data in rec.messages:
        if t_name == topic:
            last = data
    if last is None:
        raise RunError(f'ageing_from {path!r}: {topic} holds no message')
    _stamp, v = M.decode_ageing(last)
    state = dict(start) if start is not None else {
        'wear_leading_a': 0.0, 'wear_trailing_a': 0.0, 'wear_leading_b': 0.0,
        'wear_trailing_b': 0.0}
    if recorded.anti_backlash:
        state['wear_leading_a'] = v['wear_leading'] - state['wear_leading_b']
        state['wear_trailing_b'] = v['wear_trailing'] - state['wear_trailing_a']
    else:
        state['wear_leading_a'] = v['wear_leading']
        state['wear_trailing_a'] = v['wear_trailing']
    state['lubricant'] = v['lubricant']
    state['screw_temperature'] = v['screw_temperature']
    try:
        return ageing_from_record({AGEING_KEY + k: x for k, x in state.items()})
    except ParameterError as exc:
        raise RunError(f'ageing_from {path!r}: {exc}') from None
