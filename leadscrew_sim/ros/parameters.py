"""
The node's ROS parameters: the physics (ScrewParams) and the run settings (RunSettings).

Both are declared from their core schema (:mod:`leadscrew_sim.core.fields`):
the unit goes into the description, the range into the descriptor, and the
read-only flag from the field metadata. An integer given for a floating-point
parameter (``ros2 param set ... backlash 0``) is taken as that number.
Start-up overrides and run-time changes are coerced and checked once, by
``ScrewParams.from_dict`` and ``RunSettings.from_dict``; a batch of changes
is taken whole or refused whole.
"""
import collections
import math

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

from ..core import load_preset, ParameterError, ScrewParams
from ..core.fields import field_name, public_name
from ..core.presets import preset_label
from ..core.settings import RunSettings
from ..core.errors import LeadscrewError

__all__ = ['check_drive_interface', 'declare_live_view', 'DEFAULT_PRESET', 'declare_parameters',
           'descriptor',
           'integers_as_doubles', 'ParameterChange', 'StartupError', 'validate_changes']

DEFAULT_PRESET = 'tr12x3'

#: The live view's start-up parameters (read-only): name -> (default, description).
LIVE_VIEW_PARAMETERS = {
    'foxglove_port': (0, 'TCP port of the Foxglove WebSocket live view (0: off; 1-65535)'),
    'foxglove_host': ('127.0.0.1', 'address the Foxglove live view binds (with foxglove_port)'),
}

#: Parameters the node knows besides the physics and the run settings.
OTHER_PARAMETERS = frozenset(('preset', 'use_sim_time', 'start_type_description_service',
                              *LIVE_VIEW_PARAMETERS))


class StartupError(LeadscrewError):
    """An invalid configuration found while the node starts (exit code 2)."""


def descriptor(name, value, md, read_only):
    """Return the ParameterDescriptor of a field with metadata ``md`` and current ``value``."""
    unit, lo, hi, choices = md['unit'], md['lo'], md['hi'], md.get('choices')
    text = md['description'] if unit in ('-', '') else f'{md["description"]} [{unit}]'
    if choices:
        text += f' (one of: {", ".join(choices)})'
    d = ParameterDescriptor(name=name, description=text, read_only=read_only)
    if lo is not None and hi is not None and math.isfinite(lo) and math.isfinite(hi):
        if isinstance(value, bool):
            pass
        elif isinstance(value, int):
            d.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=0)]
        elif isinstance(value, float):
            d.floating_point_range = [FloatingPointRange(
                from_value=float(lo), to_value=float(hi), step=0.0)]
    return d


def _overrides(node):
    """Return {name: value} of the node's start-up overrides (``-p name:=value``)."""
    return {name: p.value for name, p in getattr(node, '_parameter_overrides', {}).items()
            if p.value is not None}


def _load_base(preset):
    if not isinstance(preset, str):
        raise StartupError(f"parameter 'preset': {preset!r} is not a string")
    try:
        return load_preset(preset)
    except ParameterError as exc:
        raise StartupError(str(exc)) from None
    except (OSError, ValueError) as exc:
        raise StartupError(f"parameter 'preset': cannot read {preset!r}: {exc}") from None


def _declare(node, name, value, md, read_only):
    node.declare_parameter(name, value, descriptor(name, value, md, read_only),
                           ignore_override=True)


def declare_parameters(node):
    """
    Declare every parameter of ``node`` from its overrides; return (preset, params, settings).

    Raises StartupError for an unreadable preset or an invalid override;
    warns about overrides of unknown parameters.
    """
    overrides = _overrides(node)
    preset = overrides.get('preset', DEFAULT_PRESET)
    base = _load_base(preset)
    preset = preset_label(preset)
    node.declare_parameter('preset', preset, ParameterDescriptor(
        name='preset', read_only=True,
        description='preset name (config/<name>.yaml) or YAML path giving the defaults '
                    'of the physical parameters'), ignore_override=True)
    physics, run = ScrewParams.field_info(), RunSettings.field_info()
    try:
        params = ScrewParams.from_dict(
            {k: overrides[public_name(k)] for k in physics if public_name(k) in overrides},
            base=base)
        settings = RunSettings.from_dict({k: overrides[k] for k in run if k in overrides})
    except ParameterError as exc:
        raise StartupError(str(exc)) from None
    try:
        check_drive_interface(params, settings)
    except ParameterError as exc:
        raise StartupError(str(exc)) from None
    for schema, values in ((physics, params), (run, settings)):
        for name, (_typ, _default, md) in schema.items():
            _declare(node, public_name(name), getattr(values, name), md, md['read_only'])
    for name in getattr(node, '_parameter_overrides', {}):
        if field_name(name) not in physics and name not in run and name not in OTHER_PARAMETERS:
            node.get_logger().warn(f"ignoring unknown parameter '{name}'")
    return preset, params, settings


def declare_live_view(node):
    """
    Declare ``foxglove_port`` and ``foxglove_host`` (read-only); return (host, port).

    Raises StartupError for a port outside 0-65535 or an empty host.
    """
    overrides = _overrides(node)
    values = {}
    for name, (default, text) in LIVE_VIEW_PARAMETERS.items():
        value = overrides.get(name, default)
        if type(value) is not type(default):
            raise StartupError(f"parameter '{name}': {value!r} is not "
                               f"{'an integer' if isinstance(default, int) else 'a string'}")
        values[name] = value
    port, host = values['foxglove_port'], values['foxglove_host']
    if not 0 <= port <= 65535:
        raise StartupError(f"parameter 'foxglove_port': {port} is outside 0-65535 (0: off)")
    if not host:
        raise StartupError("parameter 'foxglove_host': empty (an address, e.g. 127.0.0.1)")
    node.declare_parameter('foxglove_port', port, ParameterDescriptor(
        name='foxglove_port', read_only=True, description=LIVE_VIEW_PARAMETERS['foxglove_port'][1],
        integer_range=[IntegerRange(from_value=0, to_value=65535, step=0)]), ignore_override=True)
    node.declare_parameter('foxglove_host', host, ParameterDescriptor(
        name='foxglove_host', read_only=True,
        description=LIVE_VIEW_PARAMETERS['foxglove_host'][1]), ignore_override=True)
    return host, port


#: A validated batch of run-time changes: ``physics`` and ``run`` the values as set, by
#: name; ``params`` and ``settings`` the new ScrewParams and RunSettings (None if the
#: batch changes none of them).
ParameterChange = collections.namedtuple('ParameterChange', 'physics run params settings')


def validate_changes(parameters, params, settings):
    """
    Validate a batch of rclpy Parameters against the current params and settings.

    Returns a :class:`ParameterChange`; raises ParameterError for the first
    invalid value (the batch is then refused whole). Other parameters
    (``use_sim_time``) pass through untouched.
    """
    physics_names, run_names = ScrewParams.field_info(), RunSettings.field_info()
    physics = {p.name: p.value for p in parameters if field_name(p.name) in physics_names}
    run = {p.name: p.value for p in parameters if p.name in run_names}
    new_params = ScrewParams.from_dict(physics, base=params) if physics else None
    new_settings = RunSettings.from_dict(run, base=settings) if run else None
    check_drive_interface(new_params or params, new_settings or settings)
    return ParameterChange(physics, run, new_params, new_settings)


def check_drive_interface(params, settings):
    """
    Raise ParameterError if the command interface asks a stepper for torque.

    A stepper drive takes position and velocity commands only, so the fixed
    ``joint_command_mode`` effort (a ros2_control effort interface) cannot drive it.
    """
    if params.drive_type == 'stepper' and settings.joint_command_mode == 'effort':
        raise ParameterError('joint_command_mode', "'effort' with drive_type stepper: a "
                             'stepper drive takes position and velocity commands only '
                             "(allowed: auto, position, velocity)")


#: Fields whose ROS parameter type is DOUBLE.
_DOUBLES = frozenset(public_name(name) for schema in (ScrewParams, RunSettings)
                     for name, (typ, _d, _md) in schema.field_info().items() if typ is float)


def integers_as_doubles(parameters):
    """
    Return the parameters with every integer given for a floating-point field made a double.

    A pre-set callback of the node: rclpy checks the type against the
    descriptor after it, so ``ros2 param set ... backlash 0`` sets 0.0 instead
    of failing with "Wrong parameter type, expected 'Double' got 'Integer'".

    Parameters
    ----------
    parameters : list of rclpy.parameter.Parameter
        The parameters of one set request.

    """
    from rclpy.parameter import Parameter
    out = []
    for p in parameters:
        if p.name in _DOUBLES and p.type_ == Parameter.Type.INTEGER:
            p = Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
        out.append(p)
    return out
