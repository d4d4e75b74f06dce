"""
The ``commission`` profile: the single profiles one after the other, each on its own command.

``sweep`` (velocity), ``breakaway`` (torque), ``reversals`` (position) and
``chirp`` (velocity), and ``iso230`` (position) with ``iso230=1``; each
part is the single profile with its defaults from the axis, so its levels
and limits are those of the single profile. The sweep comes first: a fit
of the recording's start (the sweep) re-simulates from the recorded
initial state. A stepper takes no torque command: its run has no
breakaway part. The last command of a part sets the drive's mode until
the next part's first command (the node's mode rule).

``parts`` holds (name, start [s], profile); :meth:`Commission.record` is
the segments record written into a recording (names and [start, end]
times), :data:`SEGMENTS_RECORD` its name.
"""
import bisect

from .base import KIND_TOPICS, ProfileError, UNITS
from .singles import PROFILES

__all__ = ['COMMISSION', 'Commission', 'PART_ORDER', 'SEGMENTS_FORMAT', 'SEGMENTS_RECORD']

#: The name of the metadata record of the segments in a recording.
SEGMENTS_RECORD = 'leadscrew_sim_segments'
#: The format tag of the segments record and of a segments sidecar file.
SEGMENTS_FORMAT = 'leadscrew_sim.segments/1'
#: Longest sweep time of the chirp part [s] (a stepper's default band starts low).
CHIRP_MAX = 10.0
#: The parts in their order; iso230 only when asked.
PART_ORDER = ('sweep', 'breakaway', 'reversals', 'chirp', 'iso230')


class Commission:
    """
    The commissioning run: the single profiles chained, each with the axis's defaults.

    Parameters
    ----------
    params : ScrewParams
        The axis.
    iso230 : bool or int
        Add the ISO 230-2 cycle at the end (it lasts about 150 s on tr12x3).
    gap : float
        Rest between two parts [s] (the last value of the part before holds).

    """

    name = 'commission'
    kind = 'mixed'
    figures = False
    summary = 'sweep, breakaway, reversals and chirp in one run (iso230=1 adds ISO 230-2)'
    OPTIONS = {
        'iso230': ('-', 'add the ISO 230-2 cycle (1 yes, 0 no)', 0, 1, True),
        'gap': ('s', 'rest between two parts', 0.0, 10.0, False),
    }

    def __init__(self, params, iso230=None, gap=None):
        """Build the parts from the axis's defaults."""
        self.params = params
        self.options = {'iso230': self._check('iso230', 0 if iso230 is None else iso230),
                        'gap': self._check('gap', 0.5 if gap is None else gap)}
        names = [n for n in PART_ORDER if n != 'iso230' or self.options['iso230']]
        if params.drive_type == 'stepper':       # no torque commands to a stepper
            names.remove('breakaway')
        self.parts, t = [], 0.0
        for n in names:
            p = PROFILES[n](params)
            if n == 'chirp' and p.duration > CHIRP_MAX + 1.0:
                p = PROFILES[n](params, duration=CHIRP_MAX)    # fmin stays the default
            self.parts.append((n, t, p))
            t += p.duration + self.options['gap']
        self.duration = t - self.options['gap']
        self._starts = [t0 for _n, t0, _p in self.parts]
        self.segments = tuple(s._replace(t0=s.t0 + t0, t1=s.t1 + t0, label=f'{n}: {s.label}')
                              for n, t0, p in self.parts for s in p.segments)
        self._seg_starts = [s.t0 for s in self.segments]
        #: Default and lowest command rate [Hz]: those of the fastest part (the chirp's).
        self.command_rate = max(getattr(p, 'command_rate', 100.0) for _n, _t, p in self.parts)
        self.min_command_rate = max(getattr(p, 'min_command_rate', 0.0)
                                    for _n, _t, p in self.parts)

    def _check(self, key, value):
        unit, _d, lo, hi, integer = self.OPTIONS[key]
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise ProfileError(self.name, key, f'= {value!r}: not a number') from None
        if not lo <= number <= hi or (integer and number != int(number)):
            whole = ' (a whole number)' if integer else ''
            raise ProfileError(self.name, key, f'= {value!r} {unit}: must lie in '
                               f'[{lo:g}, {hi:g}] {unit}{whole}')
        return int(number) if integer else number

    # Timing -------------------------------------------------------------------------
    def part_index(self, t):
        """Return the index of the part in force at ``t`` [s] (a gap: the part before)."""
        return max(bisect.bisect_right(self._starts, t + 1e-9) - 1, 0)

    def part_at(self, t):
        """Return (name, start [s], profile) of the part in force at ``t`` [s]."""
        return self.parts[self.part_index(t)]

    def kind_at(self, t):
        """Return the command kind (torque, velocity, position) at ``t`` [s]."""
        return self.part_at(t)[2].kind

    def topic_at(self, t):
        """Return the node's command topic at ``t`` [s]."""
        return KIND_TOPICS[self.kind_at(t)]

    def unit_at(self, t):
        """Return the unit of the command at ``t`` [s]."""
        return UNITS[self.kind_at(t)]

    @property
    def topics(self):
        """Return the command topics of the parts, each once, in order."""
        return list(dict.fromkeys(p.topic for _n, _t, p in self.parts))

    @property
    def unit(self):
        """Return the units of the parts' commands."""
        return ', '.join(dict.fromkeys(p.unit for _n, _t, p in self.parts))

    def segment_at(self, t):
        """Return the index of the segment that holds ``t`` [s]."""
        return min(max(bisect.bisect_right(self._seg_starts, t) - 1, 0),
                   len(self.segments) - 1)

    def __call__(self, t):
        """Return the planned command value at ``t`` [s] (in the unit of its part)."""
        _n, t0, p = self.part_at(t)
        return p(t - t0)

    def controller(self):
        """Return ``fn(t, x=None) -> command``: each part's own controller, on its own time."""
        ctls = [p.controller() for _n, _t, p in self.parts]

        def fn(t, x=None):
            """Return the command at ``t`` [s] for the nut at ``x`` [m]."""
            i = self.part_index(t)
            return ctls[i](t - self._starts[i], x)
        fn.needs_state = True
        return fn

    # Descriptions ---------------------------------------------------------------------
    def windows(self):
        """Return [(name, start [s], end [s])] of the parts."""
        return [(n, t0, t0 + p.duration) for n, t0, p in self.parts]

    def record(self, offset=0.0):
        """
        Return the segments record: names and [start, end] times [s] (strings, MCAP metadata).

        Parameters
        ----------
        offset : float
            Time [s] of the profile's start on the recording's log-time axis.

        """
        out = {'format': SEGMENTS_FORMAT, 'time_base': 'log_time',
               'names': ','.join(n for n, _a, _b in self.windows())}
        for n, a, b in self.windows():
            out[n] = f'{a + offset!r} {b + offset!r}'
        return out

    def describe(self):
        """Return a one-line description: the name, the options and the parts."""
        return (f'excite=commission iso230={self.options["iso230"]} gap={self.options["gap"]:g} '
                f'parts={",".join(n for n, _t, _p in self.parts)}')

    def listing(self):
        """Return the lines of the profile listing of ``excite`` for this profile."""
        lines = [f'{self.name}: {self.summary}',
                 f'  commands {", ".join(self.topics)}, duration {self.duration:.3f} s, '
                 f'{len(self.parts)} parts']
        for n, a, b in self.windows():
            lines.append(f'  part {n}: {a:.3f} .. {b:.3f} s')
        for key, (unit, desc, lo, hi, _i) in self.OPTIONS.items():
            lines.append(f'  {key} = {self.options[key]:g} {unit}  ({desc}; [{lo:g}, {hi:g}])')
        return lines


#: Name -> class, for :data:`.profiles.ALL_PROFILES`.
COMMISSION = {Commission.name: Commission}
