"""
The plain pieces every offline call shares: its options as fields, recordings, checks.

:class:`Options` carries a call's keywords to the run library as named
fields (never parsed command-line arguments); :func:`open_recording` opens
what the calls analyse; :func:`_number` checks a numeric option where it
enters and names it as its keyword.
"""
import dataclasses
import math

from .foreign.mapping import Mapping
from .options import open_recording as _open, RunError

__all__ = ['Options', 'Recording', 'open_recording']


class Options:
    """The options of one call as named fields (what the run library reads)."""

    def __init__(self, **fields):
        """Keep ``fields``."""
        self.__dict__.update(fields)

    def __repr__(self):
        """Return the fields."""
        return f'Options({self.__dict__!r})'


def _number(name, value, unit, lo=None, hi=None, lo_open=False, optional=True):
    """
    Check the numeric option ``name`` where it enters; return it (None passes if optional).

    Raises RunError naming the option, its value [unit] and the allowed range.
    """
    if value is None and optional:
        return None
    ok = (isinstance(value, (int, float)) and not isinstance(value, bool)
          and math.isfinite(value))
    if ok and lo is not None:
        ok = value > lo if lo_open else value >= lo
    if ok and hi is not None:
        ok = value <= hi
    if not ok:
        if lo is None and hi is None:
            raise RunError(f"option '{name}': {value!r} {unit} must be a finite number")
        rng = f'{"(" if lo_open else "["}{lo}, {hi}]'
        raise RunError(f"option '{name}': {value!r} {unit} is outside the allowed range {rng}")
    return value


def _sets(values):
    """Return ``{name: value}`` as the run library's NAME=VALUE items (None: none)."""
    if values is None:
        return None
    if not isinstance(values, dict):
        raise RunError(f'set: {values!r} must be a dict {{parameter name: value}}')
    return [f'{k}={v!r}' if isinstance(v, float) else f'{k}={v}' for k, v in values.items()]


def _opt_sets(values):
    """Return ``{name: value}`` of an excitation profile's options as NAME=VALUE items."""
    return None if values is None else [f'{k}={v}' for k, v in dict(values).items()]


# ----------------------------------------------------------------------------- recordings
@dataclasses.dataclass(frozen=True)
class Recording:
    """
    A recording to analyse: an MCAP file or a rosbag2 directory, and its mapping.

    ``mapping``: how a foreign recording's topics and joints map onto the
    axis (:class:`Mapping`; None: a leadscrew_sim recording, or the node's
    own topic and joint names).
    """

    path: str
    mapping: object = None


def open_recording(path, mapping=None):
    """
    Open an MCAP file or a rosbag2 directory for the calls; return a :class:`Recording`.

    Raises a :class:`leadscrew_sim.LeadscrewError` when it cannot be read.
    """
    if mapping is not None and not isinstance(mapping, Mapping):
        raise RunError(f'mapping: {mapping!r} must be a leadscrew_sim.Mapping')
    rec = _open(path)
    rec.require_ros2()
    return Recording(str(path), mapping)


def _recording(rec):
    """Return a :class:`Recording` of ``rec`` (a path is opened)."""
    return rec if isinstance(rec, Recording) else open_recording(rec)


def _mapping_fields(mapping):
    """Return the run library's mapping fields of a :class:`Mapping` (None: none given)."""
    m = mapping or Mapping()
    return dict(map=None, state_topic=m.state_topic, screw_joint=m.screw_joint,
                nut_joint=m.nut_joint, command_topic=m.command_topic,
                command_kind=m.command_kind, command_index=m.command_index,
                command_joint=m.command_joint, command_delay=m.command_delay,
                rate=m.step_rate)
