"""
The events of a run: what happened to the axis, and when, from its per-tick arrays.

:func:`run_events` turns per-tick arrays (nut position against the stroke,
the limit and home switches, the drive's fault code, the command's
staleness) and a list of parameter changes into one :class:`Event` per
transition: an end stop reached and left (the nut beyond ``stroke_min`` or
``stroke_max``, where the model's end-stop springs act), a switch tripped
and released, a drive fault latched and cleared (by its name in
:data:`~leadscrew_sim.core.drive_modes.FAULT_NAMES`), an injected fault
(a ``fault.*`` parameter) on and off, a command gone stale and resumed.
A condition that goes off for less than ``settle`` seconds and comes back
(a nut bouncing on its stop) stays one event. Numbers only: nothing is printed.
"""
import collections

import numpy as np

from ..core.drive_modes import FAULT_NAMES, FAULT_NONE
from ..core.fields import field_name, public_name
from ..core.params import ScrewParams

#: One event: its time [s from the run's start], its kind and a one-line text.
Event = collections.namedtuple('Event', 'time kind text')

#: Shortest time [s] a condition must stay off to end: shorter gaps are bounces.
SETTLE = 0.02

#: The injected faults: the ``fault_*`` fields that switch a fault on or off.
#: ``fault_jam_position`` only places the jam.
FAULT_FIELDS = tuple(n for n in ScrewParams.names()
                     if n.startswith('fault_') and n != 'fault_jam_position')

#: The switches of a run's arrays: name -> (on text, off text).
SWITCHES = {'limit_min': ('limit switch min tripped', 'limit switch min released'),
            'limit_max': ('limit switch max tripped', 'limit switch max released'),
            'home': ('home switch tripped', 'home switch released')}


def intervals(on, settle_ticks=0):
    """
    Return [(first, end)] tick indices of the stretches where ``on`` holds.

    ``end`` is the first tick after the stretch (``len(on)`` when it lasts to
    the end). Stretches separated by fewer than ``settle_ticks`` off ticks
    form one.

    Parameters
    ----------
    on : array_like of bool
        The condition, per tick.
    settle_ticks : int
        The shortest gap that ends a stretch.

    """
    on = np.asarray(on, dtype=bool)
    if not len(on):
        return []
    edges = np.flatnonzero(np.diff(np.concatenate([[False], on, [False]]).astype(np.int8)))
    starts, ends = edges[0::2].tolist(), edges[1::2].tolist()
    out = []
    for a, b in zip(starts, ends):
        if out and a - out[-1][1] < settle_ticks:
            out[-1] = (out[-1][0], b)
        else:
            out.append((a, b))
    return out


def _settle_ticks(time, settle):
    """Return ``settle`` [s] in ticks of ``time`` (at least 1)."""
    if len(time) < 2:
        return 1
    dt = float(time[-1] - time[0]) / (len(time) - 1)
    return max(1, int(np.ceil(settle / dt - 1e-9))) if dt > 0 else 1


def _stretch_events(events, time, on, settle_ticks, kind, texts):
    """Add the (on, off) events of the stretches of ``on`` to ``events``."""
    n = len(on)
    for a, b in intervals(on, settle_ticks):
        events.append(Event(float(time[a]), kind + '_on', texts[0]))
        if b < n:
            events.append(Event(float(time[b]), kind + '_off', texts[1]))


def _fault_code_events(events, time, fault):
    """Add one event per change of the latched drive fault code."""
    fault = np.asarray(fault, dtype=np.int64)
    before = np.concatenate([[FAULT_NONE], fault[:-1]])
    for i in np.flatnonzero(fault != before).tolist():
        old, new = int(before[i]), int(fault[i])
        if old != FAULT_NONE:
            events.append(Event(float(time[i]), 'drive_fault_off',
                                f'drive fault cleared: {FAULT_NAMES.get(old, old)}'))
        if new != FAULT_NONE:
            events.append(Event(float(time[i]), 'drive_fault_on',
                                f'drive fault latched: {FAULT_NAMES.get(new, new)}'))


def _is_on(name, value):
    """Return True when fault field ``name`` at ``value`` injects a fault (not its default)."""
    return value != ScrewParams.field_info()[name][1]


def _value_text(value):
    return f'{value:g}' if isinstance(value, float) else str(value)


def fault_changes(changes, initial=None):
    """
    Return the events of the injected faults in a list of parameter changes.

    Parameters
    ----------
    changes : iterable of (float, dict)
        (time [s], {parameter: value}) in time order; field or ROS (``fault.*``)
        names, values of the field's type.
    initial : dict, optional
        The fault fields' values before the first change (default: off).

    """
    state = {n: ScrewParams.field_info()[n][1] for n in FAULT_FIELDS}
    state.update({field_name(k): v for k, v in (initial or {}).items()
                  if field_name(k) in state})
    events = []
    for t, values in changes:
        for key, value in values.items():
            name = field_name(key)
            if name not in state or value == state[name]:
                continue
            was, now = _is_on(name, state[name]), _is_on(name, value)
            state[name] = value
            label = public_name(name)
            if now:
                what = 'on' if not was else 'changed'
                detail = '' if isinstance(value, bool) else f' ({label}={_value_text(value)})'
                events.append(Event(float(t), 'injected_fault_on',
                                    f'injected fault {label} {what}{detail}'))
            elif was:
                events.append(Event(float(t), 'injected_fault_off',
                                    f'injected fault {label} off'))
    return events


def run_events(time, nut_position, stroke, switches=None, fault=None, stale=None,
               changes=(), initial_faults=None, settle=SETTLE):
    """
    Return the events of a run in time order: a list of :class:`Event`.

    Parameters
    ----------
    time : array_like of float
        The time of each tick [s from the run's start].
    nut_position : array_like of float
        Nut A's position at each tick [m].
    stroke : (float, float)
        ``stroke_min`` and ``stroke_max`` [m]: beyond them the end stops act.
    switches : dict, optional
        ``limit_min``, ``limit_max``, ``home``: bool arrays per tick (any of them).
    fault : array_like of int, optional
        The latched drive fault code per tick (``drive_modes.FAULT_*``).
    stale : array_like of bool, optional
        The command is stale (timed out) at each tick.
    changes : iterable of (float, dict)
        Parameter changes (time [s], {name: value}), for the injected faults
        (:func:`fault_changes`).
    initial_faults : dict, optional
        The ``fault.*`` values the run starts with (default: off).
    settle : float
        The shortest time [s] a condition must stay off to end (debounce).

    """
    time = np.asarray(time, dtype=float)
    x = np.asarray(nut_position, dtype=float)
    ticks = _settle_ticks(time, settle)
    events = []
    lo, hi = stroke
    _stretch_events(events, time, x < lo, ticks, 'end_stop',
                    (f'end stop reached at stroke_min ({lo:g} m)',
                     f'end stop left at stroke_min ({lo:g} m)'))
    _stretch_events(events, time, x > hi, ticks, 'end_stop',
                    (f'end stop reached at stroke_max ({hi:g} m)',
                     f'end stop left at stroke_max ({hi:g} m)'))
    for name, flags in (switches or {}).items():
        if flags is not None:
            _stretch_events(events, time, np.asarray(flags, dtype=bool), ticks, name,
                            SWITCHES.get(name, (f'{name} on', f'{name} off')))
    if fault is not None and len(fault):
        _fault_code_events(events, time, fault)
    if stale is not None:
        _stretch_events(events, time, np.asarray(stale, dtype=bool), 1, 'command',
                        ('command stale (command_timeout)', 'command resumed'))
    events += fault_changes(changes, initial_faults)
    return sorted(events, key=lambda e: e.time)
