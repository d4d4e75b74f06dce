"""
The node's external force input in a recording without its parameters record.

The node takes an extra axial force on the nut [N] on its ``external_force``
topic (std_msgs/Float64), held until the next message. A ``ros2 bag record`` of
the node, or its MCAP with the parameters record lost, holds those messages.
A twin that leaves them out drives a different axis: a test bench's load
force of 394 N against the speed ladder of ``stick_slip`` left the twin at the
true parameters 786 noise levels off on the screw angle. :func:`find_forces`
reads them, and :func:`held_forces` puts them on the replay's step grid, as
the node's commands are.
"""
import dataclasses

import numpy as np

from .mapping import FLOAT64
from ...core.commands import first_step
from ...io import cdr as C
from ...io.topics import graph_name

#: The node's topic of the external force (relative: any namespace).
FORCE_TOPIC = 'external_force'
#: Largest |force| the node takes [N] (the range of its external_force parameter).
FORCE_MAX = 1e7


@dataclasses.dataclass
class Forces:
    """The taken external forces of a recording: topic, log times [ns], values [N], skipped."""

    topic: str
    times: np.ndarray
    values: np.ndarray
    skipped: int


def is_force_topic(topic):
    """Return whether ``topic`` is named as the node's external force input."""
    return topic == '/' + FORCE_TOPIC or topic.endswith('/' + FORCE_TOPIC)


def find_forces(rec, state_topic, commands=()):
    """
    Return the :class:`Forces` of the node's external_force topic in ``rec`` (None: none).

    The topic in the state topic's namespace is taken first; one the mapping
    made a command topic (``commands``) is not a force. Values the node
    refuses (not finite, or beyond +-:data:`FORCE_MAX`) are skipped.
    """
    own = '/' + graph_name('joint_states')            # the node's: <ns>/axis/joint_states
    ns = state_topic[:-len(own)] if state_topic.endswith(own) else state_topic.rsplit('/', 1)[0]
    found = sorted((t for t, ty in rec.topic_types.items()
                    if ty == FLOAT64 and t not in commands and is_force_topic(t)),
                   key=lambda t: (not t.startswith(ns + '/'), t))
    for topic in found:
        arrays = rec.topic_arrays([topic])[topic]
        if not len(arrays.log_times):
            continue
        values = C.decode_float64s(arrays.messages())
        times = np.asarray(arrays.log_times, dtype=np.int64)
        ok = np.isfinite(values) & (np.abs(values) <= FORCE_MAX)
        return Forces(topic, times[ok], values[ok], int(np.count_nonzero(~ok)))
    return None


def held_forces(forces, t0, dt_ns, n, delay_ns):
    """
    Return the external force [N] of steps 0 .. n - 1 of the grid from ``t0`` [ns].

    Each message acts from the step its log time (plus ``delay_ns``, as the
    commands are shifted) falls in, until the next one; 0 before the first
    and without forces.
    """
    out = np.zeros(max(0, n))
    if forces is None or not len(forces.times) or n <= 0:
        return out
    ks = first_step(forces.times + delay_ns, t0, dt_ns)
    idx = np.searchsorted(ks, np.arange(n), side='right') - 1
    ok = idx >= 0
    out[ok] = forces.values[idx[ok]]
    return out


def forces_text(forces):
    """Return the words of a report on the external forces ('' without), ending in '; '."""
    if forces is None:
        return ''
    skipped = f', {forces.skipped} refused skipped' if forces.skipped else ''
    return f'external force from {forces.topic} ({len(forces.times)} taken{skipped}); '
