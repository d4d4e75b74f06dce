"""
The ageing state of an axis by name: flank wear, lubricant, screw temperature.

The kernel integrates the ageing (:mod:`.engine.ageing`, doc/model.md section
19) in six slots of the state vector. :data:`STATE_FIELDS` names them with
their units and allowed ranges; :func:`check_state` validates a mapping of
them (a state file, a recording's record, a caller's dict) and
:func:`fresh_state` is a new axis's. :data:`REPORTED_FIELDS` are the fields
of a ``sim/ageing`` message, in its order: what :meth:`LeadScrewModel.ageing_values`
reports each tick.
"""
import math

from .fields import ParameterError

#: The ageing state: name -> (unit, lowest, highest allowed value).
STATE_FIELDS = {
    'wear_leading_a': ('m', 0.0, 0.1),
    'wear_trailing_a': ('m', 0.0, 0.1),
    'wear_leading_b': ('m', 0.0, 0.1),
    'wear_trailing_b': ('m', 0.0, 0.1),
    'lubricant': ('-', 0.0, 1.0),
    'screw_temperature': ('degC', -273.15, 2000.0),
}

#: The fields of a sim/ageing message (leadscrew_sim/msg/AgeingState), with their units.
REPORTED_FIELDS = {
    'wear_leading': 'm', 'wear_trailing': 'm', 'backlash': 'm', 'preload': 'N',
    'lubricant': '-', 'mu_k': '-', 'mu_s': '-', 'screw_temperature': 'degC',
    'heat_flow': 'W', 'thermal_growth': 'm',
}


def fresh_state(params):
    """Return the ageing state of a new axis: no wear, fresh lubricant, at the ambient."""
    state = dict.fromkeys(STATE_FIELDS, 0.0)
    state['lubricant'] = 1.0
    state['screw_temperature'] = params.ambient_temperature
    return state


def check_state(values, where='ageing state'):
    """
    Return the ageing state of a mapping, every field of :data:`STATE_FIELDS` checked.

    Raises ParameterError naming the field, its value and its allowed range,
    or the missing and unknown fields; ``where`` says what held the mapping.
    """
    if not hasattr(values, 'keys'):
        raise ParameterError(where, f'{values!r} is not a mapping of '
                             f'{", ".join(STATE_FIELDS)}')
    missing = [k for k in STATE_FIELDS if k not in values]
    unknown = [k for k in values if k not in STATE_FIELDS]
    if missing or unknown:
        raise ParameterError(where, f'missing {missing}, unknown {unknown}; the fields are '
                             f'{", ".join(STATE_FIELDS)}')
    state = {}
    for name, (unit, lo, hi) in STATE_FIELDS.items():
        v = values[name]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or not lo <= v <= hi:
            raise ParameterError(name, f'{v!r} [{unit}] in the {where} is outside the allowed '
                                 f'range [{lo}, {hi}]')
        state[name] = float(v)
    return state
