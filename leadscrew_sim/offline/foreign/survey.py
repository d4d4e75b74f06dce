"""
What a foreign recording holds for the mapping: its JointState topics, command topics, options.

``info`` prints it: per JointState topic the joint names, which of
position, velocity and effort they carry, and the rate of the header stamps;
per command topic of a type the mapping reads, what it commands; then the
mapping options that fit, for the user to copy (the joint roles and the
command's kind are guessed from the names, and said to be guesses), each
named by its keyword, or as ``info`` names it: by its flag.
"""
import numpy as np

from .forces import is_force_topic
from .mapping import (COMMAND_TYPES, FLOAT64, is_state_topic, JOINT_STATE, MULTI_ARRAY,
                      TRAJECTORY)
from ..options import NS
from ...io import cdr as C
from ...io import joint_states as JS

#: Name parts that suggest a joint's role.
SCREW_HINTS = ('screw', 'motor', 'rev', 'rot', 'spindle')
NUT_HINTS = ('nut', 'linear', 'prism', 'slide', 'carriage', 'lin')
#: Name parts that suggest a command's kind.
KIND_HINTS = (('position', 'position'), ('velocity', 'velocity'), ('effort', 'torque'),
              ('torque', 'torque'))


def _role(name):
    low = name.lower()
    if any(h in low for h in NUT_HINTS):
        return 'nut'
    if any(h in low for h in SCREW_HINTS):
        return 'screw'
    return None


def marked_lines(rec):
    """
    Return the lines that describe a foreign recording's topics for the mapping.

    Each option they propose is marked ``<<keyword>>``
    (:func:`leadscrew_sim.offline.options.option_text` names it).
    """
    joint_topics = [t for t, ty in sorted(rec.topic_types.items()) if ty == JOINT_STATE]
    # the node's load input on the nut acts on the twin as it is, never as a command
    force_topics = [t for t, ty in sorted(rec.topic_types.items())
                    if ty == FLOAT64 and is_force_topic(t)]
    # a state (the node's nut_position is a Float64 too) is never proposed as a command
    command_topics = [t for t, ty in sorted(rec.topic_types.items())
                      if not is_state_topic(t) and t not in force_topics
                      and (ty in COMMAND_TYPES and ty != JOINT_STATE
                           or (ty == JOINT_STATE and 'command' in t))]
    arrays = rec.topic_arrays(joint_topics + force_topics + [t for t in command_topics
                                                             if t not in joint_topics])
    lines, states = [], {}
    for topic in joint_topics:
        a = arrays[topic]
        if not len(a.log_times):
            lines.append(f'JointState {topic}: no messages')
            continue
        try:
            stamps, names, pos, vel, eff = JS.joint_state_columns(a.data)
        except C.DecodeError as exc:
            lines.append(f'JointState {topic}: undecodable ({exc})')
            continue
        d = np.diff(stamps)
        rate = f'{NS / np.median(d):.1f} Hz by header stamps' if len(d) and \
            np.median(d) > 0 else 'rate -'
        carried = [q for q, v in (('position', pos), ('velocity', vel), ('effort', eff))
                   if v.size and np.isfinite(v).any()]
        lines.append(f'JointState {topic}: {len(stamps)} messages, {rate}, joints '
                     f'{", ".join(names) or "none"}; carries {", ".join(carried) or "nothing"}')
        states[topic] = names
    commands = []
    for topic in command_topics:
        ty = rec.topic_types[topic]
        a = arrays[topic]
        if not len(a.log_times):
            continue
        first = bytes(a.messages()[0])
        try:
            if ty == MULTI_ARRAY:
                what = f'{len(C.decode_float64_multi_array(first))} entries'
            elif ty == TRAJECTORY:
                _s, names, points = C.decode_joint_trajectory(first)
                vel = all(len(p[1]) for p in points) if points else False
                what = (f'joints {", ".join(names)}, {len(points)} points in the first, '
                        f'{"with" if vel else "without"} velocities')
            elif ty == JOINT_STATE:
                what = f'joints {", ".join(C.decode_joint_state(first)[1])}'
            else:
                what = 'one value'
        except C.DecodeError as exc:
            what = f'undecodable ({exc})'
        lines.append(f'command {topic}: {ty}, {len(a.log_times)} messages, {what}')
        commands.append((topic, ty, first))
    for topic in force_topics:
        if len(arrays[topic].log_times):
            lines.append(f'external force {topic}: {FLOAT64}, {len(arrays[topic].log_times)} '
                         'messages, the node\'s load on the nut [N] (the twin takes it, no '
                         'flag needed)')
    if not states:
        lines.append('no sensor_msgs/JointState topic: nothing to map the states from')
        return lines
    state = max(states, key=lambda t: ('joint_states' in t, len(arrays[t].log_times)))
    names = states[state]
    screw = next((n for n in names if _role(n) == 'screw'), None)
    nut = next((n for n in names if _role(n) == 'nut'), None)
    guessed = screw is None or nut is None
    if len(names) == 2 and guessed:
        screw, nut = (screw or [n for n in names if n != nut][0],
                      nut or [n for n in names if n != screw][0])
    base = f'<<state_topic>> {state}' + (f' <<screw_joint>> {screw}' if screw else '') + \
        (f' <<nut_joint>> {nut}' if nut else '')
    lines.append('mapping flags that fit (joint roles and kinds guessed from the names: check '
                 'them; <<map>> FILE takes the same keys):')
    if not commands:
        lines.append(f'  {base} <<command_topic>> TOPIC   (no command topic of a type read: '
                     f'{", ".join(COMMAND_TYPES)})')
    several = []
    for topic, ty, first in commands:
        kind = next((k for h, k in KIND_HINTS if h in topic.lower()), None)
        extra = ''
        if ty in (FLOAT64, MULTI_ARRAY):
            extra = f' <<command_kind>> {kind or "KIND"}'
            if ty == MULTI_ARRAY:
                n = len(C.decode_float64_multi_array(first))
                index = names.index(nut) if nut in names and names.index(nut) < n else 0
                extra += f' <<command_index>> {index}'
        elif ty == TRAJECTORY:
            cnames = C.decode_joint_trajectory(first)[1]
            joint = nut if nut in cnames else screw if screw in cnames else None
            extra = f' <<command_joint>> {joint}' if joint else ' <<command_joint>> NAME'
        lines.append(f'  {base} <<command_topic>> {topic}{extra}')
        several.append(f' <<command_topic>> {topic}{extra}')
    if len(several) > 1:
        lines.append('  all of them (the controllers a switch leaves; the latest command acts):')
        lines.append(f'  {base}{"".join(several)}')
    return lines
