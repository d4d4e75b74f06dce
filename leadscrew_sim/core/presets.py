"""Presets: the parameter files shipped in ``config/``, found in the source tree or an install."""
import os
from pathlib import Path
import sys

from . import yamlio
from .fields import flatten, ParameterError
from .params import ScrewParams


def package_data_dirs(name):
    """
    Return the existing directories of the package's data folder ``name``, in search order.

    The source tree's ``<name>/`` (also an editable install), then
    ``<prefix>/share/leadscrew_sim/<name>`` of the install prefix this package lies
    in, of every ``AMENT_PREFIX_PATH`` entry and of ``sys.prefix``.

    Parameters
    ----------
    name : str
        ``'config'`` or ``'urdf'``.

    """
    here = Path(__file__).resolve().parent
    dirs = [here.parents[1] / name]                         # source tree / editable
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    prefixes += [sys.prefix]
    for parent in here.parents:                             # <prefix>/lib/pythonX/site-packages
        if parent.name == 'lib':
            prefixes.insert(0, str(parent.parent))
            break
    dirs += [Path(p) / 'share' / 'leadscrew_sim' / name for p in prefixes]
    return [d for d in dirs if d.is_dir()]


def config_dirs():
    """Directories searched for preset YAML files, in order (LEADSCREW_SIM_CONFIG first)."""
    first = os.environ.get('LEADSCREW_SIM_CONFIG')
    extra = [Path(first)] if first and Path(first).is_dir() else []
    return extra + package_data_dirs('config')


def preset_names():
    """Names of all presets found."""
    names = set()
    for d in config_dirs():
        names.update(p.stem for p in d.glob('*.yaml'))
    return sorted(names)


def preset_path(name):
    """
    Return the path of the YAML file of a named preset.

    Parameters
    ----------
    name : str
        Preset name, the file name in ``config/`` without ``.yaml``.

    """
    for d in config_dirs():
        p = d / f'{name}.yaml'
        if p.is_file():
            return p
    raise ParameterError('preset', f'{name!r} is not a known preset '
                         f'(known: {", ".join(preset_names()) or "none found"})')


def read_parameter_file(path):
    """
    Return the ``ros__parameters`` mapping of a ROS 2 parameter YAML file.

    Parameters
    ----------
    path : str or pathlib.Path
        The file; its first key holding ``ros__parameters`` counts
        (``/**``, a node name or a namespaced node name).

    """
    with open(path) as fh:
        doc = yamlio.load(fh) or {}
    for node in doc.values():
        if isinstance(node, dict) and 'ros__parameters' in node:
            return dict(node['ros__parameters'])
    raise ParameterError('preset', f'{path} has no <node>: ros__parameters: section')


def physics_subset(values):
    """
    Split a parameter mapping into (physics fields, other keys).

    Parameters
    ----------
    values : dict
        Parameter name -> value.

    """
    names = set(ScrewParams.names())
    values = flatten(values)    # fault.jam and a nested fault: {jam: ...} -> fault_jam
    phys = {k: v for k, v in values.items() if k in names}
    other = {k: v for k, v in values.items() if k not in names}
    return phys, other


def load_preset(name, **overrides):
    """
    Load a preset and apply overrides.

    Parameters
    ----------
    name : str
        Preset name (see :func:`preset_names`) or the path of a ``.yaml`` file.
    **overrides
        Physical parameters to change, in their SI units (see ScrewParams).

    Returns
    -------
    ScrewParams
        The validated parameter set.

    """
    path = Path(name) if str(name).endswith(('.yaml', '.yml')) else preset_path(name)
    phys, _ = physics_subset(read_parameter_file(path))
    params = ScrewParams.from_dict(phys)
    return ScrewParams.from_dict(overrides, base=params) if overrides else params


def preset_label(name):
    """
    Return the name a preset reports: its own ``preset`` key for a file, else the name.

    Parameters
    ----------
    name : str
        Preset name or the path of a ``.yaml`` parameter file.

    """
    if not str(name).endswith(('.yaml', '.yml')):
        return str(name)
    try:
        own = read_parameter_file(name).get('preset')
    except (OSError, ParameterError, ValueError):
        own = None
    if isinstance(own, str) and own and not own.endswith(('.yaml', '.yml')):
        return own
    return Path(name).stem
