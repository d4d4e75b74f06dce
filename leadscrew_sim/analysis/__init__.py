"""
Analyses above the core: identification, excitation profiles, figures, linearisation and stability.

Imports :mod:`leadscrew_sim.core` and never ``io``, ``ros`` or ``cli``.
"""
