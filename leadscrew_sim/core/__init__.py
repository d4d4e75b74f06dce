"""
The physics core: geometry, parameters and presets, the kernel and the model.

Imports numpy, numba and PyYAML (for the preset files) only: nothing from ROS.
"""
from .model import LeadScrewModel, StepOutput
from .params import ParameterError, ScrewParams
from .presets import load_preset, preset_names
from .faults import SimulationFault

__all__ = ['LeadScrewModel', 'StepOutput', 'ParameterError', 'ScrewParams',
           'SimulationFault', 'load_preset', 'preset_names']
