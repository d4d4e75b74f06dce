"""
Axes and runs shared by the stepper tests (test_stepper_*.py): no oracle lives here.

:func:`rigid_axis` puts the nema17_tr8x8 preset's motor on an ideal load
(horizontal, frictionless, backlash-free, stiff: one rigid body of inertia
J_m + J_s + m rt^2), left-handed so that q = theta and x = rt theta;
:func:`run_commands` runs rows of one command; :func:`motor_inertia_total`
is J_total of that body.
"""
import math

import numpy as np

from leadscrew_sim import LeadScrewModel, load_preset
from leadscrew_sim.core.drive_modes import MODE_POSITION, MODE_VELOCITY

NAN = math.nan


def rigid_axis(preset='nema17_tr8x8', **changes):
    """Return the preset's stepper on a horizontal, frictionless, backlash-free, stiff axis."""
    values = dict(hand='left', inclination=0.0, mu_s=0.0, mu_k=0.0, backlash=0.0,
                  payload_mass=0.5, contact_stiffness=1e9, contact_damping=2e3,
                  guide_viscous=0.0, bearing_viscous=0.0, stroke_min=-50.0, stroke_max=50.0)
    values.update(changes)
    return load_preset(preset).replace(**values)


def motor_inertia_total(p):
    """J_m + J_s + (m_n + m_p) rt^2 [kg m^2]: the rigid axis as one body on the motor."""
    rt = p.lead_ratio
    return p.motor_inertia + p.screw_inertia + (p.nut_mass + p.payload_mass) * rt * rt


def position_rows(n, theta):
    """Return n command rows of a position target theta [rad] (theta sense)."""
    return np.tile([MODE_POSITION, theta, NAN, NAN], (n, 1))


def velocity_rows(n, rate):
    """Return n command rows of a velocity command rate [rad/s] (theta sense)."""
    return np.tile([MODE_VELOCITY, NAN, rate, NAN], (n, 1))


def run_commands(model, rows, forces=None):
    """Run ``rows`` (one per step) through ``model``; return the run's arrays."""
    return model.run(None, forces, commands=rows)


def new_model(p, dt=1e-3):
    """Return (model, initial motor angle [rad]) of parameters p."""
    m = LeadScrewModel(p, dt=dt)
    return m, m.output().motor_angle
