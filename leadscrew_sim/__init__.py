"""
leadscrew_sim: a lead screw axis simulator (physics core, ROS 2 node, MCAP tools).

Layers, with imports running one way (``core <- analysis``, ``core <- io``,
``{core, analysis, io} <- offline``, ``{core, io} <- ros``, ``offline <- cli``):

- :mod:`leadscrew_sim.core`: the simulator's public API (numpy and numba only),
  its compiled engine in ``core.engine``;
- :mod:`leadscrew_sim.analysis`: identification, excitation profiles, figures,
  linear design, stability maps (core and scipy, never io, ros or cli);
- :mod:`leadscrew_sim.io`: bytes and schemas (CDR, MCAP), no rclpy;
- :mod:`leadscrew_sim.offline`: the run library of the offline verbs;
- :mod:`leadscrew_sim.ros`: the ROS 2 node;
- :mod:`leadscrew_sim.cli`: the offline command line.

The physics core can be used as a plain Python library::

    from leadscrew_sim import LeadScrewModel, load_preset
    model = LeadScrewModel(load_preset('tr12x3'))
    out = model.step(0.5, dt=1e-3)   # motor torque 0.5 N m for 1 ms

and so can the offline tools (:mod:`leadscrew_sim.offline.library`)::

    import leadscrew_sim as ls
    run = ls.simulate('tr12x3', excite='commission', output='run.mcap')
    fit = ls.identify(ls.open_recording('run.mcap'), fit=['mu_s', 'mu_k'])

The names below are imported on first use, so that a process that needs only
one layer (the recorder process needs only ``io``) does not load numba.
Every error the package raises derives from ``leadscrew_sim.LeadscrewError``
(:mod:`leadscrew_sim.core.errors` lists them).
"""
__all__ = ['LeadScrewModel', 'LeadscrewError', 'StepOutput', 'ParameterError', 'ScrewParams',
           'SimulationFault', 'load_preset', 'preset_names',
           'simulate', 'open_recording', 'identify', 'commission', 'resim', 'excite', 'pullout',
           'stability', 'freqresp', 'recover', 'info', 'Mapping', 'RunError', 'MappingError']

#: The offline tools' calls (:mod:`leadscrew_sim.offline.library`) and their errors.
_LIBRARY = ('simulate', 'open_recording', 'identify', 'commission', 'resim', 'excite',
            'pullout', 'stability', 'freqresp', 'recover', 'info', 'Mapping')
_ERRORS = {'RunError': 'options', 'MappingError': 'foreign.mapping'}


def __getattr__(name):
    """Import the public names lazily: the core's, the offline calls and their errors."""
    import importlib
    if name in _LIBRARY:
        return getattr(importlib.import_module('.offline.library', __name__), name)
    if name in _ERRORS:
        return getattr(importlib.import_module(f'.offline.{_ERRORS[name]}', __name__), name)
    if name in __all__:
        from . import core
        return getattr(core, name)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
