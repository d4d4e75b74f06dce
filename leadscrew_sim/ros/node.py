"""
ROS 2 node ``leadscrew_sim_node``: the lead screw axis on the ROS graph.

Contract: /work/shared/design/interfaces.md. Commands (``torque_command``,
``joint_commands``, ``external_force``) are zero-order held; every tick the
model advances by exactly one fixed step ``dt = 1 / update_rate`` and the
states (``joint_states``, ``nut_position``, ``thread_force``) are published
with the stamp ``t0 + n dt`` (integer nanoseconds, strictly increasing).

Clock modes (read-only parameter ``clock_mode``):

- ``realtime``: absolute-deadline loop on CLOCK_MONOTONIC; late ticks are
  caught up with at most ``max_catchup_steps`` extra fixed steps, beyond that
  the loop skips ahead (an overrun). t0 is the ROS time at start.
- ``stepped``: sim time from 0, ``/clock`` every tick, as fast as possible
  (``real_time_factor`` 0) or paced at ``real_time_factor``.
- ``lockstep``: one tick per received ``torque_command`` or ``joint_commands``
  message, sim time from 0, ``/clock`` every tick.

A command recorded in the MCAP file carries the log time ``t0 + n dt`` where
n is the number of steps taken before it; it first acts on the step from
``t0 + n dt`` to ``t0 + (n + 1) dt`` (the state stamped ``t0 + (n + 1) dt``).
"""
import array
import ctypes
import ctypes.util
import json
import math
import os
import signal
import struct
import sys
import time

from builtin_interfaces.msg import Time as TimeMsg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import SetBool, Trigger

from ..core import geometry
from ..io.messages import StateEncoder
from ..core.model import LeadScrewModel, MAX_SUBSTEPS_PER_STEP
from ..core import load_preset, ParameterError, ScrewParams
from ..core.settings import PREFIX_RE

NODE_NAME = 'leadscrew_sim_node'
DEFAULT_PRESET = 'tr12x3'
CLOCK_MODES = ('realtime', 'stepped', 'lockstep')

#: ScrewParams fields that change the meaning of the state: read-only at run time.
READ_ONLY_PHYSICS = frozenset((
    'thread_form', 'hand', 'major_diameter', 'pitch', 'starts', 'pitch_diameter',
    'anti_backlash', 'initial_position'))

#: Smallest non-zero file split (a smaller one starts a file for every few messages).
MIN_SPLIT_BYTES = 1 << 16
MIN_SPLIT_SECONDS = 1.0
#: Longest joint_prefix [characters]: the joint names go out in every joint_states.
MAX_JOINT_PREFIX = 128

#: Node parameters besides the physics: name -> (default, unit, description, lo, hi,
#: read_only, choices).
NODE_PARAMETERS = {
    'update_rate': (1000.0, 'Hz', 'simulation and publication rate', 1.0, 20000.0, True, None),
    'clock_mode': ('realtime', '-', 'realtime: wall-clock paced, stamps from the ROS time at '
                   'start; stepped: sim time from 0 with /clock, as fast as possible or paced '
                   'by real_time_factor; lockstep: one step per received command, with /clock',
                   None, None, True, CLOCK_MODES),
    'real_time_factor': (0.0, '-', 'stepped mode pacing: sim seconds per wall second; '
                         '0 runs as fast as possible', 0.0, 1000.0, False, None),
    'joint_prefix': ('', '-', 'prefix of the joint names screw_joint and nut_joint',
                     None, None, False, None),
    'command_timeout': (0.5, 's', 'a torque command older than this is replaced by 0 '
                        '(wall clock in realtime mode, sim time otherwise); 0 disables',
                        0.0, 3600.0, False, None),
    'max_catchup_steps': (10, '-', 'extra fixed steps a late realtime tick may take to catch '
                          'up before the loop skips ahead (an overrun)', 0, 1000, False, None),
    'publish_decimation': (1, '-', 'publish the states every N-th step (/clock: every step)',
                           1, 100000, False, None),
    'record': (True, '-', 'record commands and states to an MCAP file', None, None, False,
               None),
    'record_dir': ('runs', '-', 'directory of the MCAP recordings (start-up only: a '
                   'run-time change could point the writes anywhere)', None, None, True, None),
    'record_prefix': ('leadscrew', '-', 'file name prefix of the recordings: 1 to 64 '
                      'letters, digits, _ or -', None, None, False, None),
    'record_split_bytes': (0, 'B', f'start a new file after this many bytes; 0 never, else '
                           f'at least {MIN_SPLIT_BYTES}', 0, 2 ** 62, False, None),
    'record_split_seconds': (0.0, 's', f'start a new file after this long; 0 never, else at '
                             f'least {MIN_SPLIT_SECONDS:g} s', 0.0, 1e9, False, None),
    'record_flush_interval': (1.0, 's', 'flush the recording at least this often (bounds the '
                              'loss on a crash)', 0.0, 3600.0, False, None),
    'stats_file': ('', '-', 'if set, write timing statistics (JSON) to this path at shutdown '
                   '(start-up only)', None, None, True, None),
}

COMMAND_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
STATE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)

NS = 1_000_000_000

#: Largest |external_force| command [N] taken: the range of the parameter of the same name.
EXTERNAL_FORCE_LIMIT = ScrewParams.field_info()['external_force'][2]['hi']


class StartupError(Exception):
    """An invalid configuration found while the node starts (exit code 2)."""


# ---------------------------------------------------------------------------
# Timing
# ---------------------------------------------------------------------------

class _Timespec(ctypes.Structure):
    _fields_ = [('tv_sec', ctypes.c_long), ('tv_nsec', ctypes.c_long)]


class DeadlineSleeper:
    """
    Sleep until an absolute CLOCK_MONOTONIC deadline (clock_nanosleep, TIMER_ABSTIME).

    Also sets the thread's timer slack to 1 ns (prctl PR_SET_TIMERSLACK).
    Falls back to time.sleep if libc cannot be loaded.
    """

    CLOCK_MONOTONIC = 1
    TIMER_ABSTIME = 1
    PR_SET_TIMERSLACK = 29

    def __init__(self):
        """Load libc and lower the timer slack."""
        self._ts = _Timespec()
        self._fn = None
        try:
            libc = ctypes.CDLL(ctypes.util.find_library('c') or 'libc.so.6', use_errno=True)
            fn = libc.clock_nanosleep
            fn.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.POINTER(_Timespec),
                           ctypes.c_void_p]
            fn.restype = ctypes.c_int
            self._fn = fn
            self._ref = ctypes.byref(self._ts)
            libc.prctl(self.PR_SET_TIMERSLACK, ctypes.c_ulong(1), ctypes.c_ulong(0),
                       ctypes.c_ulong(0), ctypes.c_ulong(0))
        except (OSError, AttributeError):
            self._fn = None

    def sleep_until(self, deadline_ns):
        """Sleep until time.monotonic_ns() >= deadline_ns (may return early on a signal)."""
        if self._fn is None:
            delay = deadline_ns - time.monotonic_ns()
            if delay > 0:
                time.sleep(delay / NS)
            return
        self._ts.tv_sec, self._ts.tv_nsec = divmod(deadline_ns, NS)
        self._fn(self.CLOCK_MONOTONIC, self.TIMER_ABSTIME, self._ref, None)


def percentiles(values, qs=(50, 99)):
    """Return {'p50': .., 'p99': .., 'max': ..} of a sequence (nearest rank)."""
    if not values:
        return {f'p{q}': None for q in qs} | {'max': None}
    s = sorted(values)
    out = {f'p{q}': s[min(len(s) - 1, max(0, math.ceil(q / 100.0 * len(s)) - 1))] for q in qs}
    out['max'] = s[-1]
    return out


# ---------------------------------------------------------------------------
# Serialisation
# ---------------------------------------------------------------------------

#: std_msgs/Float64 CDR: encapsulation id (CDR / XCDR2, big / little endian) -> decoder
#: of the double at offset 4.
_F64_CDR = {b'\x00\x00': struct.Struct('>d'), b'\x00\x01': struct.Struct('<d'),
            b'\x00\x06': struct.Struct('>d'), b'\x00\x07': struct.Struct('<d')}


def float64_value(data):
    """
    Return the value of a serialized std_msgs/Float64 (raw subscription bytes).

    Decodes the CDR directly (about 1 us instead of 10 us for
    deserialize_message), falling back to rclpy for any other encapsulation.
    """
    codec = _F64_CDR.get(bytes(data[:2])) if len(data) >= 12 else None
    if codec is None:
        return deserialize_message(data, Float64).data
    return codec.unpack_from(data, 4)[0]


def stamp_msg(stamp_ns):
    """builtin_interfaces/Time of an integer nanosecond time."""
    sec, nsec = divmod(int(stamp_ns), NS)
    return TimeMsg(sec=sec, nanosec=nsec)


# ---------------------------------------------------------------------------
# Recording adapter
# ---------------------------------------------------------------------------

class Recorder:
    """
    Record through ``leadscrew_sim.recording.RecordingSession`` in a child process.

    MCAP writing costs ~50 us per message in Python and stalls for 10-15 ms
    when a chunk is compressed and indexed; inside the 1 kHz loop (or in a
    thread, through the GIL) that would make ticks late. The node therefore
    only appends framed bytes to a pipe (a few us per tick); the child
    process ``recorder_child`` owns the session. The child ends on EOF (also
    when the node is killed: the file is closed cleanly) and ignores SIGINT
    and SIGTERM so a Ctrl-C to the process group cannot cut a write short.
    Errors never raise into the simulation loop; they are kept in ``error``
    and shown in diagnostics.

    A metadata record with a ``log_time_ns`` key (reset, parameter update) also
    gets ``messages_at_log_time``: the number of messages with that log time
    recorded before it, so a reader can tell whether, e.g., a reset came before
    or after a command logged in the same tick (``leadscrew_sim resim``).
    """

    MAX_PENDING = 64 << 20          # bytes buffered in the node before dropping

    def __init__(self, logger):
        """Create an idle recorder."""
        self._log = logger
        self._proc = None
        self._fd = None
        self._buf = bytearray()
        self._channels = {}
        self._status = {}
        self._status_tail = b''
        self._finishing = []
        self.error = None
        self.dropped = 0
        self._at_time = None            # log time of the last message queued
        self._at_count = 0              # messages queued with that log time

    @property
    def active(self):
        """Return True while a recording is open."""
        return self._fd is not None

    def start(self, directory, prefix, split_bytes, split_seconds, flush_interval,
              channels, metadata):
        """Start a child with channels {topic: (type, qos yaml, trim)} and a metadata record."""
        self.stop(wait=False)
        self.error = None
        self._status = {}
        self.dropped = 0
        self._at_time, self._at_count = None, 0
        config = dict(directory=str(directory), prefix=prefix, split_bytes=int(split_bytes),
                      split_seconds=float(split_seconds),
                      flush_interval=float(flush_interval),
                      channels=[[t, typ, qos, trim] for t, (typ, qos, trim) in channels.items()],
                      metadata={'leadscrew_sim_parameters': metadata})
        try:
            import subprocess
            proc = subprocess.Popen(
                [sys.executable, '-c', 'from leadscrew_sim.ros.node import recorder_child; '
                 'recorder_child()'],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, close_fds=True)
        except OSError as exc:
            self._fail(f'cannot start the recorder process: {exc}')
            return False
        self._proc = proc
        self._fd = proc.stdin.fileno()
        try:
            import fcntl
            fcntl.fcntl(self._fd, 1031, 1 << 20)          # F_SETPIPE_SZ: 1 MiB
        except OSError:
            pass
        os.set_blocking(self._fd, False)
        os.set_blocking(proc.stdout.fileno(), False)
        self._channels = {t: i + 1 for i, t in enumerate(channels)}
        self._control({'op': 'open', **config})
        self.flush()
        return True

    def _control(self, obj):
        data = json.dumps(obj).encode()
        self._buf += _FRAME.pack(0, len(data), 0) + data

    def write(self, topic, data, log_time_ns):
        """Queue one serialized message (sent to the child on the next flush())."""
        if self._fd is None:
            return
        if len(self._buf) > self.MAX_PENDING:
            self.dropped += 1
            return
        self._buf += _FRAME.pack(self._channels[topic], len(data), log_time_ns)
        self._buf += data
        if log_time_ns == self._at_time:
            self._at_count += 1
        else:
            self._at_time, self._at_count = log_time_ns, 1

    def add_metadata(self, name, values):
        """Queue a metadata record (no-op when not recording)."""
        if self._fd is not None:
            data = {str(k): str(v) for k, v in values.items()}
            if 'log_time_ns' in values:
                same = int(values['log_time_ns']) == self._at_time
                data['messages_at_log_time'] = str(self._at_count if same else 0)
            self._control({'op': 'metadata', 'name': name, 'data': data})

    def flush(self):
        """Hand the queued bytes to the pipe without blocking (once per tick)."""
        if self._fd is None or not self._buf:
            return
        try:
            n = os.write(self._fd, self._buf)
        except BlockingIOError:
            return
        except OSError as exc:
            self._fail(f'recorder process gone: {exc}')
            return
        del self._buf[:n]

    def poll(self):
        """Read status lines from the child (non-blocking); call about once a second."""
        for proc in list(self._finishing):
            if proc.poll() is not None:
                self._finishing.remove(proc)
        proc = self._proc
        if proc is None:
            return
        try:
            chunk = os.read(proc.stdout.fileno(), 65536)
        except BlockingIOError:
            chunk = None
        except OSError:
            chunk = b''
        if chunk:
            lines = (self._status_tail + chunk).split(b'\n')
            self._status_tail = lines.pop()
            for line in lines:
                try:
                    self._status = json.loads(line)
                except ValueError:
                    pass
            if self._status.get('error') and not self.error:
                self.error = self._status['error']
                self._log.error(f'recording: {self.error}')
        if proc.poll() is not None and self._fd is not None:
            self._fail(f'recorder process exited with code {proc.returncode}')

    def stop(self, wait=True, timeout=20.0):
        """Close the recording: EOF to the child, which closes the file."""
        proc = self._proc
        if proc is None:
            return
        if self._fd is not None:
            os.set_blocking(self._fd, True)
            try:
                if self._buf:
                    proc.stdin.write(self._buf)
                proc.stdin.close()
            except OSError as exc:
                self.error = self.error or f'recorder process gone: {exc}'
            self._buf = bytearray()
            self._fd = None
        if wait:
            try:
                proc.wait(timeout=timeout)
                os.set_blocking(proc.stdout.fileno(), True)
                out = proc.stdout.read()
                proc.stdout.close()
                for line in (self._status_tail + (out or b'')).split(b'\n'):
                    try:
                        self._status = json.loads(line)
                    except ValueError:
                        pass
            except Exception:  # noqa: B902 - never raise at shutdown
                proc.kill()
            self._log.info(f'recording closed: {self._status.get("path")} '
                           f'({self._status.get("bytes")} B, '
                           f'{self._status.get("messages")} messages)')
            for other in self._finishing:
                try:
                    other.wait(timeout=timeout)
                except Exception:  # noqa: B902
                    other.kill()
            self._finishing = []
        else:
            self._finishing.append(proc)
        self._proc = None

    def status(self):
        """Return (file, bytes, messages, error) for diagnostics."""
        st = self._status
        return (str(st.get('path') or ''), int(st.get('bytes') or 0),
                int(st.get('messages') or 0), self.error or st.get('error'))

    def _fail(self, message):
        self.error = message
        self._log.error(message)
        self._fd = None
        self._buf = bytearray()
        proc, self._proc = self._proc, None
        if proc is not None:
            try:
                proc.stdin.close()
            except OSError:
                pass
            self._finishing.append(proc)


_FRAME = struct.Struct('<IIq')       # channel id (0: JSON control), length, log time [ns]
CHILD_BATCH_S = 0.01                  # the recorder child reads the pipe every 10 ms


def recorder_child():
    """Child process of Recorder: read frames from stdin, write the MCAP session."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    # Throughput work that must never delay the node's loop: SCHED_IDLE runs
    # only on otherwise idle CPU time and yields at once when the node wakes
    # (bench: tick lateness p99 90-280 us vs 450-640 us at nice 10). On a
    # saturated machine the pipe (1 MiB) and the node's buffer (MAX_PENDING,
    # minutes of data) absorb the backlog; beyond that, drops are counted.
    try:
        os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
    except (AttributeError, OSError):
        try:
            os.nice(10)
        except OSError:
            pass
    src, out = sys.stdin.buffer, sys.stdout
    session, ids, error = None, {}, None
    last = 0.0

    def report(final=False):
        st = dict(path=str(session.current_path or '') if session else '',
                  bytes=session.bytes_written if session else 0,
                  messages=session.messages_written if session else 0,
                  error=error or (session.error if session else None), final=final)
        out.write(json.dumps(st) + '\n')
        out.flush()

    buf = bytearray()
    while True:
        chunk = src.read1(1 << 20)
        if not chunk:
            break
        buf += chunk
        pos = 0
        while len(buf) - pos >= _FRAME.size:
            cid, n, t = _FRAME.unpack_from(buf, pos)
            if len(buf) - pos - _FRAME.size < n:
                break
            data = bytes(buf[pos + _FRAME.size:pos + _FRAME.size + n])
            pos += _FRAME.size + n
            try:
                if cid:
                    if session is not None:
                        session.write(ids[cid], data, t)
                    continue
                ctl = json.loads(data)
                if ctl['op'] == 'open':
                    from ..io.session import RecordingSession
                    session = RecordingSession(
                        ctl['directory'], prefix=ctl['prefix'],
                        split_bytes=ctl['split_bytes'], split_seconds=ctl['split_seconds'],
                        flush_interval=ctl['flush_interval'], metadata=ctl['metadata'])
                    for i, (topic, typ, qos, trim) in enumerate(ctl['channels']):
                        ids[i + 1] = session.add_channel(topic, typ, qos, trim)
                    report()
                elif ctl['op'] == 'metadata' and session is not None:
                    session.add_metadata(ctl['name'], ctl['data'])
            except Exception as exc:  # noqa: B902 - report, keep draining the pipe
                if error is None:
                    error = f'{type(exc).__name__}: {exc}'.replace('\n', ' ')
                    report()
                session_bad = session
                session = None
                if session_bad is not None:
                    try:
                        session_bad.close()
                    except Exception:  # noqa: B902
                        pass
        del buf[:pos]
        now = time.monotonic()
        if now - last > 0.5:
            last = now
            report()
        # Let a few ticks pile up in the pipe (1 MiB): one wake-up per
        # CHILD_BATCH_S instead of one per tick. Adds at most that much to the
        # loss when the child itself is killed (a killed node only ends the pipe).
        time.sleep(CHILD_BATCH_S)
    if session is not None:
        session.close()
    report(final=True)


# ---------------------------------------------------------------------------
# The node
# ---------------------------------------------------------------------------

def _coerce_node_param(name, value, default, lo, hi, choices):
    """Coerce and check a node (non-physics) parameter value; raise ParameterError."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ParameterError(name, f'{value!r} is not a boolean (true/false)')
    elif isinstance(default, int):
        if isinstance(value, bool) or not (
                isinstance(value, int) or (isinstance(value, float) and value.is_integer())):
            raise ParameterError(name, f'{value!r} is not an integer')
        value = int(value)
    elif isinstance(default, float):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParameterError(name, f'{value!r} is not a number')
        value = float(value)
        if not math.isfinite(value):
            raise ParameterError(name, f'{value!r} is not finite')
    elif isinstance(default, str):
        if not isinstance(value, str):
            raise ParameterError(name, f'{value!r} is not a string')
    if choices and value not in choices:
        raise ParameterError(name, f'{value!r} is not one of {", ".join(choices)}')
    if lo is not None and not lo <= value <= hi:
        raise ParameterError(name, f'{value!r} is outside the allowed range [{lo}, {hi}]')
    _check_node_param(name, value)
    return value


def _check_node_param(name, value):
    """Check the rules of a node parameter beyond its type and range."""
    shown = repr(value) if len(repr(value)) <= 80 else repr(value)[:77] + '...'
    if name == 'record_prefix' and not PREFIX_RE.match(value):
        raise ParameterError(name, f'{shown} must be 1 to 64 letters, digits, _ or - '
                             '(it starts the file names: no paths)')
    if name in ('record_dir', 'stats_file', 'joint_prefix') and any(
            ord(c) < 32 or ord(c) == 127 for c in value):
        raise ParameterError(name, f'{shown} contains control characters')
    if name == 'record_dir' and not value:
        raise ParameterError(name, 'must not be empty')
    if name == 'joint_prefix' and (len(value) > MAX_JOINT_PREFIX
                                   or any(c.isspace() for c in value)):
        raise ParameterError(name, f'{shown} must be at most {MAX_JOINT_PREFIX} characters '
                             'without spaces')
    if name == 'record_split_bytes' and 0 < value < MIN_SPLIT_BYTES:
        raise ParameterError(name, f'{value} B would start a new file every few messages: '
                             f'give 0 (never) or at least {MIN_SPLIT_BYTES} B')
    if name == 'record_split_seconds' and 0.0 < value < MIN_SPLIT_SECONDS:
        raise ParameterError(name, f'{value!r} s would start many files a second: give 0 '
                             f'(never) or at least {MIN_SPLIT_SECONDS:g} s')


def _descriptor(name, value, unit, desc, lo, hi, read_only, choices):
    text = desc if unit in ('-', '') else f'{desc} [{unit}]'
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


class LeadScrewSimNode(Node):
    """The simulated lead screw axis (see the module docstring)."""

    def __init__(self, **kwargs):
        """Declare and validate the parameters, build the model and the ROS interfaces."""
        super().__init__(NODE_NAME, **kwargs)
        self._running = True
        self._declare_all()
        self.dt_ns = int(round(NS / self.cfg['update_rate']))
        self._spin_budget_ns = max(100_000, self.dt_ns // 4)
        self.model = self._make_model()
        LeadScrewModel(self.params, dt=self.dt_ns / NS).advance(0.0)   # JIT warm-up
        self.mode = self.cfg['clock_mode']
        self.t0_ns = self.get_clock().now().nanoseconds if self.mode == 'realtime' else 0
        self.n = 0                         # steps taken; stamp = t0 + n dt

        # Commands (zero-order held) and counters.
        self.torque = 0.0
        self.force = 0.0
        self.cmd_time = None               # tick time of the last torque command [ns]
        self.cmd_wall = None               # monotonic time of the last torque command
        self.tick_time = 0                 # time base of command ages (see _now_for_age)
        self.stale = False
        self.rejected = 0                  # malformed or non-finite commands
        self.ignored = 0                   # joint_commands without our joint
        self.commands = 0
        self._warned_no_joint = False
        self._events = 0

        # Timing statistics.
        self.overruns = 0
        self.skipped_steps = 0
        self.late_ticks = 0
        self.catchup_steps = 0
        self._lateness = array.array('q')          # current diagnostics window
        self._lateness_all = array.array('q') if self.cfg['stats_file'] else None
        self._win_start = time.monotonic_ns()
        self._win_ticks = 0
        self.achieved_rate = 0.0
        self._run_start = None
        self._run_ticks = 0

        self.recorder = Recorder(self.get_logger())
        self._build_interfaces()
        self.add_on_set_parameters_callback(self._on_set_parameters)
        if self.cfg['record']:
            self._start_recording()
        p = self.params
        self.get_logger().info(
            f'preset {self.preset}: {p.thread_form} d={p.major_diameter * 1e3:g} mm '
            f'lead {p.lead * 1e3:g} mm {p.hand}-hand, '
            f'{"self-locking" if p.self_locking else "back-drivable"}; '
            f'{self.cfg["update_rate"]:g} Hz, {self.model.nsub} substeps/step, '
            f'clock_mode {self.mode}')

    def _make_model(self):
        """Build the model; a set needing too many substeps per step is a StartupError."""
        dt = self.dt_ns / NS
        try:
            return LeadScrewModel(self.params, dt=dt)
        except ParameterError as exc:
            p = self.params
            if p.substep > 0.0 and dt / p.substep > MAX_SUBSTEPS_PER_STEP:
                raise StartupError(
                    f"parameter 'substep': {p.substep:g} s gives "
                    f'{math.ceil(dt / p.substep)} substeps per {dt:g} s step (limit '
                    f'{MAX_SUBSTEPS_PER_STEP}); raise it (0: automatic) or update_rate'
                ) from None
            raise StartupError(f'{exc} (update_rate {self.cfg["update_rate"]:g} Hz)') from None

    # -- parameters --------------------------------------------------------
    def _override(self, name):
        ov = getattr(self, '_parameter_overrides', {}).get(name)
        return None if ov is None else ov.value

    def _declare_all(self):
        preset = self._override('preset')
        if preset is None:
            preset = DEFAULT_PRESET
        if not isinstance(preset, str):
            raise StartupError(f"parameter 'preset': {preset!r} is not a string")
        try:
            base = load_preset(preset)
        except ParameterError as exc:
            raise StartupError(str(exc)) from None
        except (OSError, ValueError) as exc:
            raise StartupError(f"parameter 'preset': cannot read {preset!r}: {exc}") from None
        self.preset = preset
        self.declare_parameter('preset', preset, ParameterDescriptor(
            name='preset', read_only=True,
            description='preset name (config/<name>.yaml) or YAML path giving the defaults '
                        'of the physical parameters'), ignore_override=True)

        info = ScrewParams.field_info()
        overrides = {}
        for name in info:
            v = self._override(name)
            if v is not None:
                overrides[name] = v
        try:
            self.params = ScrewParams.from_dict(overrides, base=base)
        except ParameterError as exc:
            raise StartupError(str(exc)) from None
        for name, (_typ, _default, md) in info.items():
            value = getattr(self.params, name)
            desc = _descriptor(name, value, md['unit'], md['description'], md['lo'], md['hi'],
                               name in READ_ONLY_PHYSICS, md.get('choices'))
            self.declare_parameter(name, value, desc, ignore_override=True)

        self.cfg = {}
        for name, (default, unit, desc, lo, hi, ro, choices) in NODE_PARAMETERS.items():
            value = self._override(name)
            value = default if value is None else value
            try:
                value = _coerce_node_param(name, value, default, lo, hi, choices)
            except ParameterError as exc:
                raise StartupError(str(exc)) from None
            self.cfg[name] = value
            self.declare_parameter(
                name, value, _descriptor(name, value, unit, desc, lo, hi, ro, choices),
                ignore_override=True)
        known = set(info) | set(NODE_PARAMETERS) | {
            'preset', 'use_sim_time', 'start_type_description_service'}
        for name in getattr(self, '_parameter_overrides', {}):
            if name not in known:
                self.get_logger().warn(f"ignoring unknown parameter '{name}'")

    def all_parameter_values(self):
        """Return {name: str(value)} of every parameter plus the run settings."""
        values = {name: str(getattr(self.params, name)) for name in ScrewParams.field_info()}
        values.update({name: str(v) for name, v in self.cfg.items()})
        values.update(preset=self.preset, update_rate=str(self.cfg['update_rate']),
                      clock_mode=self.mode, dt_ns=str(self.dt_ns), t0_ns=str(self.t0_ns),
                      command_log_time='a command logged at t acts on the step [t, t + dt)')
        return values

    def _on_set_parameters(self, parameters):
        physics, node = {}, {}
        info = ScrewParams.field_info()
        for p in parameters:
            if p.name in info:
                physics[p.name] = p.value
            elif p.name in NODE_PARAMETERS:
                node[p.name] = p.value
        try:
            new_params = ScrewParams.from_dict(physics, base=self.params) if physics else None
            new_cfg = {}
            for name, value in node.items():
                default, _u, _d, lo, hi, _ro, choices = NODE_PARAMETERS[name]
                new_cfg[name] = _coerce_node_param(name, value, default, lo, hi, choices)
            if new_params is not None:
                self.model.set_params(new_params)
        except ParameterError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        if new_params is not None:
            self.params = new_params
            self.recorder.add_metadata('leadscrew_sim_parameters_update', dict(
                {k: str(v) for k, v in physics.items()}, log_time_ns=str(self._sim_now())))
        if new_cfg:
            self._apply_cfg(new_cfg)
        return SetParametersResult(successful=True)

    def _apply_cfg(self, new_cfg):
        old = dict(self.cfg)
        self.cfg.update(new_cfg)
        if new_cfg.get('joint_prefix', old['joint_prefix']) != old['joint_prefix']:
            self._make_serializers()
        if 'real_time_factor' in new_cfg:
            self._pace_reset = True
        if 'record' in new_cfg and new_cfg['record'] != old['record']:
            if new_cfg['record']:
                self._start_recording()
            else:
                self.recorder.stop(wait=False)

    # -- ROS interfaces ------------------------------------------------------
    def _build_interfaces(self):
        self._pub_js = self.create_publisher(JointState, 'joint_states', STATE_QOS)
        self._pub_x = self.create_publisher(Float64, 'nut_position', STATE_QOS)
        self._pub_wr = self.create_publisher(WrenchStamped, 'thread_force', STATE_QOS)
        self._pub_diag = self.create_publisher(DiagnosticArray, 'diagnostics', 10)
        self._pub_clock = None
        if self.mode != 'realtime':
            self._pub_clock = self.create_publisher(Clock, '/clock', 10)
        self.create_subscription(Float64, 'torque_command', self._on_torque, COMMAND_QOS,
                                 raw=True)
        self.create_subscription(JointState, 'joint_commands', self._on_joint_commands,
                                 COMMAND_QOS, raw=True)
        self.create_subscription(Float64, 'external_force', self._on_force, COMMAND_QOS,
                                 raw=True)
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.create_service(SetBool, '~/record', self._on_record)
        self._topic = {name: pub.topic_name for name, pub in (
            ('js', self._pub_js), ('x', self._pub_x), ('wr', self._pub_wr),
            ('clock', self._pub_clock)) if pub is not None}
        self._make_serializers()
        self._pace_reset = True

    def _make_serializers(self):
        enc = StateEncoder(self.cfg['joint_prefix'])
        self._ser_js = enc.joint_states
        self._ser_x = enc.nut_position
        self._ser_wr = enc.thread_force
        self._ser_clock = enc.clock

    def recording_channels(self):
        """
        Return {resolved topic: (type name, offered QoS yaml, trim)} of the recorded topics.

        ``trim``: the recorder cuts bytes past the CDR end (commands as received);
        the states are our exact encodings and need no check.
        """
        chans = {}
        items = [(sub.topic_name, sub.msg_type, True) for sub in self.subscriptions]
        items += [(pub.topic_name, pub.msg_type, False) for pub in (
            self._pub_js, self._pub_x, self._pub_wr, self._pub_clock) if pub is not None]
        for topic, msg_type, trim in items:
            name = f'{msg_type.__module__.split(".")[0]}/msg/{msg_type.__name__}'
            chans[topic] = (name, None, trim)   # recorder default: reliable, keep last 10
        return chans

    def _start_recording(self):
        c = self.cfg
        ok = self.recorder.start(c['record_dir'], c['record_prefix'], c['record_split_bytes'],
                                 c['record_split_seconds'], c['record_flush_interval'],
                                 self.recording_channels(), self.all_parameter_values())
        return ok

    # -- command callbacks -----------------------------------------------------
    def _sim_now(self):
        return self.t0_ns + self.n * self.dt_ns

    def _reject(self, what):
        self.rejected += 1
        self.get_logger().warn(f'rejected {what} ({self.rejected} so far)',
                               throttle_duration_sec=1.0)

    def _record_cmd(self, topic, data):
        if self.recorder.active:
            self.recorder.write(topic, data, self._sim_now())

    def _set_torque(self, value):
        self.torque = value
        # lockstep: the command arrives before its tick, at the current sim time
        self.cmd_time = self._sim_now() if self.mode == 'lockstep' else self.tick_time
        self.cmd_wall = time.monotonic_ns()
        self.commands += 1
        if self.stale:
            self.stale = False
            self.get_logger().info('torque command resumed')

    def _on_torque(self, data):
        self._events += 1
        self._record_cmd(self._topic_name('torque_command'), data)
        value = float64_value(data)
        if math.isfinite(value):
            self._set_torque(value)
        else:
            self._reject(f'non-finite torque_command {value!r}')
        if self.mode == 'lockstep':
            self._lockstep_tick()

    def _on_joint_commands(self, data):
        self._events += 1
        self._record_cmd(self._topic_name('joint_commands'), data)
        msg = deserialize_message(data, JointState)
        joint = self.cfg['joint_prefix'] + 'screw_joint'
        count = msg.name.count(joint)
        if count == 0:
            self.ignored += 1
            if not self._warned_no_joint:
                self._warned_no_joint = True
                self.get_logger().warn(f'joint_commands without joint {joint!r} ignored '
                                       f'(names {list(msg.name)[:8]}); warning once')
        elif count > 1:
            self._reject(f'joint_commands naming {joint!r} {count} times')
        elif len(msg.effort) != len(msg.name):
            self._reject(f'joint_commands with {len(msg.effort)} efforts for '
                         f'{len(msg.name)} names')
        else:
            value = float(msg.effort[msg.name.index(joint)])
            if math.isfinite(value):
                self._set_torque(value)
            else:
                self._reject(f'non-finite joint_commands effort {value!r}')
        if self.mode == 'lockstep':
            self._lockstep_tick()

    def _on_force(self, data):
        self._events += 1
        self._record_cmd(self._topic_name('external_force'), data)
        value = float64_value(data)
        if abs(value) <= EXTERNAL_FORCE_LIMIT:
            self.force = value
        else:
            # A finite but huge force (1e308 N) would drive the state to Inf and
            # stop the integration: refuse what the parameter range refuses.
            self._reject(f'external_force {value!r} N outside '
                         f'[-{EXTERNAL_FORCE_LIMIT:g}, {EXTERNAL_FORCE_LIMIT:g}] N')

    def _topic_name(self, rel):
        cache = self.__dict__.setdefault('_topic_names', {})
        name = cache.get(rel)
        if name is None:
            name = self.resolve_topic_name(rel)
            cache[rel] = name
        return name

    def _on_reset(self, _request, response):
        self.model.reset()
        self.torque = 0.0
        self.force = 0.0
        self.cmd_time = self.cmd_wall = None
        self.stale = False
        self.recorder.add_metadata('leadscrew_sim_reset', {'log_time_ns': self._sim_now()})
        response.success = True
        response.message = f'reset to the initial state at sim time {self._sim_now()} ns'
        self.get_logger().info(response.message)
        return response

    def _on_record(self, request, response):
        result = self.set_parameters([rclpy.parameter.Parameter('record', value=request.data)])
        ok = result[0].successful
        file, _size, _n, err = self.recorder.status()
        response.success = bool(ok and (self.recorder.active == request.data))
        response.message = (f'recording to {file}' if self.recorder.active
                            else (err or 'recording stopped'))
        return response

    # -- stepping ----------------------------------------------------------------
    def _step(self, age_now):
        """Advance one fixed step and publish; age_now is the time base of command ages."""
        model = self.model
        if model.fault:
            return
        torque = self.torque
        timeout = self.cfg['command_timeout']
        if self.cmd_time is not None and timeout > 0.0 and (
                age_now - self.cmd_time) > timeout * NS:
            torque = 0.0
            if not self.stale:
                self.stale = True
                self.get_logger().warn(
                    f'torque command older than command_timeout {timeout:g} s: applying 0 N m')
            else:
                self.get_logger().warn('torque command stale: applying 0 N m',
                                       throttle_duration_sec=5.0)
        try:
            model.advance(torque, None, self.force)
        except FloatingPointError as exc:
            self.get_logger().error(f'simulation fault, integration stopped: {exc}; '
                                    'call ~/reset to restart')
            return
        self.n += 1
        if self.n % self.cfg['publish_decimation'] == 0:
            self._publish_states()
        if self._pub_clock is not None:
            data = self._ser_clock(self._sim_now(), ())
            self._pub_clock.publish(data)
            self._record_state('clock', data)

    def _publish_states(self):
        angle, x, omega, v, torque, force, thread_torque = self.model.joint_values()
        stamp = self._sim_now()
        data = self._ser_js(stamp, (angle, x, omega, v, torque, force))
        self._pub_js.publish(data)
        self._record_state('js', data)
        data = self._ser_x(None, (x,))
        self._pub_x.publish(data)
        self._record_state('x', data)
        data = self._ser_wr(stamp, (force, thread_torque))
        self._pub_wr.publish(data)
        self._record_state('wr', data)

    def _record_state(self, key, data):
        if self.recorder.active:
            self.recorder.write(self._topic[key], data, self._sim_now())

    def _lockstep_tick(self):
        self.tick_time = self._sim_now()
        self._step(self.tick_time)
        self._count_tick(1)
        self.recorder.flush()

    def _count_tick(self, steps):
        self._win_ticks += steps
        self._run_ticks += steps

    # -- main loops ------------------------------------------------------------------
    def stop(self):
        """Ask the main loop to finish (signal-safe)."""
        self._running = False

    def run(self, executor):
        """Run the clock mode's main loop until stop()."""
        self._executor = executor
        self._run_start = time.monotonic_ns()
        self._next_diag = self._run_start + NS
        getattr(self, f'_run_{self.mode}')()
        self._run_end = time.monotonic_ns()

    def _spin(self):
        """
        Process the pending events: one spin_once, again while commands keep coming.

        At most 16 events and about a quarter of a period per tick: a command
        flood (tens of thousands per second from another process) then delays
        commands (the latest one wins anyway) instead of starving the loop.
        """
        ex = self._executor
        end = time.monotonic_ns() + self._spin_budget_ns
        for _ in range(16):
            before = self._events
            ex.spin_once(timeout_sec=0)
            if self._events == before or time.monotonic_ns() >= end:
                break

    def _run_realtime(self):
        period = self.dt_ns
        sleeper = DeadlineSleeper()
        deadline = time.monotonic_ns() + period
        while self._running:
            sleeper.sleep_until(deadline)
            now = time.monotonic_ns()
            if now < deadline:
                continue                    # woken early by a signal
            late = now - deadline
            self._lateness.append(late)
            if self._lateness_all is not None:
                self._lateness_all.append(late)
            self.tick_time = deadline
            self._spin()
            due = 1 + late // period
            steps = min(due, 1 + self.cfg['max_catchup_steps'])
            for i in range(steps):
                self._step(deadline + i * period)
            if due > 1:
                self.late_ticks += 1
                self.catchup_steps += steps - 1
            if due > steps:
                self.overruns += 1
                self.skipped_steps += due - steps
            deadline += due * period
            self._count_tick(steps)
            self.recorder.flush()
            if now >= self._next_diag:
                self._publish_diagnostics(now)

    def _run_stepped(self):
        sleeper = DeadlineSleeper()
        deadline = 0
        while self._running:
            rtf = self.cfg['real_time_factor']
            if rtf > 0.0:
                period = int(round(self.dt_ns / rtf))
                if self._pace_reset:
                    deadline = time.monotonic_ns()
                    self._pace_reset = False
                deadline += period
                sleeper.sleep_until(deadline)
            self.tick_time = self._sim_now()
            self._spin()
            self._step(self.tick_time)
            self._count_tick(1)
            self.recorder.flush()
            now = time.monotonic_ns()
            if now >= self._next_diag:
                self._publish_diagnostics(now)

    def _run_lockstep(self):
        ex = self._executor
        self._pub_clock.publish(self._ser_clock(self._sim_now(), ()))
        while self._running:
            ex.spin_once(timeout_sec=0.05)
            now = time.monotonic_ns()
            if now >= self._next_diag:
                self._publish_diagnostics(now)
                self._pub_clock.publish(self._ser_clock(self._sim_now(), ()))

    # -- diagnostics ------------------------------------------------------------------
    def timing_stats(self):
        """Return the timing statistics of the run so far (lateness in ns)."""
        end = getattr(self, '_run_end', None) or time.monotonic_ns()
        elapsed = (end - self._run_start) / NS if self._run_start else 0.0
        lat = self._lateness_all if self._lateness_all is not None else self._lateness
        pct = percentiles(lat)
        return dict(
            clock_mode=self.mode, update_rate=self.cfg['update_rate'], steps=self.n,
            ticks=self._run_ticks, elapsed_s=elapsed,
            achieved_rate=self._run_ticks / elapsed if elapsed > 0 else 0.0,
            lateness_p50_ns=pct['p50'], lateness_p99_ns=pct['p99'],
            lateness_max_ns=pct['max'], lateness_samples=len(lat),
            overruns=self.overruns, skipped_steps=self.skipped_steps,
            late_ticks=self.late_ticks, catchup_steps=self.catchup_steps,
            rejected_commands=self.rejected, ignored_commands=self.ignored,
            commands=self.commands,
            fault=self.model.fault)

    def _publish_diagnostics(self, now):
        window = (now - self._win_start) / NS
        self.achieved_rate = self._win_ticks / window if window > 0 else 0.0
        pct = percentiles(self._lateness)
        self._lateness = array.array('q')
        self._win_start, self._win_ticks = now, 0
        self._next_diag = now + NS
        p, m = self.params, self.model
        o = m.output()
        if self.cmd_wall is None:
            age = 'no command yet'
        elif self.mode == 'realtime':
            age = f'{(now - self.cmd_wall) / NS:.3f}'
        else:
            age = f'{(self._sim_now() - self.cmd_time) / NS:.3f}'
        self.recorder.poll()
        rec_file, rec_bytes, rec_msgs, rec_err = self.recorder.status()
        eff = geometry.efficiency(p.mu_k * p.thread_factor, p.lead_angle)
        level, msg = DiagnosticStatus.OK, 'running'
        if self.stale:
            level, msg = DiagnosticStatus.WARN, 'torque command stale: applying 0 N m'
        if rec_err:
            level, msg = DiagnosticStatus.WARN, f'recording: {rec_err}'
        if m.fault:
            level, msg = DiagnosticStatus.ERROR, f'simulation fault: {m.fault}'
        values = [
            ('contact', o.contact_name), ('thread', 'stick' if o.stuck else 'slip'),
            ('self_locking', str(p.self_locking)), ('efficiency', f'{eff:.4f}'),
            ('nut_position_m', f'{o.nut_position:.6f}'),
            ('applied_torque_Nm', f'{o.motor_torque:.6g}'),
            ('axial_force_N', f'{o.axial_force:.6g}'),
            ('command_age_s', age), ('command_stale', str(self.stale)),
            ('clock_mode', self.mode), ('sim_time_s', f'{self._sim_now() / NS:.6f}'),
            ('achieved_rate_hz', f'{self.achieved_rate:.2f}'),
            ('target_rate_hz', f'{self.cfg["update_rate"]:g}'),
            ('lateness_p50_us', _us(pct['p50'])), ('lateness_p99_us', _us(pct['p99'])),
            ('lateness_max_us', _us(pct['max'])),
            ('overruns', str(self.overruns)), ('skipped_steps', str(self.skipped_steps)),
            ('late_ticks', str(self.late_ticks)), ('catchup_steps', str(self.catchup_steps)),
            ('commands', str(self.commands)), ('rejected_commands', str(self.rejected)),
            ('ignored_commands', str(self.ignored)),
            ('substeps', str(m.nsub)),
            ('recording', str(self.recorder.active)), ('recording_file', rec_file),
            ('recording_bytes', str(rec_bytes)), ('recording_messages', str(rec_msgs)),
            ('recording_error', rec_err or ''),
            ('recording_dropped', str(self.recorder.dropped)),
        ]
        status = DiagnosticStatus(level=level, name=f'{self.get_name()}: lead screw axis',
                                  message=msg, hardware_id=f'leadscrew_sim/{self.preset}',
                                  values=[KeyValue(key=k, value=v) for k, v in values])
        arr = DiagnosticArray(status=[status])
        arr.header.stamp = stamp_msg(self._sim_now())
        self._pub_diag.publish(serialize_message(arr))

    def close(self):
        """Write the stats file, close the recorder."""
        path = self.cfg.get('stats_file')
        if path and self._run_start:
            try:
                with open(path, 'w') as fh:
                    json.dump(self.timing_stats(), fh, indent=1)
            except OSError as exc:
                self.get_logger().error(f'cannot write stats_file {path!r}: {exc}')
        self.recorder.stop()


def _us(ns):
    return '' if ns is None else f'{ns / 1000.0:.1f}'


def make_executor(context=None):
    """Return an EventsExecutor, or a SingleThreadedExecutor if it is unavailable."""
    try:
        from rclpy.experimental import EventsExecutor
        return EventsExecutor(context=context)
    except (ImportError, AttributeError, RuntimeError):
        return SingleThreadedExecutor(context=context)


def main(args=None):
    """Run the node until SIGINT/SIGTERM; return the exit code (2: bad parameters)."""
    from rclpy.signals import SignalHandlerOptions
    argv = sys.argv if args is None else args
    try:
        rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # noqa: B902 - bad --ros-args
        print(f'{NODE_NAME}: error: {exc}', file=sys.stderr)
        return 2
    node = None
    stop_early = []

    def on_signal(_signum, _frame):
        if node is not None:
            node.stop()
        stop_early.append(True)

    # Before the node exists: a Ctrl-C during start-up (numba, DDS discovery
    # can take seconds) ends the node cleanly instead of with a traceback.
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        try:
            node = LeadScrewSimNode()
        except StartupError as exc:
            print(f'{NODE_NAME}: error: {exc}', file=sys.stderr, flush=True)
            return 2
        except (rclpy.exceptions.InvalidParameterValueException,
                rclpy.exceptions.InvalidParameterTypeException,
                rclpy.exceptions.ParameterException) as exc:
            print(f'{NODE_NAME}: error: {exc}', file=sys.stderr, flush=True)
            return 2
        if stop_early:
            node.stop()
        executor = make_executor()
        executor.add_node(node)
        node.run(executor)
        node.close()
        node.get_logger().info(f'stopped after {node.n} steps')
        return 0
    finally:
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()


if __name__ == '__main__':
    sys.exit(main())
