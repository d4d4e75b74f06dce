"""
Offline command-line tool ``leadscrew_sim``: simulate, info, resim, play, plot.

- ``simulate``: run the model without ROS and write an MCAP file in the
  node's recording layout (same topics, types, joint names, metadata).
- ``info`` (``summary``): one screen about a recording (any ros2-profile MCAP).
- ``resim``: re-run the recorded commands through the model with the recorded
  (or overridden) parameters and report the difference from the recorded states.
- ``play``: republish the messages of any ros2-profile MCAP with their timing.
- ``plot``: one PNG with four panels of a leadscrew_sim recording.

Tick/command alignment (the node's rule, see ``leadscrew_sim.node``): a
command logged at ``t0 + k dt`` acts on the step from ``t0 + k dt`` to
``t0 + (k + 1) dt``, whose states are logged at ``t0 + (k + 1) dt``. ``simulate``
logs one ``torque_command`` per tick at ``k dt`` (and ``external_force`` when it
changes), so ``resim`` feeds the model the very same doubles and reproduces
the states bit for bit.

Every error prints one line ``leadscrew_sim: error: ...`` on stderr and exits
with status 1 (2 for command-line usage errors); set ``LEADSCREW_SIM_DEBUG=1``
for tracebacks.
"""
import argparse
import bisect
import math
import os
from pathlib import Path
import struct
import sys
import time

import numpy as np

from ..io import cdr as C, messages as M, topics as T
from ..core.params import ParameterError, ScrewParams
from ..core.presets import load_preset, physics_subset, read_parameter_file

PROG = 'leadscrew_sim'
NS = 1_000_000_000
PARAMS_RECORD = 'leadscrew_sim_parameters'
UPDATE_RECORD = 'leadscrew_sim_parameters_update'
RESET_RECORD = 'leadscrew_sim_reset'
CLI_RECORD = 'leadscrew_sim_cli'
DEFAULT_PRESET = 'tr12x3'
MCAP_MAGIC = b'\x89MCAP0\r\n'

#: The node's run settings (NODE_PARAMETERS of leadscrew_sim.node) as simulate writes
#: them into the parameters record; command_timeout 0: a command comes every tick.
RUN_SETTINGS = dict(
    update_rate=1000.0, clock_mode='simulate', real_time_factor=0.0, joint_prefix='',
    command_timeout=0.0, max_catchup_steps=10, publish_decimation=1, record=True,
    record_dir='runs', record_prefix='leadscrew', record_split_bytes=0,
    record_split_seconds=0.0, record_flush_interval=1.0, stats_file='')
COMMAND_LOG_TIME = 'a command logged at t acts on the step [t, t + dt)'


class CliError(Exception):
    """A user-facing error: printed as one line, exit status 1."""


class UsageError(CliError):
    """A command-line usage error (exit status 2)."""


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line (no usage dump)."""

    def error(self, message):
        """Raise UsageError instead of printing the usage and exiting."""
        raise UsageError(message)


# ---------------------------------------------------------------------------
# Parameters
# ---------------------------------------------------------------------------

def _parse_scalar(text):
    """Parse a --set value as a YAML scalar; '1e-4' counts as a number."""
    from ..core import yamlio
    try:
        value = yamlio.load(text)
    except yamlio.YAMLError:
        value = text
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            pass
    return value


def parse_sets(items):
    """Return (physics overrides, run-setting overrides) from ``name=value`` strings."""
    fields = ScrewParams.field_info()
    phys, run = {}, {}
    for item in items or ():
        name, sep, text = item.partition('=')
        name = name.strip()
        if not sep or not name:
            raise CliError(f'--set {item!r}: expected name=value')
        value = _parse_scalar(text)
        if name in fields:
            phys[name] = value
        elif name == 'joint_prefix':
            run[name] = '' if value is None else str(text)
        else:
            raise CliError(f"--set: unknown parameter '{name}' (physics parameters: "
                           f"{', '.join(sorted(fields))}; or joint_prefix)")
    return phys, run


def _from_str(name, text):
    """Convert a metadata string back to the typed value of ScrewParams field ``name``."""
    default = ScrewParams.field_info()[name][1]
    try:
        if isinstance(default, bool):
            if text not in ('True', 'False'):
                raise ValueError(text)
            return text == 'True'
        if isinstance(default, int):
            return int(text)
        if isinstance(default, float):
            return float(text)
    except ValueError:
        raise CliError(f"recorded parameter '{name}' has the invalid value {text!r}") from None
    return text


def params_from_metadata(meta, overrides=None):
    """Return (ScrewParams, missing field names) from a parameters metadata record."""
    values = {}
    missing = []
    for name in ScrewParams.field_info():
        if name in meta:
            values[name] = _from_str(name, meta[name])
        else:
            missing.append(name)
    params = ScrewParams.from_dict(values)
    if overrides:
        params = ScrewParams.from_dict(overrides, base=params)
    return params, missing


def parameters_record(params, preset, update_rate, dt_ns, run_overrides=None):
    """Return the parameters metadata record (the node's keys) of a simulate run."""
    values = {name: str(getattr(params, name)) for name in ScrewParams.field_info()}
    cfg = dict(RUN_SETTINGS, update_rate=float(update_rate), **(run_overrides or {}))
    values.update({name: str(v) for name, v in cfg.items()})
    values.update(preset=str(preset), update_rate=str(float(update_rate)),
                  clock_mode='simulate', dt_ns=str(dt_ns), t0_ns='0',
                  command_log_time=COMMAND_LOG_TIME)
    return values


# ---------------------------------------------------------------------------
# Inputs: torque / force sources
# ---------------------------------------------------------------------------

def read_csv_series(path, what):
    """Read ``time,value`` rows (s, SI) with an optional header; return sorted (times, values)."""
    try:
        fh = open(path, newline='')
    except OSError as exc:
        raise CliError(f'{what} CSV {path}: {exc.strerror or exc}') from None
    times, values = [], []
    with fh:
        for lineno, line in enumerate(fh, 1):
            text = line.strip()
            if not text or text.startswith('#'):
                continue
            cells = [c.strip() for c in text.replace(';', ',').split(',')]
            try:
                if len(cells) != 2:
                    raise ValueError
                t, v = float(cells[0]), float(cells[1])
            except ValueError:
                if not times and lineno == 1 and not _numeric(cells[0]):
                    continue                        # header line
                raise CliError(f'{what} CSV {path}, line {lineno}: expected "time,value" '
                               f'with two numbers, got {text[:60]!r}') from None
            if not (math.isfinite(t) and math.isfinite(v)):
                raise CliError(f'{what} CSV {path}, line {lineno}: non-finite number')
            if times and t < times[-1]:
                raise CliError(f'{what} CSV {path}, line {lineno}: time {t} s goes backwards '
                               f'(previous {times[-1]} s)')
            times.append(t)
            values.append(v)
    if not times:
        raise CliError(f'{what} CSV {path}: no data rows')
    return times, values


def _numeric(text):
    try:
        float(text)
        return True
    except ValueError:
        return False


class Held:
    """Zero-order hold of a (time, value) series: value of the last row with time <= t."""

    def __init__(self, times, values, before=0.0):
        """Keep the series; ``before`` is the value before the first row."""
        self.times, self.values, self.before = times, values, before

    def __call__(self, t):
        """Return the held value at time t [s]."""
        i = bisect.bisect_right(self.times, t + 1e-12)
        return self.values[i - 1] if i else self.before


class MoveController:
    """
    PID position control of the nut toward a target along a ramp reference (``--profile move``).

    Reference: from the initial position to ``target`` at ``speed`` m/s.
    Gains from the effective moving mass M (payload + reflected inertia) with
    three closed-loop poles at ``-2 pi bandwidth``: kd = 3 M w, kp = 3 M w^2,
    ki = M w^3; gravity feed-forward; the integral is clamped so its force
    stays within the motor's max_torque (anti-windup). The model saturates the
    torque itself.
    """

    def __init__(self, params, target, speed, bandwidth=3.0):
        """Precompute the reference ramp and the gains."""
        self.x0 = params.initial_position
        self.target = target
        self.speed = abs(speed)
        self.rt = params.lead / (2.0 * math.pi)
        mass = params.moving_mass + (params.motor_inertia + params.screw_inertia) / self.rt ** 2
        w = 2.0 * math.pi * bandwidth
        self.kp, self.kd, self.ki = 3.0 * mass * w * w, 3.0 * mass * w, mass * w ** 3
        self.f_grav = params.moving_mass * params.gravity * math.sin(params.inclination)
        self.f_max = params.max_torque / self.rt
        self.hs = params.hand_sign
        self.integral = 0.0
        self.t_prev = 0.0

    def reference(self, t):
        """Return the reference position [m] at time t [s]."""
        d = self.target - self.x0
        travel = self.speed * t
        return self.target if travel >= abs(d) else self.x0 + math.copysign(travel, d)

    def __call__(self, t, x, v):
        """
        Return the motor torque [N m] for the nut position x [m].

        v is the motor velocity expressed as nut velocity (h rt omega_m) [m/s]:
        damping on the motor side is collocated with the torque, so a compliant
        coupling does not destabilize the loop.
        """
        ref = self.reference(t)
        v_ref = 0.0 if ref == self.target else math.copysign(self.speed, self.target - self.x0)
        err = ref - x
        lim = self.f_max / self.ki
        self.integral = min(lim, max(-lim, self.integral + err * (t - self.t_prev)))
        self.t_prev = t
        force = self.kp * err + self.kd * (v_ref - v) + self.ki * self.integral + self.f_grav
        # x = rt * q and q = h * theta: a force F along +x needs a torque h * rt * F.
        return self.hs * self.rt * force


def make_torque_source(args, params):
    """
    Return ``fn(k, t, x, v) -> torque`` and a description of the input.

    x is the nut position [m], v the motor velocity as nut velocity [m/s].
    """
    chosen = [n for n, v in (('--torque', args.torque), ('--torque-csv', args.torque_csv),
                             ('--profile', args.profile)) if v is not None]
    if len(chosen) > 1:
        raise CliError(f'give only one torque input, not {" and ".join(chosen)}')
    if args.torque_csv is not None:
        held = Held(*read_csv_series(args.torque_csv, 'torque'))
        return (lambda k, t, x, v: held(t)), f'torque_csv={args.torque_csv}'
    if args.profile is None:
        c = float(args.torque or 0.0)
        _finite('--torque', c)
        return (lambda k, t, x, v: c), f'torque={c}'
    amp = args.amplitude
    if args.profile == 'move':
        target = args.target if args.target is not None else params.initial_position + 0.01
        if not params.stroke_min <= target <= params.stroke_max:
            raise CliError(f'--target {target} m lies outside the stroke '
                           f'[{params.stroke_min}, {params.stroke_max}] m')
        ctl = MoveController(params, target, args.speed)
        fn = (lambda k, t, x, v: ctl(t, x, v))
        fn.needs_state = True           # closed loop: simulate steps tick by tick
        return fn, f'profile=move target={target} speed={args.speed}'
    amp = 0.5 * params.max_torque if amp is None else amp
    _finite('--amplitude', amp)
    f = args.frequency
    if args.profile == 'step':
        t_step = args.step_time
        return (lambda k, t, x, v: amp if t >= t_step else 0.0), (
            f'profile=step amplitude={amp} step_time={t_step}')
    if args.profile == 'ramp':
        dur = args.duration
        return (lambda k, t, x, v: amp * t / dur), f'profile=ramp amplitude={amp}'
    w = 2.0 * math.pi * f
    return (lambda k, t, x, v: amp * math.sin(w * t)), f'profile=sine amplitude={amp} f={f}'


def _finite(name, value):
    if not math.isfinite(value):
        raise CliError(f'{name} {value!r} is not a finite number')


def make_force_source(args):
    """Return ``fn(t) -> external force [N]`` (None: no force input) and a description."""
    if args.force is not None and args.force_csv is not None:
        raise CliError('give only one of --force and --force-csv')
    if args.force_csv is not None:
        return Held(*read_csv_series(args.force_csv, 'force')), f'force_csv={args.force_csv}'
    if args.force is not None:
        _finite('--force', args.force)
        c = float(args.force)
        return (lambda t: c), f'force={c}'
    return None, ''


# ---------------------------------------------------------------------------
# Progress
# ---------------------------------------------------------------------------

class Progress:
    """A progress bar on stderr, shown only once a run has taken ``delay`` s of wall time."""

    def __init__(self, total, label, quiet=False, delay=2.0):
        """Start the clock."""
        self.total = max(1, total)
        self.label = label
        self.quiet = quiet or not total
        self.t0 = time.monotonic()
        self.delay = delay
        self.next = self.t0 + delay
        self.shown = False

    def update(self, done):
        """Redraw at most 4 times a second."""
        now = time.monotonic()
        if self.quiet or now < self.next:
            return
        self.next = now + 0.25
        self.shown = True
        frac = done / self.total
        bar = '#' * int(30 * frac)
        rate = done / (now - self.t0)
        eta = (self.total - done) / rate if rate > 0 else 0.0
        sys.stderr.write(f'\r{self.label} [{bar:<30}] {100 * frac:5.1f}% ETA {eta:5.1f} s ')
        sys.stderr.flush()

    def done(self):
        """Clear the bar."""
        if self.shown:
            sys.stderr.write('\r' + ' ' * 70 + '\r')
            sys.stderr.flush()


# ---------------------------------------------------------------------------
# Recording output
# ---------------------------------------------------------------------------

class RunWriter:
    """An MCAP file in the node's layout: channels, parameters record, messages."""

    def __init__(self, path, joint_prefix='', namespace='/', clock=False):
        """Open the file and register the node's channels (resolved names)."""
        from ..io.session import McapRecorder, qos_profile_yaml
        self.path = str(path)
        try:
            Path(self.path).parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise CliError(f'cannot create the directory of {self.path}: {exc}') from None
        self.rec = McapRecorder(self.path, flush_interval=1.0)
        if self.rec.error:
            raise CliError(f'cannot write {self.rec.error}')
        self.ids = {}
        topics = list(T.COMMAND_TOPICS) + list(T.STATE_TOPICS) + (['/clock'] if clock else [])
        for rel in topics:
            msg_type, _role, qos = T.TOPICS[rel]
            # our encoders write exact CDR, so the recorder need not trim
            self.ids[rel] = self.rec.add_channel(T.resolve(rel, namespace), msg_type,
                                                 qos_profile_yaml(**qos), trim=False)
        self.write = self.rec.write
        self.enc = M.StateEncoder(joint_prefix)

    def close(self):
        """Finish the file; raise CliError on an I/O error."""
        self.rec.close()
        if self.rec.error:
            raise CliError(f'writing failed: {self.rec.error}')
        return os.path.getsize(self.path)


# ---------------------------------------------------------------------------
# simulate
# ---------------------------------------------------------------------------

def load_params(args, phys_overrides):
    """Return (ScrewParams, preset label, extra settings from a --params file)."""
    if args.params and args.preset:
        raise CliError('give --preset or --params, not both')
    extra = {}
    if args.params:
        try:
            values = read_parameter_file(args.params)
        except OSError as exc:
            raise CliError(f'--params {args.params}: {exc.strerror or exc}') from None
        except ParameterError:
            raise CliError(f'--params {args.params}: no "<node>: ros__parameters:" '
                           'section') from None
        except Exception as exc:  # noqa: B902 - YAML syntax errors of many kinds
            raise CliError(f'--params {args.params}: cannot parse YAML: '
                           f'{str(exc).splitlines()[0]}') from None
        phys, other = physics_subset(values)
        preset = other.get('preset')
        base = load_preset(preset) if isinstance(preset, str) else ScrewParams()
        params = ScrewParams.from_dict(phys, base=base)
        extra = {k: other[k] for k in ('update_rate', 'joint_prefix') if k in other}
        label = Path(args.params).stem
    else:
        label = args.preset or DEFAULT_PRESET
        params = load_preset(label)
    if phys_overrides:
        params = ScrewParams.from_dict(phys_overrides, base=params)
    return params, label, extra


def cmd_simulate(args):
    """Run the model offline and record it in the node's layout."""
    from ..core.model import LeadScrewModel
    phys_ov, run_ov = parse_sets(args.set)
    params, label, extra = load_params(args, phys_ov)
    rate = args.rate if args.rate is not None else float(extra.get('update_rate', 1000.0))
    if not (math.isfinite(rate) and 1.0 <= rate <= 1e6):
        raise CliError(f'--rate {rate} Hz must lie in [1, 1e6]')
    if not (math.isfinite(args.duration) and args.duration > 0):
        raise CliError(f'--duration {args.duration} s must be > 0')
    prefix = run_ov.get('joint_prefix', extra.get('joint_prefix', ''))
    dt_ns = int(round(NS / rate))
    n_steps = int(round(args.duration * NS / dt_ns))
    torque_fn, torque_desc = make_torque_source(args, params)
    force_fn, force_desc = make_force_source(args)
    model = LeadScrewModel(params, dt=dt_ns / NS)
    out = args.output or f'runs/sim_{label}_{time.strftime("%Y%m%d-%H%M%S")}.mcap'
    w = RunWriter(out, prefix, clock=args.clock)
    w.rec.add_metadata(PARAMS_RECORD, parameters_record(
        params, label, rate, dt_ns, {'joint_prefix': prefix} if prefix else None))
    w.rec.add_metadata(CLI_RECORD, {
        'command': 'simulate', 'argv': ' '.join(sys.argv[1:]), 'torque_input': torque_desc,
        'force_input': force_desc, 'steps': str(n_steps)})
    t_wall = time.perf_counter()
    try:
        stats = simulate_loop(model, n_steps, dt_ns, torque_fn, force_fn, w,
                              Progress(n_steps, 'simulate', args.quiet), args.clock)
    finally:
        size = w.close()
    wall = time.perf_counter() - t_wall
    sim_s = n_steps * dt_ns / NS
    print(f'wrote {out}: {sim_s:g} s simulated at {rate:g} Hz ({n_steps} steps, '
          f'{model.nsub} substeps/step) in {wall:.2f} s wall ({sim_s / wall:.1f}x real time), '
          f'{size} B')
    print(f'nut position {stats["x_min"]:.6g} .. {stats["x_max"]:.6g} m, final '
          f'{stats["x_end"]:.6g} m; max |torque| {stats["tq_max"]:.4g} N m')
    return 0


#: Ticks per block of simulate: the model runs a block in one compiled call
#: (open-loop inputs) and the block's messages are encoded and recorded at once.
BLOCK_TICKS = 1000


def simulate_loop(model, n_steps, dt_ns, torque_fn, force_fn, w, progress, clock=False):
    """
    Advance n_steps, recording command and states per tick; return a few statistics.

    Blocks of :data:`BLOCK_TICKS` ticks: open-loop torque inputs (functions of
    time only) run through ``model.run`` in one compiled call, the closed-loop
    ``move`` profile tick by tick; both give the same bits as ``model.advance``
    per tick. The file holds, per tick k at t_k = k dt: torque_command (and
    external_force when it changes) at t_k, then the states at t_k + dt.
    """
    dt = dt_ns / NS
    needs_state = getattr(torque_fn, 'needs_state', False)
    o = model.output()
    x, vm = o.nut_position, 0.0
    vm_scale = model.params.hand_sign * model.params.lead / (2.0 * math.pi)
    stats = dict(x_min=x, x_max=x, x_end=x, tq_max=0.0)
    force = 0.0
    for k0 in range(0, n_steps, BLOCK_TICKS):
        ks = range(k0, min(n_steps, k0 + BLOCK_TICKS))
        forces, changes = [], []
        for k in ks:
            f = force if force_fn is None else float(force_fn(k * dt))
            if force_fn is not None and (f != force or k == 0):
                changes.append(k)
            forces.append(f)
            force = f
        if needs_state:
            torques, cols = _closed_loop_block(model, ks, dt, torque_fn, forces, x, vm,
                                               vm_scale)
        else:
            torques = [float(torque_fn(k, k * dt, None, None)) for k in ks]
            _check_finite(torques, ks, dt)
            try:
                r = model.run(torques, forces)
            except FloatingPointError as exc:
                raise CliError(f'simulation fault: {exc}') from None
            cols = [r[n] for n in ('screw_angle', 'nut_position', 'screw_velocity',
                                   'nut_velocity', 'motor_torque', 'axial_force',
                                   'thread_torque')]
        x = float(cols[1][-1])
        vm = vm_scale * model.output().motor_velocity
        _record_block(w, ks, dt_ns, torques, forces, changes, cols, clock)
        stats['x_min'] = min(stats['x_min'], float(np.min(cols[1])))
        stats['x_max'] = max(stats['x_max'], float(np.max(cols[1])))
        stats['tq_max'] = max(stats['tq_max'], float(np.max(np.abs(cols[4]))))
        stats['x_end'] = x
        progress.update(ks.stop)
    progress.done()
    return stats


def _check_finite(torques, ks, dt):
    bad = np.flatnonzero(~np.isfinite(np.asarray(torques, dtype=float)))
    if len(bad):
        raise CliError(f'torque input is not finite at t={ks[bad[0]] * dt:.6f} s')


def _closed_loop_block(model, ks, dt, torque_fn, forces, x, vm, vm_scale):
    """Step tick by tick (the torque depends on the state); return torques and columns."""
    n = len(ks)
    cols = [np.empty(n) for _ in range(7)]
    torques = []
    for i, k in enumerate(ks):
        tq = float(torque_fn(k, k * dt, x, vm))
        _check_finite([tq], [k], dt)
        torques.append(tq)
        try:
            model.advance(tq, None, forces[i])
        except FloatingPointError as exc:
            raise CliError(f'simulation fault: {exc}') from None
        o = model.output()
        x, vm = o.nut_position, vm_scale * o.motor_velocity
        for col, v in zip(cols, (o.screw_angle, x, o.screw_velocity, o.nut_velocity,
                                 o.motor_torque, o.axial_force, o.thread_torque)):
            col[i] = v
    return torques, cols


def _record_block(w, ks, dt_ns, torques, forces, changes, cols, clock):
    """Encode and write the messages of one block in the node's per-tick order."""
    enc, ids = w.enc, w.ids
    t_cmd = np.arange(ks.start, ks.stop, dtype=np.int64) * dt_ns
    t_state = t_cmd + dt_ns
    angle, x, w_screw, v_nut, tq_motor, f_ax, tq_thread = cols
    rows = [C.F64_TEMPLATE.rows(None, [np.asarray(torques, dtype=float)]),
            enc.joint_states.rows(t_state, [angle, x, w_screw, v_nut, tq_motor, f_ax]),
            enc.nut_position.rows(None, [x]),
            enc.thread_force.rows(t_state, [f_ax, tq_thread])]
    times = [t_cmd, t_state, t_state, t_state]
    chans = [ids['torque_command'], ids['joint_states'], ids['nut_position'],
             ids['thread_force']]
    if clock:
        rows.append(enc.clock.rows(t_state, []))
        times.append(t_state)
        chans.append(ids['/clock'])
    a = 0
    for c in changes + [ks.stop]:
        i = c - ks.start
        if i > a:
            w.rec.write_rows(chans, [r[a:i] for r in rows], [t[a:i] for t in times])
        if c == ks.stop:
            break
        # a force change: torque, force, then the states of that tick
        w.write(chans[0], rows[0][i].tobytes(), int(t_cmd[i]))
        w.write(ids['external_force'], C.encode_float64(forces[i]), int(t_cmd[i]))
        w.rec.write_rows(chans[1:], [r[i:i + 1] for r in rows[1:]],
                         [t[i:i + 1] for t in times[1:]])
        a = i + 1


# ---------------------------------------------------------------------------
# Reading recordings
# ---------------------------------------------------------------------------

class Recording:
    """A fully read MCAP file: header, channels, metadata and the messages in file order."""

    def __init__(self, path, topics=None, load_messages=True):
        """Read ``path``; raise CliError for missing, truncated or corrupt files."""
        from mcap.reader import make_reader
        self.path = str(path)
        try:
            fh = open(self.path, 'rb')
        except FileNotFoundError:
            raise CliError(f'{self.path}: no such file') from None
        except OSError as exc:
            raise CliError(f'{self.path}: {exc.strerror or exc}') from None
        with fh:
            head = fh.read(8)
            if head != MCAP_MAGIC:
                raise CliError(f'{self.path}: not an MCAP file (bad magic bytes)')
            fh.seek(0)
            try:
                reader = make_reader(fh, validate_crcs=True)
                self.header = reader.get_header()
                summary = reader.get_summary()
                if summary is None:
                    raise ValueError('no summary section')
                self.summary = summary
                self.metadata = [(m.name, dict(m.metadata)) for m in reader.iter_metadata()]
                self.channels = {c.id: c for c in summary.channels.values()}
                self.schemas = {s.id: s for s in summary.schemas.values()}
                self.messages = []
                if load_messages:
                    want = set(topics) if topics else None
                    msgs = self.messages
                    for _schema, channel, msg in reader.iter_messages(
                            topics=topics, log_time_order=False):
                        if want is None or channel.topic in want:
                            msgs.append((msg.log_time, channel.topic, msg.data))
                    msgs.sort(key=lambda m: m[0])        # stable: ties keep file order
            except CliError:
                raise
            except Exception as exc:  # noqa: B902 - mcap raises many kinds on bad data
                detail = str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__
                raise CliError(f'{self.path}: truncated or corrupt MCAP file ({detail}); '
                               'a truncated recording can be repaired with '
                               'leadscrew_sim.recording.recover()') from None
        self.profile = self.header.profile
        self.topic_types = {c.topic: self.schemas[c.schema_id].name if c.schema_id in
                            self.schemas else '' for c in self.channels.values()}

    def record(self, name):
        """Return the first metadata record called ``name`` (or None)."""
        for n, data in self.metadata:
            if n == name:
                return data
        return None

    def require_ros2(self):
        """Raise CliError unless the header profile is ros2 with cdr channels."""
        if self.profile != 'ros2':
            raise CliError(f'{self.path}: not a ROS 2 recording (MCAP profile '
                           f'{self.profile!r}, expected "ros2")')

    def require_ours(self, what):
        """Raise CliError unless the file is a leadscrew_sim recording."""
        self.require_ros2()
        if self.record(PARAMS_RECORD) is None:
            raise CliError(f'{self.path}: {what} needs a leadscrew_sim recording (no '
                           f'"{PARAMS_RECORD}" metadata record)')

    def role_topic(self, rel):
        """Return the recorded topic whose last name component is ``rel`` (or None)."""
        for topic in self.topic_types:
            if topic.rsplit('/', 1)[-1] == rel:
                return topic
        return None


# ---------------------------------------------------------------------------
# Re-simulation
# ---------------------------------------------------------------------------

class Resim:
    """
    Re-run a leadscrew_sim recording through the model.

    Commands (torque_command, joint_commands effort of the screw joint,
    external_force), parameter updates and resets are applied in log-time
    order: everything logged at or before ``t0 + k dt`` acts on step k (the
    node's rule); torque commands older than ``command_timeout`` (sim time)
    become 0 as in the node's stepped and lockstep modes. States are produced
    at ``t0 + (k + 1) dt`` every ``publish_decimation`` steps.

    A reset or parameter update logged at the same time as messages takes its
    place among them from ``messages_at_log_time`` (the number of messages of
    that log time the node recorded before it; the file order of the messages
    is their recording order). Without that key it comes after them.
    """

    def __init__(self, rec, phys_overrides=None):
        """Read parameters, run settings, commands and recorded states from ``rec``."""
        rec.require_ours('resim')
        meta = rec.record(PARAMS_RECORD)
        self.rec = rec
        self.meta = meta
        self.overrides = dict(phys_overrides or {})
        self.params, self.missing = params_from_metadata(meta, self.overrides)
        try:
            rate = float(meta.get('update_rate', 1000.0))
            self.dt_ns = int(meta.get('dt_ns') or round(NS / rate))
            self.t0 = int(meta.get('t0_ns', 0))
            self.decimation = max(1, int(meta.get('publish_decimation', 1)))
            self.timeout = float(meta.get('command_timeout', 0.0))
        except ValueError as exc:
            raise CliError(f'{rec.path}: bad run settings in the parameters record: '
                           f'{exc}') from None
        self.prefix = meta.get('joint_prefix', '')
        self.clock_mode = meta.get('clock_mode', '')
        self.topics = {rel: rec.role_topic(rel) for rel in T.COMMAND_TOPICS + T.STATE_TOPICS}
        by_topic = {t: rel for rel, t in self.topics.items() if t}
        self.events = []            # (log_time, kind, payload) in log-time order
        self.states = {}            # step index -> dict(rel -> bytes)
        last_state = -1
        order = []                  # sort keys of the events: (log time, rank)
        same_t, rank = None, 0      # rank: index among the messages of one log time
        for log_time, topic, data in rec.messages:
            if log_time != same_t:
                same_t, rank = log_time, 0
            rank += 1
            rel = by_topic.get(topic)
            if rel in T.COMMAND_TOPICS:
                self.events.append((log_time, rel, data))
                order.append((log_time, rank))
            elif rel in T.STATE_TOPICS:
                k, r = divmod(log_time - self.t0, self.dt_ns)
                if r == 0 and k > 0:
                    self.states.setdefault(k, {})[rel] = data
                    last_state = max(last_state, k)
        for name, data in rec.metadata:
            if name in (UPDATE_RECORD, RESET_RECORD) and 'log_time_ns' in data:
                try:
                    log_time = int(data['log_time_ns'])
                    before = int(data.get('messages_at_log_time', -1))
                except ValueError as exc:
                    raise CliError(f'{rec.path}: bad "{name}" metadata record: '
                                   f'{exc}') from None
                self.events.append((log_time, name, data))
                # after the first `before` messages of its log time; else after all
                order.append((log_time, before + 0.5 if before >= 0 else math.inf))
        index = sorted(range(len(self.events)), key=order.__getitem__)
        self.events = [self.events[i] for i in index]
        if last_state < 0:
            last_cmd = max([(e[0] - self.t0) // self.dt_ns for e in self.events] or [-1])
            last_state = last_cmd + 1
        self.n_steps = max(0, last_state)

    def run(self, writer=None, keep=False, progress=None):
        """
        Run all steps; optionally write a new recording and keep per-step outputs.

        Returns (new states {k: (js values, x, wrench values)}, outputs list or None,
        model).
        """
        from ..core.model import LeadScrewModel
        model = LeadScrewModel(self.params, dt=self.dt_ns / NS)
        screw = self.prefix + 'screw_joint'
        torque = force = 0.0
        cmd_time = None
        events, ne, ie = self.events, len(self.events), 0
        dt_ns, t0, dec = self.dt_ns, self.t0, self.decimation
        timeout_ns = self.timeout * NS if self.clock_mode != 'realtime' else 0.0
        new_states = {}
        outs = [] if keep else None
        enc = M.StateEncoder(self.prefix)
        self.rejected = 0
        for k in range(self.n_steps):
            t_k = t0 + k * dt_ns
            while ie < ne and events[ie][0] <= t_k:
                log_time, kind, data = events[ie]
                ie += 1
                if writer is not None and kind in writer.ids:
                    writer.write(writer.ids[kind], data, log_time)
                if kind == 'torque_command':
                    value = C.decode_float64(data)
                    if math.isfinite(value):
                        torque, cmd_time = value, t_k
                    else:
                        self.rejected += 1
                elif kind == 'joint_commands':
                    _s, names, _p, _v, eff = C.decode_joint_state(data)
                    if screw in names:
                        i = names.index(screw)
                        if len(eff) == len(names) and math.isfinite(eff[i]):
                            torque, cmd_time = eff[i], t_k
                        else:
                            self.rejected += 1
                elif kind == 'external_force':
                    value = C.decode_float64(data)
                    if math.isfinite(value):
                        force = value
                    else:
                        self.rejected += 1
                elif kind == UPDATE_RECORD:
                    changes = {n: _from_str(n, v) for n, v in data.items()
                               if n in ScrewParams.field_info()}
                    changes.update(self.overrides)
                    model.set_params(ScrewParams.from_dict(changes, base=model.params))
                elif kind == RESET_RECORD:
                    model.reset()
                    torque = force = 0.0
                    cmd_time = None
            tq = torque
            if timeout_ns > 0.0 and cmd_time is not None and t_k - cmd_time > timeout_ns:
                tq = 0.0
            try:
                model.advance(tq, None, force)
            except FloatingPointError as exc:
                raise CliError(f'simulation fault at step {k}: {exc}') from None
            if (k + 1) % dec == 0 or keep:
                o = model.output()
                js, x, wr = M.StateEncoder.values(o)
                if (k + 1) % dec == 0:
                    new_states[k + 1] = (js, x[0], wr)
                    if writer is not None:
                        s = t_k + dt_ns
                        writer.write(writer.ids['joint_states'], enc.joint_states(s, js), s)
                        writer.write(writer.ids['nut_position'], enc.nut_position(None, x), s)
                        writer.write(writer.ids['thread_force'], enc.thread_force(s, wr), s)
                if keep:
                    outs.append(o)
            if progress is not None and not k & 1023:
                progress.update(k)
        if progress is not None:
            progress.done()
        return new_states, outs, model

    def compare(self, new_states):
        """
        Return rows (topic, field, max |diff|, rms diff, n) of new vs recorded states.

        Also sets ``bit_differences``: the number of compared values whose IEEE 754
        bits differ (a zero difference can hide -0.0 against +0.0).
        """
        fields = [('joint_states', f'{q}[{j}]') for q in ('position', 'velocity', 'effort')
                  for j in self.joint_labels()] + [('nut_position', 'data'),
                                                   ('thread_force', 'force.x'),
                                                   ('thread_force', 'torque.x')]
        acc = {f: [0.0, 0.0, 0, 0] for f in fields}
        for k, rec in self.states.items():
            new = new_states.get(k)
            if new is None:
                continue
            js, x, wr = new
            if 'joint_states' in rec:
                _s, _n, pos, vel, eff = C.decode_joint_state(rec['joint_states'])
                old = list(pos[:2]) + list(vel[:2]) + list(eff[:2])
                for i, (field, val) in enumerate(zip(fields[:6], old)):
                    _acc(acc[field], val, js[i])
            if 'nut_position' in rec:
                _acc(acc[fields[6]], C.decode_float64(rec['nut_position']), x)
            if 'thread_force' in rec:
                _s, f, t = C.decode_wrench_stamped(rec['thread_force'])
                _acc(acc[fields[7]], f[0], wr[0])
                _acc(acc[fields[8]], t[0], wr[1])
        rows = []
        self.bit_differences = sum(a[3] for a in acc.values())
        for (topic, field), (mx, sq, n, _bits) in acc.items():
            rows.append((self.topics.get(topic) or topic, field, mx,
                         math.sqrt(sq / n) if n else float('nan'), n))
        return rows

    def joint_labels(self):
        """Return the two joint names."""
        return (self.prefix + 'screw_joint', self.prefix + 'nut_joint')


_BITS = struct.Struct('<d').pack


def _acc(a, old, new):
    d = old - new
    d = abs(d) if d == d else math.inf
    if d > a[0]:
        a[0] = d
    a[1] += d * d
    a[2] += 1
    if d or _BITS(old) != _BITS(new):
        a[3] += 1


def cmd_resim(args):
    """Re-simulate a recording and print the difference from the recorded states."""
    phys_ov, run_ov = parse_sets(args.set)
    if run_ov:
        raise CliError('resim --set accepts physics parameters only')
    rec = Recording(args.file)
    sim = Resim(rec, phys_ov)
    src = Path(args.file)
    out = args.output or str(src.with_name(src.name[:-5] if src.name.endswith('.mcap')
                                           else src.name)) + '.resim.mcap'
    if os.path.abspath(out) == os.path.abspath(args.file):
        raise CliError(f'--output {out} would overwrite the input file')
    w = RunWriter(out, sim.prefix)
    meta = dict(sim.meta)
    meta.update({n: str(getattr(sim.params, n)) for n in ScrewParams.field_info()})
    w.rec.add_metadata(PARAMS_RECORD, meta)
    w.rec.add_metadata(CLI_RECORD, {'command': 'resim', 'source': str(args.file),
                                    'overrides': ' '.join(args.set or [])})
    try:
        progress = Progress(sim.n_steps, 'resim', args.quiet)
        new_states, _outs, _model = sim.run(w, progress=progress)
    finally:
        w.close()
    rows = sim.compare(new_states)
    print(f'resim of {args.file}: {sim.n_steps} steps at dt {sim.dt_ns} ns '
          f'(clock_mode {sim.clock_mode or "?"}), overrides: '
          f'{" ".join(args.set or []) or "none"}; wrote {out}')
    if sim.missing:
        print(f'warning: parameters missing from the recording (defaults used): '
              f'{", ".join(sim.missing)}')
    if sim.clock_mode == 'realtime':
        print('note: realtime recording: command timeouts were wall-clock based and '
              'overrun skips are not reproduced')
    print(f'{"topic":<24} {"field":<24} {"max |diff|":>14} {"rms diff":>14} {"n":>8}')
    overall = 0.0
    for topic, field, mx, rms, n in rows:
        print(f'{topic:<24} {field:<24} {float(mx)!r:>14} {float(rms)!r:>14} {n:>8}')
        if n:
            overall = max(overall, float(mx))
    compared = sum(1 for k in sim.states if k in new_states)
    note = ''
    if compared and overall == 0.0:
        note = (' (bit-identical)' if not sim.bit_differences else
                f' (equal values, but {sim.bit_differences} differ in their bits: -0.0/+0.0)')
    print(f'compared {compared} recorded ticks; overall max |diff|: {overall!r}{note}')
    return 0


# ---------------------------------------------------------------------------
# info
# ---------------------------------------------------------------------------

def cmd_info(args):
    """Print one screen about a recording."""
    rec = Recording(args.file)
    rec.require_ros2()
    st = rec.summary.statistics
    size = os.path.getsize(args.file)
    counts = dict(st.channel_message_counts) if st else {}
    t_first = st.message_start_time if st and st.message_count else 0
    t_last = st.message_end_time if st and st.message_count else 0
    print(f'file:      {args.file} ({size} B), profile {rec.profile!r}, '
          f'library {rec.header.library!r}')
    print(f'duration:  {(t_last - t_first) / NS:.6f} s (log time {t_first / NS:.6f} .. '
          f'{t_last / NS:.6f} s), {st.message_count if st else 0} messages')
    print(f'{"topic":<28} {"type":<34} {"count":>8} {"rate Hz":>9}')
    span = (t_last - t_first) / NS
    for cid, ch in sorted(rec.channels.items(), key=lambda c: c[1].topic):
        n = counts.get(cid, 0)
        rate = f'{(n - 1) / span:.1f}' if n > 1 and span > 0 else '-'
        print(f'{ch.topic:<28} {rec.topic_types.get(ch.topic, ""):<34} {n:>8} {rate:>9}')
    meta = rec.record(PARAMS_RECORD)
    if meta is None:
        print('(not a leadscrew_sim recording: generic counts only)')
        return 0
    print(f'leadscrew_sim run: preset {meta.get("preset", "?")}, '
          f'{meta.get("update_rate", "?")} Hz, clock_mode {meta.get("clock_mode", "?")}')
    js_topic = rec.role_topic('joint_states')
    xs, vs, ws, tqs = [], [], [], []
    for _t, topic, data in rec.messages:
        if topic == js_topic:
            _s, _names, pos, vel, eff = C.decode_joint_state(data)
            if len(pos) >= 2:
                xs.append(pos[1])
            if len(vel) >= 2:
                vs.append(abs(vel[1]))
                ws.append(abs(vel[0]))
            if eff:
                tqs.append(abs(eff[0]))
    if xs:
        print(f'nut position: min {min(xs):.6g} m, max {max(xs):.6g} m, '
              f'final {xs[-1]:.6g} m')
    if vs:
        print(f'max |velocity|: nut {max(vs):.6g} m/s, screw {max(ws):.6g} rad/s')
    if tqs:
        print(f'max |motor torque|: {max(tqs):.6g} N m')
    timing = {}
    for _name, data in rec.metadata:
        for key in ('overruns', 'late_ticks', 'skipped_steps', 'catchup_steps'):
            if key in data:
                timing[key] = data[key]
    print('timing: ' + (', '.join(f'{k} {v}' for k, v in timing.items()) if timing else
                        'no overrun/late-tick counts in the metadata'))
    if args.no_resim:
        return 0
    sim = Resim(rec)
    _new, outs, model = sim.run(keep=True, progress=Progress(sim.n_steps, 'info', args.quiet))
    if outs:
        stick = sum(1 for o in outs if o.stuck) / len(outs)
        side = {name: sum(1 for o in outs if o.contact == c) / len(outs)
                for c, name in ((1, 'leading'), (-1, 'trailing'), (0, 'backlash'))}
        e = model.energy()
        print(f'(re-simulated from the recorded parameters and commands) thread stuck '
              f'{100 * stick:.1f}% of steps; contact ' +
              ', '.join(f'{k} {100 * v:.1f}%' for k, v in side.items()))
        print(f'energy: input work {e["input_work"]:.6g} J, friction dissipated '
              f'{e["friction_dissipation"]:.6g} J, damping dissipated '
              f'{e["damping_dissipation"]:.6g} J (balance residual {e["residual"]:.3g} J)')
    return 0


# ---------------------------------------------------------------------------
# plot
# ---------------------------------------------------------------------------

def cmd_plot(args):
    """Write one PNG with four panels (forces re-simulated from the file)."""
    import numpy as np
    rec = Recording(args.file)
    sim = Resim(rec)
    _new, outs, _model = sim.run(keep=True, progress=Progress(sim.n_steps, 'plot', args.quiet))
    if not outs:
        raise CliError(f'{args.file}: no steps to plot')
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    t = (sim.t0 + sim.dt_ns * np.arange(1, len(outs) + 1)) / NS
    col = {name: np.array([getattr(o, name) for o in outs], dtype=float) for name in (
        'nut_position', 'nut_velocity', 'screw_angle', 'motor_torque', 'normal_leading',
        'normal_trailing', 'friction_force', 'contact', 'stuck')}
    p = sim.params
    w_in, h_in = args.width / args.dpi, args.height / args.dpi
    fig, axs = plt.subplots(2, 2, figsize=(w_in, h_in), dpi=args.dpi)
    fig.suptitle(f'{Path(args.file).name}: preset {sim.meta.get("preset", "?")}, '
                 f'{NS / sim.dt_ns:g} Hz', fontsize=10)
    ax = axs[0, 0]
    ax.plot(t, col['nut_position'] * 1e3, 'C0', lw=1, label='nut position [mm]')
    ax.set_xlabel('time [s]')
    ax.set_ylabel('nut position [mm]', color='C0')
    ax2 = ax.twinx()
    ax2.plot(t, col['nut_velocity'] * 1e3, 'C1', lw=0.8, label='nut velocity [mm/s]')
    ax2.plot(t, col['motor_torque'] * 1e3, 'C2', lw=0.8, label='motor torque [mN m]')
    ax2.set_ylabel('velocity [mm/s], torque [mN m]')
    lines = ax.get_lines() + ax2.get_lines()
    ax.legend(lines, [ln.get_label() for ln in lines], fontsize=7, loc='best')
    ax.set_title('position, velocity, torque', fontsize=9)

    ax = axs[0, 1]
    stuck = col['stuck'] > 0.5
    ax.fill_between(t, 0, 1, where=stuck, color='0.85', step='post',
                    transform=ax.get_xaxis_transform(), label='stick')
    for c, name, color in ((1, 'leading flank', 'C3'), (-1, 'trailing flank', 'C4'),
                           (0, 'in backlash', 'C7')):
        ax.fill_between(t, 0.96, 1.0, where=col['contact'] == c, color=color, step='post',
                        transform=ax.get_xaxis_transform(), label=f'contact: {name}')
    ax.plot(t, col['normal_leading'], 'C3', lw=0.8, label='normal force, leading [N]')
    ax.plot(t, col['normal_trailing'], 'C4', lw=0.8, label='normal force, trailing [N]')
    ax.plot(t, col['friction_force'], 'k', lw=0.8, label='friction force [N]')
    ax.set_xlabel('time [s]')
    ax.set_ylabel('force [N]')
    ax.legend(fontsize=7, loc='best')
    ax.set_title('thread forces (re-simulated), stick shaded, contact side on top', fontsize=9)

    ax = axs[1, 0]
    rt = p.lead / (2.0 * math.pi)
    dev = col['nut_position'] - rt * p.hand_sign * col['screw_angle']
    ax.plot(col['screw_angle'], dev * 1e6, 'C0', lw=0.8)
    ax.axhline(0.5 * p.backlash * 1e6, color='0.5', ls='--', lw=0.8)
    ax.axhline(-0.5 * p.backlash * 1e6, color='0.5', ls='--', lw=0.8)
    ax.set_xlabel('screw angle [rad]')
    ax.set_ylabel('x - x_nominal(theta) [um]')
    ax.set_title(f'backlash hysteresis (dashed: +-b/2, b = {p.backlash * 1e6:g} um)',
                 fontsize=9)

    ax = axs[1, 1]
    ax.plot(col['nut_position'] * 1e3, col['nut_velocity'] * 1e3, 'C0', lw=0.6)
    ax.set_xlabel('nut position [mm]')
    ax.set_ylabel('nut velocity [mm/s]')
    ax.set_title('phase portrait', fontsize=9)
    for a in axs.flat:
        a.grid(True, lw=0.3)
    fig.tight_layout()
    src = Path(args.file)
    out = args.output or str(src.with_suffix('.png'))
    try:
        fig.savefig(out, dpi=args.dpi)
    except OSError as exc:
        raise CliError(f'cannot write {out}: {exc.strerror or exc}') from None
    plt.close(fig)
    print(f'wrote {out} ({args.width}x{args.height} px; forces and contact re-simulated '
          'from the recorded parameters and commands)')
    return 0


# ---------------------------------------------------------------------------
# play
# ---------------------------------------------------------------------------

def _message_class(msg_type):
    """Return the Python class of 'pkg/msg/Type'."""
    try:
        from rosidl_runtime_py.utilities import get_message
        return get_message(msg_type)
    except ImportError:
        pass
    import importlib
    parts = msg_type.split('/')
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if len(parts) != 3:
        raise CliError(f'unsupported message type name {msg_type!r}')
    try:
        return getattr(importlib.import_module(f'{parts[0]}.{parts[1]}'), parts[2])
    except (ImportError, AttributeError):
        raise CliError(f'message type {msg_type!r} is not installed') from None


def _qos_from_metadata(metadata):
    """Return a QoSProfile from a channel's offered_qos_profiles (reliable, depth 10 default)."""
    from ..core import yamlio
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    rel, dur, depth = ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE, 10
    try:
        profiles = yamlio.load(metadata.get('offered_qos_profiles', '')) or []
        if profiles and isinstance(profiles[0], dict):
            pr = profiles[0]
            if pr.get('reliability') in ('best_effort', 2):
                rel = ReliabilityPolicy.BEST_EFFORT
            if pr.get('durability') in ('transient_local', 1):
                dur = DurabilityPolicy.TRANSIENT_LOCAL
            depth = max(1, int(pr.get('depth') or 10))
    except (yamlio.YAMLError, ValueError, TypeError, AttributeError):
        pass
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=max(depth, 100), reliability=rel,
                      durability=dur)


class _Sleeper:
    """Absolute CLOCK_MONOTONIC deadlines (clock_nanosleep TIMER_ABSTIME; time.sleep fallback)."""

    def __init__(self):
        """Load libc."""
        import ctypes
        import ctypes.util

        class Timespec(ctypes.Structure):
            _fields_ = [('tv_sec', ctypes.c_long), ('tv_nsec', ctypes.c_long)]
        self._ts = Timespec()
        try:
            libc = ctypes.CDLL(ctypes.util.find_library('c') or 'libc.so.6')
            self._fn = libc.clock_nanosleep
            self._ref = ctypes.byref(self._ts)
        except (OSError, AttributeError):
            self._fn = None

    def until(self, deadline_ns):
        """Sleep until time.monotonic_ns() >= deadline_ns."""
        while True:
            now = time.monotonic_ns()
            if now >= deadline_ns:
                return
            if self._fn is None:
                time.sleep((deadline_ns - now) / NS)
            else:
                self._ts.tv_sec, self._ts.tv_nsec = divmod(deadline_ns, NS)
                self._fn(1, 1, self._ref, None)        # CLOCK_MONOTONIC, TIMER_ABSTIME


def _parse_remaps(items):
    remap = {}
    for item in items or ():
        src, sep, dst = item.partition(':=')
        if not sep or not src or not dst:
            raise CliError(f'--remap {item!r}: expected from:=to')
        remap[src] = dst
    return remap


#: play: pause after the subscribers matched [s] (the readers' side of discovery).
PLAY_SETTLE_S = 0.25
#: play: longest wait for the subscribers' acknowledgements at the end [s].
PLAY_ACK_TIMEOUT_S = 5.0


def cmd_play(args):
    """Republish a recording with its original timing."""
    if not (math.isfinite(args.rate) and args.rate > 0):
        raise CliError(f'--rate {args.rate} must be > 0')
    rec = Recording(args.file, topics=args.topics)
    rec.require_ros2()
    remap = _parse_remaps(args.remap)
    if args.topics:
        unknown = [t for t in args.topics if t not in rec.topic_types]
        if unknown:
            raise CliError(f'--topics: not in the file: {", ".join(unknown)} (topics: '
                           f'{", ".join(sorted(rec.topic_types))})')
    if not rec.messages:
        raise CliError(f'{args.file}: no messages to play')
    used = sorted({m[1] for m in rec.messages})
    chan_meta = {c.topic: dict(c.metadata) for c in rec.channels.values()}
    classes = {t: _message_class(rec.topic_types[t]) for t in used}
    import rclpy
    from rclpy.qos import QoSProfile
    context = rclpy.Context()
    rclpy.init(args=[], context=context)
    node = None
    try:
        node = rclpy.create_node('leadscrew_sim_player', context=context)
        pubs = {}
        for t in used:
            pubs[t] = node.create_publisher(classes[t], remap.get(t, t),
                                            _qos_from_metadata(chan_meta.get(t, {})))
        clock_pub = None
        if args.clock:
            from rosgraph_msgs.msg import Clock
            clock_pub = node.create_publisher(Clock, '/clock', QoSProfile(depth=10))
            clock_enc = M.StateEncoder().clock
        end = time.monotonic() + args.wait_timeout
        while time.monotonic() < end:
            matched = sum(p.get_subscription_count() for p in pubs.values())
            if matched >= args.wait_subscribers:
                # Discovery is two-sided: the subscription can be matched here
                # before its reader has matched this writer, and a message sent
                # in between is not delivered. Give the other side a moment.
                time.sleep(PLAY_SETTLE_S)
                break
            time.sleep(0.01)
        else:
            if args.wait_subscribers:
                print(f'{PROG}: warning: {matched} of {args.wait_subscribers} subscribers '
                      f'after {args.wait_timeout:g} s; playing anyway', file=sys.stderr)
        sleeper = _Sleeper()
        t_first = rec.messages[0][0]
        scale = 1.0 / args.rate
        sent = 0
        t_wall0 = time.monotonic_ns()
        while True:
            start = time.monotonic_ns() + 1_000_000
            for log_time, topic, data in rec.messages:
                sleeper.until(start + int((log_time - t_first) * scale))
                if clock_pub is not None:
                    clock_pub.publish(clock_enc(log_time, ()))
                pubs[topic].publish(data)
                sent += 1
            if not args.loop:
                break
        wall = (time.monotonic_ns() - t_wall0) / NS
        # Reliable writers: wait until the subscribers acknowledged the tail
        # before the node (and its history) is destroyed.
        from rclpy.duration import Duration
        unacked = [t for t, p in pubs.items()
                   if not p.wait_for_all_acked(Duration(seconds=PLAY_ACK_TIMEOUT_S))]
        print(f'published {sent} messages on {len(used)} topics in {wall:.3f} s '
              f'(rate {args.rate:g})')
        if unacked:
            print(f'{PROG}: warning: not acknowledged within {PLAY_ACK_TIMEOUT_S:g} s on '
                  f'{", ".join(unacked)}', file=sys.stderr)
    except KeyboardInterrupt:
        print(f'{PROG}: interrupted', file=sys.stderr)
        return 130
    finally:
        if node is not None:
            node.destroy_node()
        if context.ok():
            rclpy.shutdown(context=context)
    return 0


# ---------------------------------------------------------------------------
# main
# ---------------------------------------------------------------------------

def build_parser():
    """Return the argument parser."""
    parser = _Parser(prog=PROG, description='Offline tools for the leadscrew_sim lead screw '
                     'axis: simulate, info, resim, play, plot.')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND')
    sub.required = True

    p = sub.add_parser('simulate', help='run the model offline and write an MCAP file')
    p.add_argument('--preset', help=f'preset name (default {DEFAULT_PRESET})')
    p.add_argument('--params', help='ROS 2 parameter file (<node>: ros__parameters:)')
    p.add_argument('--set', action='append', metavar='NAME=VALUE',
                   help='override a physics parameter (repeatable; YAML scalar)')
    p.add_argument('--duration', type=float, default=1.0, help='simulated time [s]')
    p.add_argument('--rate', type=float, help='update rate [Hz], dt = 1/rate (default 1000)')
    p.add_argument('--torque', type=float, help='constant motor torque [N m]')
    p.add_argument('--torque-csv', help='CSV time,torque [s, N m], zero-order hold')
    p.add_argument('--profile', choices=('step', 'ramp', 'sine', 'move'),
                   help='torque profile (move: PD position control to --target)')
    p.add_argument('--amplitude', type=float, help='profile torque amplitude [N m] '
                   '(default max_torque/2)')
    p.add_argument('--frequency', type=float, default=1.0, help='sine frequency [Hz]')
    p.add_argument('--step-time', type=float, default=0.1, help='step profile time [s]')
    p.add_argument('--target', type=float, help='move target nut position [m] '
                   '(default initial + 10 mm)')
    p.add_argument('--speed', type=float, default=0.01, help='move reference speed [m/s]')
    p.add_argument('--force', type=float, help='constant external axial force [N]')
    p.add_argument('--force-csv', help='CSV time,force [s, N], zero-order hold')
    p.add_argument('--clock', action='store_true', help='also record /clock every tick')
    p.add_argument('--output', '-o', help='output MCAP (default runs/sim_<preset>_<time>.mcap)')
    p.add_argument('--quiet', '-q', action='store_true', help='no progress bar')
    p.set_defaults(func=cmd_simulate)

    for name in ('info', 'summary'):
        p = sub.add_parser(name, help='one screen about a recording')
        p.add_argument('file')
        p.add_argument('--no-resim', action='store_true',
                       help='skip the re-simulation (stick fraction, energy)')
        p.add_argument('--quiet', '-q', action='store_true')
        p.set_defaults(func=cmd_info)

    p = sub.add_parser('resim', help='re-simulate a recording and compare')
    p.add_argument('file')
    p.add_argument('--set', action='append', metavar='NAME=VALUE')
    p.add_argument('--output', '-o', help='output MCAP (default <stem>.resim.mcap)')
    p.add_argument('--quiet', '-q', action='store_true')
    p.set_defaults(func=cmd_resim)

    p = sub.add_parser('play', help='republish a recording with its timing')
    p.add_argument('file')
    p.add_argument('--rate', type=float, default=1.0, help='speed factor')
    p.add_argument('--topics', nargs='+', help='only these (recorded) topics')
    p.add_argument('--remap', action='append', metavar='FROM:=TO')
    p.add_argument('--loop', action='store_true')
    p.add_argument('--clock', action='store_true', help='publish /clock from the log time')
    p.add_argument('--wait-subscribers', type=int, default=1, metavar='N',
                   help='wait until N subscriptions matched in total (default 1)')
    p.add_argument('--wait-timeout', type=float, default=2.0, metavar='S',
                   help='longest wait for subscribers [s] (default 2)')
    p.set_defaults(func=cmd_play)

    p = sub.add_parser('plot', help='four-panel PNG of a leadscrew_sim recording')
    p.add_argument('file')
    p.add_argument('--output', '-o', help='PNG path (default <stem>.png)')
    p.add_argument('--width', type=int, default=1200, help='pixels')
    p.add_argument('--height', type=int, default=900, help='pixels')
    p.add_argument('--dpi', type=int, default=100)
    p.add_argument('--quiet', '-q', action='store_true')
    p.set_defaults(func=cmd_plot)
    return parser


def main(argv=None):
    """Run the command line; return the exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        args = build_parser().parse_args(argv)
        return args.func(args)
    except UsageError as exc:
        print(f'{PROG}: error: {exc} (see {PROG} --help)', file=sys.stderr)
        return 2
    except (CliError, ParameterError) as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f'{PROG}: error: interrupted', file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: B902 - never a traceback for the user
        if os.environ.get('LEADSCREW_SIM_DEBUG'):
            raise
        msg = ' '.join(str(exc).split())
        print(f'{PROG}: error: {exc.__class__.__name__}: {msg}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
