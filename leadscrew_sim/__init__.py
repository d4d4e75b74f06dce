"""
leadscrew_sim: a lead screw axis simulator (physics core, ROS 2 node, MCAP tools).

The physics core (``geometry``, ``params``, ``kernel``, ``model``) imports
nothing from ROS and can be used as a plain Python library::

    from leadscrew_sim import LeadScrewModel, load_preset
    model = LeadScrewModel(load_preset('tr12x3'))
    out = model.step(0.5, dt=1e-3)   # motor torque 0.5 N m for 1 ms
"""
from .model import LeadScrewModel, StepOutput
from .params import ParameterError, ScrewParams, load_preset, preset_names

__all__ = ['LeadScrewModel', 'StepOutput', 'ParameterError', 'ScrewParams',
           'load_preset', 'preset_names']
