r"""
Soak the node: realtime 1 kHz, position mode, noisy late sensors, injected faults, split files.

Run (not in CI; about an hour and 1.2 GB of recordings in a new /tmp/soak_* directory):

    AMENT_PREFIX_PATH=.venv ROS_DOMAIN_ID=151 \
        .venv/bin/python bench/soak.py --duration 3600 --split 300 --fault-period 180

(ROS_DOMAIN_ID 77 if unset; discovery is limited to this host.) The node (preset
tr12x3) runs in realtime mode, recording with a file split every ``--split``
seconds and ``record_max_total_bytes`` from ``--max-total-bytes`` (default 4 GiB:
an hour of this soak records more than the node's default 1 GiB, whose pruning
would delete the first files), with sensors that are not ideal: a 65536-count
motor encoder with noise, a 1 um linear scale with noise, axis/joint_states 2 ticks
late and commands acting 1 tick late. Its position loop closes on the linear
scale (``drive_feedback`` linear_scale; the velocity loop stays on the encoder):
with the default motor encoder feedback a frozen encoder makes the drive run the
nut into an end stop, where the self-locking tr12x3 jams for the rest of the run
(a torque-limit trip does not stop a falling load in time).

This script's monitor node:

- publishes ``position_command`` at 50 Hz: a sine of a quarter of the preset's
  stroke (peak to peak) around its middle, period 30 s;
- from the end of the warm-up on, every ``--fault-period`` seconds turns one
  injected fault on through ``/leadscrew_sim_node/set_parameters`` (in turn
  fault.encoder_freeze, fault.state_drop_rate 0.1, fault.command_drop_rate 0.2,
  fault.motor_torque_scale 0.5, fault.drive_fault), off again after 20 s (at most
  half the period), then calls ``~/clear_fault`` (it clears what a fault latched:
  the injected drive fault, or any other); a fault is only started if it ends at
  least 10 s before the end of the run;
- reads ``diagnostics`` and samples the RSS of the node and of its recorder
  child.

At the end it stops the commands, waits until the node has taken the last of
them, stops the node (SIGINT), reads the summaries of the files and prints one
line each: ticks taken (the node's "stopped after N steps") against
the sim/joint_states (truth, every tick) and axis/joint_states (sensor: less the samples
lost to fault.state_drop_rate and the state_delay samples still under way at
exit) in the files, position commands sent, received and recorded, late ticks and
overruns from diagnostics and whether every skipped step was reported (the
sim-time lag behind the wall clock must grow by exactly the skipped steps), the
RSS growth after warm-up, the files' bytes against ``record_max_total_bytes``,
the faults set / acknowledged / cleared, and any recording error. The same
figures go to ``soak_summary.json`` next to the recordings.
"""
import argparse
import json
import math
import os
import re
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time

NODE = '/leadscrew_sim_node'
NS = 1_000_000_000

#: The node's sensors and drive protection during the soak (ROS parameter assignments).
SENSORS = ('encoder_counts:=65536', 'encoder_noise:=2.0e-5', 'linear_scale:=true',
           'scale_resolution:=1.0e-6', 'scale_noise:=5.0e-7', 'state_delay:=2',
           'command_delay:=1', 'sensor_seed:=7', 'drive_feedback:=linear_scale')

#: The injected faults in turn: (parameter, value while on, value when off).
FAULTS = (('fault.encoder_freeze', True, False),
          ('fault.state_drop_rate', 0.1, 0.0),
          ('fault.command_drop_rate', 0.2, 0.0),
          ('fault.motor_torque_scale', 0.5, 1.0),
          ('fault.drive_fault', True, False))

COMMAND_RATE = 50.0         # position_command rate [Hz]
PROFILE_PERIOD = 30.0       # period of the sine [s]
FAULT_ON = 20.0             # how long a fault stays on [s] (at most half the period)
END_MARGIN = 10.0           # a fault ends at least this long before the end of the run [s]
LAG_SAMPLES = 20            # least diagnostics messages of each lag baseline (first, last)
LAG_TOLERANCE_MS = 3.0      # lag change that transit and tick phase explain [ms]


def rss_kib(pid):
    """Return the resident set size of a process [KiB]."""
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1])
    return 0


def child_rss_kib(pid):
    """Return the summed RSS of a process's children (the recorder) [KiB]."""
    total = 0
    for task in Path(f'/proc/{pid}/task').glob('*'):
        try:
            kids = [int(c) for c in (task / 'children').read_text().split()]
        except OSError:
            continue
        total += sum(rss_kib(k) for k in kids)
    return total


def growth(first, last):
    """Return the growth from first to last [%], or None."""
    return 100.0 * (last - first) / first if first else None


def profile(stroke_min, stroke_max):
    """Return x(t): the nut position target [m] at t [s] after the first command."""
    mid, amp = 0.5 * (stroke_min + stroke_max), 0.125 * (stroke_max - stroke_min)
    return lambda t: mid + amp * math.sin(2.0 * math.pi * t / PROFILE_PERIOD)


def file_counts(files):
    """Return ({topic: messages} summed over the files' summaries, [files without one])."""
    from mcap.reader import make_reader
    counts, bad = {}, []
    for f in files:
        try:
            with open(f, 'rb') as fh:
                summary = make_reader(fh).get_summary()
        except Exception:  # noqa: B902 - any damage: reported as no summary
            summary = None
        if summary is None or summary.statistics is None:
            bad.append(f.name)
            continue
        topic = {c.id: c.topic.lstrip('/') for c in summary.channels.values()}
        for cid, n in summary.statistics.channel_message_counts.items():
            counts[topic[cid]] = counts.get(topic[cid], 0) + n
    return counts, bad


class Monitor:
    """The soak's ROS side: command profile, fault schedule, diagnostics and RSS samples."""

    def __init__(self, node_proc, target):
        """Create the monitor node, its publisher, subscription and clients."""
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rcl_interfaces.srv import GetParameters, SetParameters
        from rclpy.executors import SingleThreadedExecutor
        from std_msgs.msg import Float64
        from std_srvs.srv import Trigger
        self.Float64, self.Trigger = Float64, Trigger
        self.GetParameters, self.SetParameters = GetParameters, SetParameters
        self.proc, self.target = node_proc, target
        self.node = rclpy.create_node('soak_monitor')
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.pub = self.node.create_publisher(Float64, 'position_command', 10)
        self.node.create_subscription(DiagnosticArray, 'diagnostics', self.on_diag, 10)
        self.set_cli = self.node.create_client(SetParameters, f'{NODE}/set_parameters')
        self.get_cli = self.node.create_client(GetParameters, f'{NODE}/get_parameters')
        self.clear_cli = self.node.create_client(Trigger, f'{NODE}/clear_fault')
        self.diag, self.n_diag, self.n_run = {}, 0, 0
        self.received = []              # commands taken + dropped, per diagnostics message
        self.lags = []                  # (wall time - stamp [ns], skipped steps) per message
        self.worst_max_us = 0.0
        self.warm = None                # diagnostics values at the end of the warm-up
        self.worst_after_us = 0.0       # largest window max lateness after the warm-up [us]
        self.min_rate = math.inf
        self.position_diags = 0
        self.quiet_ferr = 0.0           # largest |following error| outside fault windows [rad]
        self.quiet_since = None         # monotonic time since when no fault is active
        self.faults = []                # one dict per injected fault
        self.sent = 0
        self.t_cmd0 = None
        self.timer = None

    def on_diag(self, msg):
        """Keep the latest values and the figures accumulated over the run."""
        wall = time.time_ns()
        values = {}
        for status in msg.status:
            values.update({kv.key: kv.value for kv in status.values})
        self.diag, self.n_diag = values, self.n_diag + 1
        if values.get('lateness_max_us'):
            self.worst_max_us = max(self.worst_max_us, float(values['lateness_max_us']))
            if self.warm is not None:
                self.worst_after_us = max(self.worst_after_us, float(values['lateness_max_us']))
        if self.t_cmd0 is not None:
            self.n_run += 1
            stamp = msg.header.stamp.sec * NS + msg.header.stamp.nanosec
            self.lags.append((wall - stamp, int(values.get('skipped_steps', 0))))
            self.received.append(int(values.get('commands', 0))
                                 + int(values.get('dropped_commands', 0)))
            if values.get('achieved_rate_hz'):
                self.min_rate = min(self.min_rate, float(values['achieved_rate_hz']))
        active, state = values.get('active_faults', ''), values.get('drive_state', '')
        quiet = active == 'none' and state == 'enabled'
        now = time.monotonic()
        if not quiet:
            self.quiet_since = None
        elif self.quiet_since is None:
            self.quiet_since = now
        if self.t_cmd0 is not None:
            self.position_diags += values.get('drive_mode') == 'position'
            if quiet and now - self.quiet_since > 3.0 and values.get('following_error_rad'):
                self.quiet_ferr = max(self.quiet_ferr, abs(float(values['following_error_rad'])))
        for f in self.faults:
            if f['phase'] == 'on' and f['name'] in active:
                f['seen_in_diagnostics'] = True
            if f['phase'] == 'cleared' and quiet:
                f['phase'] = 'done'
                f['back_to_normal_in_diagnostics'] = True
            if f['phase'] in ('on', 'off') and state.startswith('fault: '):
                f.setdefault('latched', state[len('fault: '):])

    # -- ROS helpers --------------------------------------------------------------
    def spin_until(self, pred, timeout):
        """Spin until pred() or the timeout [s]; return pred()."""
        end = time.monotonic() + timeout
        while not pred() and time.monotonic() < end and self.proc.poll() is None:
            self.executor.spin_once(timeout_sec=0.05)
        return pred()

    def spin_for(self, seconds):
        """Spin for a while."""
        self.spin_until(lambda: False, seconds)

    def call(self, cli, request, timeout=10.0):
        """Call a service and wait for its answer (None: no answer)."""
        if not self.spin_until(cli.service_is_ready, timeout):
            return None
        fut = cli.call_async(request)
        return fut.result() if self.spin_until(fut.done, timeout) else None

    def get_params(self, names):
        """Return {name: value} of the node's parameters (None: not answered)."""
        from rclpy.parameter import parameter_value_to_python
        res = self.call(self.get_cli, self.GetParameters.Request(names=list(names)))
        if res is None:
            return None
        return {n: parameter_value_to_python(v) for n, v in zip(names, res.values)}

    def set_param(self, name, value, done):
        """Set one parameter asynchronously; done(successful, reason) on the answer."""
        from rclpy.parameter import Parameter
        req = self.SetParameters.Request(
            parameters=[Parameter(name, value=value).to_parameter_msg()])
        fut = self.set_cli.call_async(req)
        fut.add_done_callback(lambda f: done(f.result().results[0].successful,
                                             f.result().results[0].reason))

    # -- the run ------------------------------------------------------------------------
    def start_commands(self):
        """Start the 50 Hz position command timer."""
        self.t_cmd0 = time.monotonic()
        self.timer = self.node.create_timer(1.0 / COMMAND_RATE, self.publish)

    def publish(self):
        """Publish the profile's position now."""
        self.pub.publish(self.Float64(data=float(self.target(time.monotonic() - self.t_cmd0))))
        self.sent += 1

    def inject(self, k, now):
        """Turn the k-th fault of the run on."""
        name, on, _off = FAULTS[k % len(FAULTS)]
        f = dict(name=name, value=on, t_on_s=round(now, 1), phase='on', set=None,
                 seen_in_diagnostics=False, off_set=None, clear=None,
                 back_to_normal_in_diagnostics=False)
        self.faults.append(f)

        def done(ok, reason):
            f['set'] = ok
            if not ok:
                f['set_reason'] = reason
        self.set_param(name, on, done)

    def release(self, f, now):
        """Turn a fault off again, then call ~/clear_fault."""
        name, _on, off = next(x for x in FAULTS if x[0] == f['name'])
        f['phase'], f['t_off_s'] = 'off', round(now, 1)

        def cleared(fut):
            r = fut.result()
            f['clear'] = bool(r.success)
            f['clear_message'] = r.message
            f['phase'] = 'cleared'

        def done(ok, reason):
            f['off_set'] = ok
            if not ok:
                f['off_reason'] = reason
            self.clear_cli.call_async(self.Trigger.Request()).add_done_callback(cleared)
        self.set_param(name, off, done)


def fault_figures(faults):
    """Return the fault counters of the summary."""
    latched = {}
    for f in faults:
        m = re.match(r'cleared the (\w+) fault', f.get('clear_message') or '')
        if m:
            latched[m.group(1)] = latched.get(m.group(1), 0) + 1
    return dict(
        injected=len(faults), set_acknowledged=sum(f['set'] is True for f in faults),
        seen_in_diagnostics=sum(f['seen_in_diagnostics'] for f in faults),
        turned_off=sum(f['off_set'] is True for f in faults),
        clear_fault_calls=sum(f['clear'] is not None for f in faults),
        clear_fault_ok=sum(f['clear'] is True for f in faults),
        latched_faults_cleared=latched,
        back_to_normal=sum(f['back_to_normal_in_diagnostics'] for f in faults))


def lag_check(lags, dt_ns):
    """
    Return (change [ms], skipped steps over the same span) of the sim-time lag.

    The stamp of a diagnostics message is t0 + n dt (n steps taken); the realtime
    loop's deadlines advance by n + skipped periods, so (wall - stamp) - skipped dt
    stays constant up to the transit time and less than a period. Its minimum over
    the first and over the last quarter of the messages (at least LAG_SAMPLES each)
    differ by more only if diagnostics missed (or invented) skipped steps.
    """
    n = max(LAG_SAMPLES, len(lags) // 4)
    if len(lags) < 2 * n:
        return None, None
    first = min(lag - s * dt_ns for lag, s in lags[:n])
    last = min(lag - s * dt_ns for lag, s in lags[-n:])
    return (last - first) / 1e6, lags[-1][1] - lags[0][1]


def main():
    """Run the soak, print the figures and write them as JSON."""
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument('--duration', type=float, default=3600.0, help='seconds')
    ap.add_argument('--split', type=float, default=300.0, help='file split [s]')
    ap.add_argument('--warmup', type=float, default=20.0, help='seconds before the first RSS')
    ap.add_argument('--fault-period', type=float, default=180.0,
                    help='seconds between injected faults')
    ap.add_argument('--max-total-bytes', type=int, default=4 << 30,
                    help='record_max_total_bytes of the node (default 4 GiB: an hour of this '
                    'soak exceeds the node\'s default of 1 GiB, whose pruning would delete '
                    'the first files)')
    args = ap.parse_args()
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.setdefault('ROS_DOMAIN_ID', '77')
    import rclpy
    from leadscrew_sim import load_preset

    preset = load_preset('tr12x3')
    out = Path(tempfile.mkdtemp(prefix='soak_'))
    os.environ.setdefault('ROS_LOG_DIR', str(out / 'ros_log'))
    log = open(out / 'node.log', 'wb')
    params = ['preset:=tr12x3', f'record_dir:={out}', f'record_split_seconds:={args.split}',
              f'record_max_total_bytes:={args.max_total_bytes}', *SENSORS]
    node = subprocess.Popen(
        [sys.executable, '-m', 'leadscrew_sim.node', '--ros-args',
         *[a for p in params for a in ('-p', p)]], stdout=log, stderr=subprocess.STDOUT)
    rclpy.init()
    mon = Monitor(node, profile(preset.stroke_min, preset.stroke_max))
    # Up: diagnostics arrive and our command writer matched; the node's side of the match
    # may trail ours (it drops samples of writers it has not yet discovered): wait a second.
    up = mon.spin_until(lambda: mon.n_diag > 0 and mon.pub.get_subscription_count() > 0, 180.0)
    if not up:
        node.kill()
        sys.exit(f'soak: the node did not come up; see {out / "node.log"}')
    mon.spin_for(1.0)
    names = ['clock_mode', 'update_rate', 'max_catchup_steps', 'record_max_total_bytes',
             'record_split_seconds', 'encoder_counts', 'encoder_noise', 'linear_scale',
             'scale_resolution', 'scale_noise', 'state_delay', 'command_delay',
             'drive_feedback']
    node_params = mon.get_params(names) or {}
    mon.spin_until(lambda: mon.set_cli.service_is_ready() and mon.clear_cli.service_is_ready(),
                   10.0)
    dt_ns = int(round(NS / float(node_params.get('update_rate') or 1000.0)))
    t0 = time.monotonic()
    mon.start_commands()
    fault_on = min(FAULT_ON, 0.5 * args.fault_period)
    next_k, rss, crss = 0, [], []
    next_rss = t0 + args.warmup
    live = None                        # the fault that is on
    while time.monotonic() - t0 < args.duration and node.poll() is None:
        mon.executor.spin_once(timeout_sec=0.05)
        now = time.monotonic() - t0
        if time.monotonic() >= next_rss:
            if mon.warm is None:
                mon.warm = dict(mon.diag)
            rss.append(rss_kib(node.pid))
            crss.append(child_rss_kib(node.pid))
            next_rss += 10.0
        start = args.warmup + next_k * args.fault_period
        if live is None and now >= start and start + fault_on + END_MARGIN <= args.duration:
            mon.inject(next_k, now)
            live, next_k = mon.faults[-1], next_k + 1
        if live is not None and now >= live['t_on_s'] + fault_on:
            mon.release(live, now)
            live = None
    # Stop the commands; wait until two diagnostics messages in a row count the same
    # commands received (the node took the last one), then stop the node.
    mon.node.destroy_timer(mon.timer)
    end = time.monotonic() + 10.0
    while time.monotonic() < end and node.poll() is None:
        n = mon.n_diag
        mon.spin_until(lambda: mon.n_diag > n, 3.0)
        if len(mon.received) > 1 and mon.received[-1] == mon.received[-2] and (
                mon.n_diag > n):
            break
    last = dict(mon.diag)
    if node.poll() is None:
        rss.append(rss_kib(node.pid))
        crss.append(child_rss_kib(node.pid))
    elapsed = time.monotonic() - t0
    load = os.getloadavg()
    node.send_signal(signal.SIGINT)
    try:
        code = node.wait(timeout=60)
    except subprocess.TimeoutExpired:
        node.kill()
        code = node.wait()
    mon.node.destroy_node()
    rclpy.shutdown()
    log.close()
    text = (out / 'node.log').read_text(errors='replace')
    steps = re.findall(r'stopped after (\d+) steps', text)
    steps = int(steps[-1]) if steps else None

    files = sorted(out.glob('*.mcap'))
    counts, no_summary = file_counts(files)
    total_bytes = sum(f.stat().st_size for f in files)
    indexes = sorted(int(m.group(1)) for f in files
                     if (m := re.search(r'_(\d{3})\.mcap$', f.name)))
    contiguous = indexes == list(range(len(indexes)))
    bound = node_params.get('record_max_total_bytes')
    state_delay = int(node_params.get('state_delay') or 0)
    dropped_states = int(last.get('dropped_states', 0))
    truth, sensor = counts.get('sim/joint_states', 0), counts.get('axis/joint_states', 0)
    sensor_expected = None if steps is None else steps - dropped_states - state_delay
    drift_ms, skipped_span = lag_check(mon.lags, dt_ns)
    warm = mon.warm or {}

    def since_warmup(key):
        return int(last.get(key, 0)) - int(warm.get(key, 0))
    ff = fault_figures(mon.faults)
    summary = dict(
        duration_s=round(elapsed, 1), split_s=args.split, fault_period_s=args.fault_period,
        warmup_s=args.warmup, directory=str(out), node_exit_code=code,
        load_average_1_5_15_min=[round(x, 2) for x in load], node_parameters=node_params,
        ticks_taken=steps, sim_joint_states_in_files=truth, joint_states_in_files=sensor,
        joint_states_expected=sensor_expected, dropped_states=dropped_states,
        dropped_commands=int(last.get('dropped_commands', 0)),
        position_commands_sent=mon.sent,
        position_commands_received=mon.received[-1] if mon.received else 0,
        position_commands_in_files=counts.get('position_command', 0),
        commands_accepted=int(last.get('commands', 0)),
        rejected_commands=int(last.get('rejected_commands', 0)),
        diagnostics_received=mon.n_diag, diagnostics_during_commands=mon.n_run,
        late_ticks=int(last.get('late_ticks', 0)),
        catchup_steps=int(last.get('catchup_steps', 0)), overruns=int(last.get('overruns', 0)),
        skipped_steps=int(last.get('skipped_steps', 0)),
        after_warmup={k: since_warmup(k) for k in ('late_ticks', 'catchup_steps', 'overruns',
                                                   'skipped_steps')},
        worst_window_lateness_max_us=mon.worst_max_us,
        worst_window_lateness_max_us_after_warmup=mon.worst_after_us,
        min_window_rate_hz=None if mon.min_rate == math.inf else mon.min_rate,
        sim_lag_drift_ms=drift_ms, skipped_steps_over_lag_span=skipped_span,
        position_mode_diagnostics=mon.position_diags,
        max_following_error_rad_outside_faults=mon.quiet_ferr,
        max_following_error_um_outside_faults=mon.quiet_ferr * preset.lead / (2 * math.pi) * 1e6,
        node_rss_kib=[rss[0], rss[-1]] if rss else None,
        node_rss_max_kib=max(rss) if rss else None,
        node_rss_growth_pct=growth(rss[0], rss[-1]) if rss else None,
        recorder_rss_kib=[crss[0], crss[-1]] if crss else None,
        recorder_rss_max_kib=max(crss) if crss else None,
        recorder_rss_growth_pct=growth(crss[0], crss[-1]) if crss else None,
        files=[[f.name, f.stat().st_size] for f in files], files_total_bytes=total_bytes,
        recorded_bytes_per_hour=round(total_bytes * 3600.0 / elapsed) if elapsed > 0 else None,
        files_without_summary=no_summary, file_indexes_contiguous=contiguous,
        record_max_total_bytes=bound, faults=ff, fault_log=mon.faults,
        recording_error=last.get('recording_error') or None,
        recording_dropped=int(last.get('recording_dropped', 0)),
        tracebacks_in_node_log=text.count('Traceback'))
    report(summary)
    path = out / 'soak_summary.json'
    path.write_text(json.dumps(summary, indent=1, default=str) + '\n')
    print(f'summary JSON: {path}')


def report(s):
    """Print the figures of a summary, one line each."""
    def yes(ok):
        return 'yes' if ok else 'NO'
    print(f'soak: {s["duration_s"]:.0f} s realtime at 1 kHz, position profile, faults every '
          f'{s["fault_period_s"]:.0f} s, split every {s["split_s"]:.0f} s, dir '
          f'{s["directory"]}, node exit code {s["node_exit_code"]}, host load average '
          f'{"/".join(str(x) for x in s["load_average_1_5_15_min"])} on {os.cpu_count()} cores')
    kept = '' if s['file_indexes_contiguous'] else ' (files were deleted: counts of the rest)'
    print(f'ticks taken {s["ticks_taken"]}; sim/joint_states in files '
          f'{s["sim_joint_states_in_files"]} (equal: '
          f'{yes(s["ticks_taken"] == s["sim_joint_states_in_files"])}){kept}')
    print(f'axis/joint_states in files {s["joint_states_in_files"]}; expected: ticks - '
          f'{s["dropped_states"]} lost to fault.state_drop_rate - '
          f'{s["node_parameters"].get("state_delay")} still under way (state_delay) at exit = '
          f'{s["joint_states_expected"]} (equal: '
          f'{yes(s["joint_states_in_files"] == s["joint_states_expected"])})')
    sent, got = s['position_commands_sent'], s['position_commands_received']
    missed = (f'; {sent - got} sent but never taken (its command queue keeps the last 10 '
              'while the node stalls)' if sent != got else '')
    print(f'position_command sent {sent}, received by the node {got} ({s["commands_accepted"]} '
          f'taken + {s["dropped_commands"]} lost to fault.command_drop_rate{missed}), in files '
          f'{s["position_commands_in_files"]} (= received: '
          f'{yes(got == s["position_commands_in_files"])}), rejected {s["rejected_commands"]}')
    print(f'drive in position mode in {s["position_mode_diagnostics"]} of '
          f'{s["diagnostics_during_commands"]} diagnostics during the commands; |following '
          f'error| outside fault windows <= {s["max_following_error_rad_outside_faults"]:.3f} '
          f'rad ({s["max_following_error_um_outside_faults"]:.0f} um at the nut)')
    drift = s['sim_lag_drift_ms']
    dt_ms = 1e3 / float(s['node_parameters'].get('update_rate') or 1000.0)
    skipped = s['skipped_steps_over_lag_span']
    verdict = ('unknown (run too short)' if drift is None else
               f'{yes(abs(drift) <= LAG_TOLERANCE_MS)} (the lag of sim time behind the wall '
               f'clock grew by {skipped * dt_ms + drift:.2f} ms while diagnostics reported '
               f'{skipped} skipped steps of {dt_ms:g} ms: difference {drift:+.2f} ms, '
               f'tolerance +-{LAG_TOLERANCE_MS:g} ms)')
    w = s['after_warmup']
    print(f'late ticks {s["late_ticks"]} ({s["catchup_steps"]} catch-up steps), overruns '
          f'{s["overruns"]} ({s["skipped_steps"]} steps skipped); after the warm-up: late '
          f'ticks {w["late_ticks"]} ({w["catchup_steps"]}), overruns {w["overruns"]} '
          f'({w["skipped_steps"]}); largest window max lateness '
          f'{s["worst_window_lateness_max_us"]:.0f} us ('
          f'{s["worst_window_lateness_max_us_after_warmup"]:.0f} us after the warm-up), lowest '
          f'achieved rate of a window {s["min_window_rate_hz"]} Hz')
    print(f'every skipped step reported: {verdict}')
    for who, key in (('node', 'node'), ('recorder child', 'recorder')):
        r = s[f'{key}_rss_kib']
        if r:
            print(f'{who} RSS after warm-up {r[0]} KiB, at end {r[1]} KiB, growth '
                  f'{s[f"{key}_rss_growth_pct"]:.1f} % (max {s[f"{key}_rss_max_kib"]} KiB)')
    bound = s['record_max_total_bytes']
    share = f'{100.0 * s["files_total_bytes"] / bound:.1f} % of' if bound else 'no bound:'
    rate = s['recorded_bytes_per_hour']
    print(f'files {len(s["files"])}, total {s["files_total_bytes"] / 1e6:.1f} MB = {share} '
          f'record_max_total_bytes {bound} B; none deleted (file indexes contiguous): '
          f'{yes(s["file_indexes_contiguous"])}; without summary: '
          f'{s["files_without_summary"] or "none"}' + (
              f'; {rate / 1e6:.0f} MB/h, so the default 1 GiB holds '
              f'{(1 << 30) / rate * 60:.0f} min of this run' if rate else ''))
    f = s['faults']
    latched = ', '.join(f'{k} x{v}' for k, v in f['latched_faults_cleared'].items()) or 'none'
    print(f'faults injected {f["injected"]}: set acknowledged {f["set_acknowledged"]}, seen '
          f'in diagnostics {f["seen_in_diagnostics"]}, turned off {f["turned_off"]}, '
          f'~/clear_fault answered ok {f["clear_fault_ok"]} of {f["clear_fault_calls"]} '
          f'(latched faults cleared: {latched}), back to normal in diagnostics '
          f'{f["back_to_normal"]}')
    print(f'recording error {s["recording_error"]!r}, messages dropped by the recorder '
          f'{s["recording_dropped"]}, tracebacks in the node log '
          f'{s["tracebacks_in_node_log"]}')


if __name__ == '__main__':
    main()
