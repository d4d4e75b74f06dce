"""
The axis a commissioning run reads: a leadscrew_sim recording, or a real axis's bag as mapped.

Both give the stages the same pieces: the commands by kind with the times
they act from [s], the measured joint states (:class:`Measured`, their
stamps [s]), the step rate [Hz], the sensors, and the re-simulation of the
whole recording with a calibrated set (its columns and the time of each
step's state [s], in the clock of the stamps).

- :class:`OwnAxis`: a node's or ``simulate``'s recording. Its parameters
  record gives the sensors, their noise seed and the rate, and the commands
  are its Float64 command topics.
- :class:`ForeignAxis`: a bag of another stack, mapped by the options of
  ``identify`` (:mod:`leadscrew_sim.offline.foreign.mapping`). Its commands
  are those of the mapped topic as the node takes them (a JointState
  command: position, else velocity, else effort), at their receipt plus
  the command delay. Its sensors are those the starting set declares, else
  those the fit read from the data. Without a nut joint the nut is read
  through the lead from the screw angle.
"""
import json

import numpy as np

from .context import Measured
from .segments import command_series
from ..foreign.mapping import Mapping
from ..foreign.replay import ForeignReplay
from ..options import NS
from ...core.commands import NutMap
from ...core.params import ScrewParams
from ...io.run_file import PARAMS_RECORD, params_from_record, run_setting

#: The sensor settings the twin takes from the axis (its own sensors).
SENSORS = ('encoder_counts', 'encoder_noise', 'encoder_bias', 'scale_resolution',
           'scale_noise', 'scale_bias', 'sensor_seed', 'linear_scale')
#: The sensor figures of the report: (report key, parameter).
SENSOR_KEYS = (('encoder_counts', 'encoder_counts'), ('encoder_noise_rad', 'encoder_noise'),
               ('linear_scale', 'linear_scale'), ('scale_resolution_m', 'scale_resolution'),
               ('scale_noise_m', 'scale_noise'))


def physics_values(params):
    """Return every physics value of ``params`` (the faults left out) as a dict."""
    return {n: getattr(params, n) for n in ScrewParams.names() if not n.startswith('fault_')}


class OwnAxis:
    """
    A leadscrew_sim recording: its parameters record, Float64 commands and joint_states.

    Parameters
    ----------
    rec : Recording
        The recording, its messages loaded.

    """

    foreign = False

    def __init__(self, rec):
        """Read the commands, the measured states, the rate and the recorded sensors."""
        self.rec = rec
        self.meta = rec.record(PARAMS_RECORD)
        self.commands = command_series(rec)
        self.measured = Measured.of(rec)
        self.rate = float(run_setting(self.meta, 'update_rate', 1000.0))
        self.recorded, _missing = params_from_record(self.meta)
        self.response_options = {}

    def sensors(self, start, fit):
        """Return ({report key: value}, where they came from): the recorded settings."""
        out = {}
        for key, name in SENSOR_KEYS:
            out[key] = _recorded(self.meta, name, getattr(start, name))
        return out, 'the recording\'s sensor parameters'

    def twin_values(self, calibrated, fit):
        """
        Return the twin's values: the calibrated physics, the sensors as recorded.

        The drive's loops act on the sensor readings: the twin reads the axis's
        sensors with their recorded settings (their noise seed too), so the
        loops see the same noise as on the recording.
        """
        values = physics_values(calibrated)
        values.update({n: getattr(self.recorded, n) for n in SENSORS})
        return values

    def resimulate(self, calibrated, fit, seed=None):
        """Return (columns of model.run, time of each step's state [s]) of the twin."""
        from ..replay.resim import Resim
        values = self.twin_values(calibrated, fit)
        if seed is not None:
            values['sensor_seed'] = seed
        sim = Resim(self.rec, values)
        cols = sim.replay()
        n = len(cols['nut_position'])
        return cols, (sim.t0 + (np.arange(n) + 1) * sim.dt_ns) / NS

    def stepper_unmeasured(self):
        """Return True for a stepper without encoder or scale (its nut is not measured)."""
        r = self.recorded
        return r.drive_type == 'stepper' and not r.encoder_counts and not r.linear_scale


class ForeignAxis:
    """
    A real axis's recording mapped onto the model (:class:`ForeignReplay`).

    Parameters
    ----------
    rec : Recording
        The recording (a rosbag2 bag or a ros2 MCAP file).
    args : argparse.Namespace
        The mapping options (those of ``identify``).
    start : ScrewParams
        The starting set (the axis's geometry, drive and any sensors it declares).

    """

    foreign = True

    def __init__(self, rec, args, start):
        """Map the recording; read its commands by kind and its measured states."""
        from ...core.model import LeadScrewModel
        self.rec, self.args = rec, args
        self.mapping = Mapping.from_args(args)
        self.replay = ForeignReplay(self.mapping, rec, start)
        rep = self.replay
        self.recorded = rep.params
        self.rate = NS / rep.dt_ns
        model = LeadScrewModel(rep.params, dt=rep.dt_ns / NS)
        self.nut_map = NutMap.of_model(model)
        delay = int(round(rep.delay.value * NS))
        self.commands = {k: (ts / NS, vs) for k, (ts, vs) in
                         rep.commands.by_kind(self.nut_map, delay).items()}
        self.measured, self.nut_from_screw = self._measured()
        m = self.mapping
        self.response_options = {k: getattr(m, k) for k in Mapping.keys()
                                 if getattr(m, k) is not None}
        self.response_options['params'] = rep.params

    def _measured(self):
        """Return (Measured at the state stamps, whether the nut is read from the screw)."""
        st = self.replay.states
        v = st.values
        nan = np.full(len(st.stamps), np.nan)
        x, xd = v.get('nut_position'), v.get('nut_velocity')
        theta, omega = v.get('screw_angle'), v.get('screw_velocity')
        from_screw = x is None and theta is not None
        k = self.nut_map.k
        if from_screw:
            first = theta[np.isfinite(theta)]
            x = self.recorded.initial_position + (theta - (first[0] if len(first) else 0.0)) / k
        if xd is None and omega is not None:
            xd = omega / k
        return Measured(st.stamps / NS, _or(v.get('motor_torque'), nan), _or(omega, nan),
                        _or(x, nan), _or(xd, nan)), from_screw

    def sensors(self, start, fit):
        """Return ({report key: value}, where they came from): declared, else from the data."""
        if fit is None:
            return ({key: getattr(start, name) for key, name in SENSOR_KEYS},
                    'the starting set (nothing was fitted to read them from the data)')
        loop = fit['problem'].loop_sensors
        out = {key: loop.get(name, getattr(start, name)) for key, name in SENSOR_KEYS}
        out['linear_scale'] = 'nut_position' in self.replay.states.values
        hows = '; '.join(f'{n} {how}' for n, (_s, how) in fit['problem'].noise.items())
        return out, f'read from the data by identify ({hows})'

    def twin_values(self, calibrated, fit):
        """Return the twin's values: the calibrated physics, the sensors identify's loops read."""
        values = physics_values(calibrated)
        values['initial_position'] = self.recorded.initial_position
        if fit is not None:
            values.update({n: v for n, v in fit['problem'].loop_sensors.items()
                           if n in SENSORS})
        return values

    def resimulate(self, calibrated, fit, seed=None):
        """Return (columns of model.run, time of each step's state [s]) of the twin."""
        values = self.twin_values(calibrated, fit)
        if seed is not None:
            values['sensor_seed'] = seed
        params = ScrewParams.from_dict(values, base=self.recorded)
        rep = self.replay.with_params(params)
        cols = rep.replay({}, interpolate=False)
        n = len(cols['nut_position'])
        return cols, (rep.t0 + (np.arange(n) + 1) * rep.dt_ns) / NS

    def stepper_unmeasured(self):
        """
        Return True for a stepper the starting set gives no encoder, without a nut joint.

        Its screw angle is then the driver's step count, not a measurement.
        """
        r = self.recorded
        return r.drive_type == 'stepper' and not r.encoder_counts and \
            'nut_position' not in self.replay.states.values


def open_axis(rec, args, start):
    """Return the :class:`OwnAxis` of a leadscrew_sim recording, else its :class:`ForeignAxis`."""
    if rec.record(PARAMS_RECORD) is not None and not Mapping.from_args(args).given:
        return OwnAxis(rec)
    return ForeignAxis(rec, args, start)


def _or(a, b):
    return b if a is None else a


def _recorded(meta, name, default):
    """Return the recorded sensor setting (the user knows their sensors), else ``default``."""
    v = meta.get(name)
    if v is None:
        return default
    try:
        return json.loads(v) if v in ('true', 'false') else float(v)
    except ValueError:
        return v
