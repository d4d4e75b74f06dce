"""
A run file: an MCAP file in the node's recording layout, as ``simulate`` and ``resim`` write it.

The layout: one channel per command and state topic of :mod:`.topics`
(resolved names, the node's QoS), states encoded by :class:`.messages.StateEncoder`,
and a parameters record holding every physics parameter and run setting as
``str(value)`` (the node's keys), read back with :func:`params_from_record`
and :func:`run_setting`.

With the physics parameters, a run file also carries what robot_state_publisher
would publish for the axis (:mod:`.description`), so a viewer (Foxglove's 3D
panel) shows the axis moving from the file alone: ``robot_description``
(std_msgs/String, transient local) and ``/tf_static`` once at the start (log
time t0), ``/tf`` with every state tick (the joint_states' stamp and log time,
the published screw angle and nut position), after that tick's state messages.
"""
import dataclasses
import os
from pathlib import Path

from . import messages as M, topics as T, tf as TF
from ..core import fields
from ..core.commands import COMMAND_LOG_TIME
from ..core.ageing import check_state
from ..core.params import ParameterError, ScrewParams
from ..core.settings import RunSettings
from ..core.errors import LeadscrewError

#: Metadata record of the parameters of a run (written at its start).
PARAMS_RECORD = 'leadscrew_sim_parameters'
#: Metadata record of a parameter change while the node runs.
UPDATE_RECORD = 'leadscrew_sim_parameters_update'
#: Metadata record of a ``~/reset`` of the node.
RESET_RECORD = 'leadscrew_sim_reset'
#: Metadata record of a ``~/clear_fault`` that cleared a latched drive fault.
CLEAR_FAULT_RECORD = 'leadscrew_sim_clear_fault'
#: Metadata record of the command line that wrote the file.
CLI_RECORD = 'leadscrew_sim_cli'
#: Metadata record of a ``~/relubricate`` of the node (the lubricant renewed).
RELUBRICATE_RECORD = 'leadscrew_sim_relubricate'
#: Metadata record of the ageing state at the end of a run (written when it closes).
AGEING_END_RECORD = 'leadscrew_sim_ageing_end'
#: Prefix of the ageing state's keys in the parameters record: the state at the run's start.
AGEING_KEY = 'ageing.'

#: The description channels of a run file: key in ``RunWriter.ids`` -> (topic, type, QoS);
#: topics as robot_state_publisher publishes them (robot_description in the namespace).
DESCRIPTION_TOPICS = {
    'robot_description': (T.graph_name('robot_description'), TF.STRING_TYPE,
                          TF.ROBOT_DESCRIPTION_QOS),
    '/tf_static': ('/tf_static', TF.TFMESSAGE_TYPE, TF.TF_STATIC_QOS),
    '/tf': ('/tf', TF.TFMESSAGE_TYPE, TF.TF_QOS),
}

#: The run settings ``simulate`` records: the node's defaults, clock mode 'simulate' and
#: command_timeout 0 (a command comes every tick).
#: The run settings that describe a run (how resim replays it); the node-only ones (the
#: recording's folder and limits, stats_file, publish_tf ...) stay out of a simulate file.
RUN_DESCRIPTION = ('update_rate', 'joint_prefix', 'joint_command_mode', 'command_timeout',
                   'publish_decimation')
SIMULATE_SETTINGS = dict({k: v for k, v in RunSettings(command_timeout=0.0).to_dict().items()
                          if k in RUN_DESCRIPTION}, clock_mode='simulate')

_RUN_FIELDS = {f.name: f for f in dataclasses.fields(RunSettings)}

__all__ = ['CLEAR_FAULT_RECORD', 'CLI_RECORD', 'DESCRIPTION_TOPICS', 'PARAMS_RECORD',
           'RESET_RECORD', 'UPDATE_RECORD', 'RunFileError', 'RunWriter', 'SIMULATE_SETTINGS',
           'params_from_record', 'parameters_record', 'run_setting']


class RunFileError(LeadscrewError, OSError):
    """A run file cannot be created or written; the message is one line."""


class RunWriter:
    """
    An MCAP file in the node's layout: channels, parameters record, messages.

    Parameters
    ----------
    path : str or Path
        The file to write; its directory is created.
    joint_prefix : str
        Prefix of the joint names in the joint_states.
    namespace : str
        Namespace the topics are resolved in.
    clock : bool
        Also register a ``/clock`` channel.
    params : ScrewParams, optional
        The axis: render its robot description and register the description
        channels of :data:`DESCRIPTION_TOPICS` after the others; then
        :meth:`write_description` writes it and :meth:`write_tf` /
        :meth:`tf_rows` the transforms. ``None``: no description.
    compression : str
        Of the chunks: ``'lz4'`` (the default: the offline tools write and
        read at the kernel's pace), ``'zstd'`` (a third smaller) or ``''``.

    """

    def __init__(self, path, joint_prefix='', namespace='/', clock=False, params=None,
                 compression='lz4'):
        """Open the file and register the node's channels (resolved names)."""
        from .mcap_file import McapRecorder
        from .qos import qos_profile_yaml
        self.path = str(path)
        self.urdf = self.tree = self.tf = None
        if params is not None:
            from .description import DescriptionError, JointTree, render_urdf, xacro_args
            try:
                self.urdf = render_urdf(xacro_args(params, joint_prefix))
                self.tree = JointTree(self.urdf)
            except (DescriptionError, ValueError) as exc:
                raise RunFileError(f'robot description: {exc}') from None
            self.tf = TF.TfEncoder(self.tree.moving_frames)
        try:
            Path(self.path).parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise RunFileError(f'cannot create the directory of {self.path}: {exc}') from None
        self.rec = McapRecorder(self.path, flush_interval=1.0, background=True,
                                compression=compression)
        if self.rec.error:
            raise RunFileError(f'cannot write {self.rec.error}')
        self.ids = {}
        topics = (list(T.COMMAND_TOPICS) + list(T.STATE_TOPICS) + list(T.RECORD_TOPICS)
                  + (['/clock'] if clock else []))
        for rel in topics:
            msg_type, _role, qos = T.TOPIC_SPECS[rel]
            # exact CDR from our encoders: the recorder need not trim
            self.ids[rel] = self.rec.add_channel(T.resolve(rel, namespace), msg_type,
                                                 qos_profile_yaml(**qos), trim=False)
        if self.tree is not None:
            for key, (rel, msg_type, qos) in DESCRIPTION_TOPICS.items():
                self.ids[key] = self.rec.add_channel(T.resolve(rel, namespace), msg_type,
                                                     qos_profile_yaml(**qos), trim=False)
        self.write = self.rec.write
        self.enc = M.StateEncoder(joint_prefix, bool(params is not None and params.anti_backlash))

    def write_description(self, log_time_ns):
        """Write robot_description and the static transforms (stamp = log time) once."""
        if self.tree is None:
            return
        t = int(log_time_ns)
        self.write(self.ids['robot_description'], TF.encode_string(self.urdf), t)
        self.write(self.ids['/tf_static'], TF.encode_tf_message(
            [(t, p, c, tr, q) for p, c, tr, q in self.tree.static_transforms()]), t)

    def write_tf(self, stamp_ns, screw_angle, nut_position, log_time_ns=None):
        """Write the /tf of one state tick at ``stamp_ns`` (log time: the stamp by default)."""
        if self.tree is not None:
            self.write(self.ids['/tf'], self.tf(
                stamp_ns, self.tree.moving_values(screw_angle, nut_position)),
                stamp_ns if log_time_ns is None else log_time_ns)

    def tf_rows(self, stamps_ns, screw_angles, nut_positions):
        """Return the /tf messages of many ticks, encoded as written (``TfEncoder.rows``)."""
        return TF.tf_encoded(self.tf, stamps_ns,
                             self.tree.moving_columns(screw_angles, nut_positions))

    def close(self):
        """Finish the file and return its size [B]; raise RunFileError on an I/O error."""
        self.rec.close()
        if self.rec.error:
            raise RunFileError(f'writing failed: {self.rec.error}')
        return os.path.getsize(self.path)


def parameters_record(params, preset, update_rate, dt_ns, run_overrides=None):
    """
    Return the parameters record (the node's keys) of a ``simulate`` run.

    Parameters
    ----------
    params : ScrewParams
        The physics of the run.
    preset : str
        Name of the preset or parameter file.
    update_rate : float
        Update rate [Hz].
    dt_ns : int
        Step [ns].
    run_overrides : dict, optional
        Run settings other than :data:`SIMULATE_SETTINGS` (``joint_prefix``).

    """
    values = {public: str(getattr(params, name)) for name, public in
              zip(ScrewParams.names(), ScrewParams.parameter_names())}
    cfg = dict(SIMULATE_SETTINGS, update_rate=float(update_rate), **(run_overrides or {}))
    values.update({name: str(v) for name, v in cfg.items()})
    values.update(preset=str(preset), update_rate=str(float(update_rate)),
                  clock_mode='simulate', dt_ns=str(dt_ns), t0_ns='0',
                  command_log_time=COMMAND_LOG_TIME)
    return values


def ageing_record(state):
    """Return the keys of an ageing state (a dict of floats) in a parameters record."""
    return {AGEING_KEY + name: repr(float(v)) for name, v in state.items()}


def ageing_from_record(record):
    """
    Return the ageing state a parameters record holds (a dict of floats), or None.

    Raises ParameterError naming the field of a malformed or out-of-range state.
    """
    values = {k[len(AGEING_KEY):]: v for k, v in record.items() if k.startswith(AGEING_KEY)}
    if not values:
        return None
    try:
        values = {k: float(v) for k, v in values.items()}
    except ValueError:
        raise ParameterError('ageing', f'{values!r} holds a value that is not a number') \
            from None
    return check_state(values, 'recorded ageing state')


def params_from_record(record):
    """
    Return (ScrewParams, names of the fields missing) of a parameters record.

    Missing fields take their defaults; raises ParameterError naming the
    parameter and its recorded value.

    Parameters
    ----------
    record : dict
        ``{name: str(value)}`` as :func:`parameters_record` and the node write it.

    """
    missing = [public for name, public in zip(ScrewParams.names(), ScrewParams.parameter_names())
               if name not in record and public not in record]
    return ScrewParams.from_text(record), missing


def run_setting(record, name, default):
    """
    Return run setting ``name`` of a parameters record, typed as its RunSettings field.

    The range is not checked (``simulate`` runs at rates the node refuses);
    raises ParameterError naming the setting and its recorded value.

    Parameters
    ----------
    record : dict
        ``{name: str(value)}`` of a parameters record.
    name : str
        A field of :class:`~leadscrew_sim.core.settings.RunSettings`.
    default : object
        Value when the record lacks ``name``.

    """
    text = record.get(name)
    return default if text is None else fields.from_text(_RUN_FIELDS[name], text)
