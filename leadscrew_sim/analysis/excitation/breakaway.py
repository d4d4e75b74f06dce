"""
The ``breakaway`` profile: slow motor torque ramps [N m] past breakaway (no ROS).

:func:`static_breakaway` gives the edges of the static torque band of the
rigid axis in closed form; :class:`BreakawayRamp` ramps from the centre
torque past them toward +theta and back, then toward -theta and back
(``torque_command``), in the theta sense of the node.
"""
import math

from .base import Builder, Profile


def static_breakaway(params, mu=None):
    """
    Return (T_up, T_down): the edges [N m] of the static band of motor torque (theta sense).

    Raising the torque above T_up starts the screw toward +theta, lowering
    it below T_down toward -theta; between them the axis stands still. The
    quasi-static closed form of the rigid axis (doc/model.md sections 7-8):
    the thread torque to drive against or with the axial load (gravity and
    the external force, plus the guide's Coulomb force against the motion),
    plus the bearing's Coulomb torque and the collar friction. A torque
    moving the nut toward +x has the sign of the hand sign.

    Parameters
    ----------
    params : ScrewParams
        The axis.
    mu : float, optional
        Thread friction coefficient (default ``mu_s``, the static one); the
        apparent coefficient is ``mu`` times the thread factor.

    """
    from ...core import geometry
    p = params
    mu_app = (p.mu_s if mu is None else mu) * p.thread_factor
    lam, r = p.lead_angle, p.r_m
    load = p.moving_mass * p.gravity * math.sin(p.inclination) - p.external_force
    out = []
    for s in (1.0, -1.0):                      # motion toward +x, toward -x
        w = s * load + p.guide_coulomb         # the load opposing this motion [N]
        if w >= 0.0:
            thread = geometry.raise_torque(w, r, mu_app, lam)
        else:
            thread = geometry.lower_torque(-w, r, mu_app, lam)
        rest = p.bearing_coulomb + p.collar_mu * p.collar_radius * abs(w)
        out.append(p.hand_sign * s * (thread + rest))
    plus_x, minus_x = out
    return (plus_x, minus_x) if p.hand_sign > 0 else (minus_x, plus_x)


class BreakawayRamp(Profile):
    """
    Slow motor torque ramps from the centre torque past breakaway, each direction in turn.

    Dwell at the centre, ramp toward +theta to centre + peak and back, dwell,
    the same toward -theta, dwell. The ramps are quasi-static: the default
    rate, peak / ramp_time, changes the torque by less than 0.1 % of the peak
    within the axis' slowest mechanical period (a few ms). Under
    :meth:`controller` a ramp ends once the nut has moved ``abort_travel``
    from where the ramp began: the torque returns to the centre and holds
    until the direction's ramp time is over, so a torque-driven axis does
    not run away after breakaway. :meth:`values` gives the planned ramps.
    """

    name = 'breakaway'
    kind = 'torque'
    summary = 'motor torque ramps past breakaway toward +theta, then -theta'
    OPTIONS = {
        'center': ('N m', 'torque of the dwells and the start of the ramps', -1e5, 1e5, False),
        'peak': ('N m', 'ramp amplitude from the centre', 1e-9, 1e5, False),
        'ramp_time': ('s', 'time of each ramp from the centre to the peak', 0.01, 3600.0,
                      False),
        'dwell': ('s', 'dwell at the centre before, between and after the ramps', 0.0,
                  3600.0, False),
        'abort_travel': ('m', 'nut travel that ends a ramp (controller)', 1e-9, 1.0, False),
    }

    def defaults(self, params, given):
        """
        Return the defaults: centre in the static band, peak 1.5 x nominal breakaway.

        Parameters
        ----------
        params : ScrewParams
            The axis.
        given : dict
            The options the user gave, by name (SI units).

        """
        t_pos, t_neg = static_breakaway(params)
        lo, hi = min(t_pos, t_neg), max(t_pos, t_neg)
        center = 0.0 if lo < 0.0 < hi else 0.5 * (lo + hi)
        center = float(given.get('center', center))
        reach = max(abs(t_pos - center), abs(t_neg - center))
        room = params.max_torque - abs(center)
        peak = min(0.95 * room, max(1.5 * reach, 0.05 * params.max_torque))
        return dict(center=center, peak=peak, ramp_time=2.0, dwell=0.5,
                    abort_travel=2e-4)

    def build(self, params, o):
        """
        Return the dwells and ramps.

        Parameters
        ----------
        params : ScrewParams
            The axis.
        o : dict
            Every option of the profile, by name (SI units), defaults filled in.

        """
        if abs(o['center']) + o['peak'] > params.max_torque:
            self.fail('peak', f'with centre {o["center"]:g} N m exceeds max_torque '
                      f'{params.max_torque:g} N m (the motor would clip the ramp)')
        c, a, tr, d = o['center'], o['peak'], o['ramp_time'], o['dwell']
        b = Builder(c)
        b.hold(d, 'dwell')
        for s, sign in ((1, '+'), (-1, '-')):
            b.ramp(c + s * a, tr, f'ramp {sign}theta up', s)
            b.ramp(c, tr, f'ramp {sign}theta down', s)
            b.hold(d, 'dwell')
        return b.out

    def controller(self):
        """Return ``fn(t, x=None)``: the ramps, each ending at abort_travel of nut motion."""
        return _AbortingRamp(self)


class _AbortingRamp:
    """The torque of a breakaway profile that returns to the centre once the nut moved."""

    needs_state = True

    def __init__(self, profile):
        self.profile = profile
        self.travel = profile.options['abort_travel']
        self.center = profile.options['center']
        self.start = {}          # direction -> nut position at the start of its ramps
        self.aborted = set()

    def __call__(self, t, x=None):
        p = self.profile
        s = p.segments[p.segment_at(t)]
        if s.direction == 0 or x is None or not t < p.duration:
            return p(t)
        x0 = self.start.setdefault(s.direction, x)
        if abs(x - x0) > self.travel:
            self.aborted.add(s.direction)
        return self.center if s.direction in self.aborted else p(t)
