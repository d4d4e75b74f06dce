"""
The physics core: geometry, parameters and presets, the kernel and the model.

Imports numpy, numba and PyYAML (for the preset files) only: nothing from ROS.
The names below load on first use, so that importing one light module (the
settings, the field schema) does not compile or load the numba kernel.
"""
import importlib

#: Public name -> module that defines it.
_WHERE = {
    'LeadScrewModel': 'model', 'StepOutput': 'output', 'ParameterError': 'fields',
    'ScrewParams': 'params', 'SimulationFault': 'faults', 'load_preset': 'presets',
    'preset_names': 'presets', 'LeadscrewError': 'errors',
}

__all__ = sorted(_WHERE)


def __getattr__(name):
    """Import a public core name lazily."""
    if name in _WHERE:
        return getattr(importlib.import_module(f'{__name__}.{_WHERE[name]}'), name)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
