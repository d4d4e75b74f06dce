"""
What an axis's encoder lets a velocity profile resolve (no ROS).

The drive's speed is the difference quotient of the encoder's readings over
the drive period, so it moves in quanta of one count per period
(:func:`velocity_quantum`); a commanded speed of a few quanta is the loop's
limit cycle on its own quantised feedback, which ``identify`` leaves out
(under 3 quanta). A profile's slowest held speed is therefore at least
:data:`RESOLVE` quanta, and a friction feature below that speed shows only
in the speed changes (:func:`stribeck_notes`).
"""
import math

#: Least speed of a quantised sweep's slowest level, in velocity quanta of its encoder
#: (identify leaves out levels under 3).
RESOLVE = 4.0


def velocity_quantum(params):
    """Return the nut speed [m/s] of one encoder count per drive period (0: ideal encoder)."""
    if not params.encoder_counts:
        return 0.0
    return params.drive_rate * params.lead / params.encoder_counts


def stribeck_notes(params):
    """Return a note when the encoder's velocity quantum hides the Stribeck drop (else none)."""
    q = velocity_quantum(params)
    band = params.stribeck_velocity * math.sin(params.lead_angle)   # nut speed of v_s [m/s]
    if not q or band >= 3.0 * q:
        return []
    return [f'note: the encoder\'s velocity quantum ({q:.3g} m/s at the nut) exceeds the '
            f'Stribeck velocity ({band:.3g} m/s at the nut): no held level resolves the '
            'Stribeck drop; it and mu_s show only in the breakaways and stops at the rests']
