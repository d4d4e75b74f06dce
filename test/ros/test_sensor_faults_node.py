"""
Sensor delays, lost messages and injected faults of the node over DDS, from another process.

The node runs as a real process (fixture ``run_exe``) on the session's isolated
domain. The test process commands it, changes the ``fault.*`` parameters through
``rcl_interfaces/SetParameters`` and reads ``axis/joint_states`` (what the sensors
report, possibly late or lost) against ``sim/joint_states`` (the truth: every
tick, never delayed). Most tests run in lockstep mode: one tick per received
torque command and the state of tick n stamped n dt (dt = 1 ms at the default
update_rate of 1000 Hz), so ticks are counted exactly and named by their stamps.

The oracles are the documented rules, not our output: a state delay of d ticks
delivers the truth of tick n - d at tick n; a command sent before tick k acts on
the state stamped (k + 1 + command_delay) dt (the log-time rule); a drop rate p
loses a Binomial(N, p) number of N messages; a frozen encoder holds its last
reading; an injected drive fault switches the torque off until ~/clear_fault.
"""
import math
from pathlib import Path
import re
import signal

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from helpers import cli_ok, MS, NODE, param_msg, stamp_ns, start_node
from leadscrew_sim.core import load_preset
from leadscrew_sim.core.engine.sensors import STREAM_COMMAND_DROP, STREAM_STATE_DROP, uniform
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

#: The state subscriptions: reliable and deep enough to hold every tick of a test.
DEEP = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)

#: The axis of every test: tr12x3 (right hand, self-locking, 10 kg vertical load, max_torque
#: 1 N m, torque_lag 0: the applied torque is the command at once) with a stiff viscous guide,
#: so that 0.25-0.3 N m lowers the nut at ~15 mm/s instead of accelerating without bound
#: (thread friction is Coulomb): every run stays well inside the +-0.2 m stroke.
AXIS = ('preset:=tr12x3', 'guide_viscous:=20000.0')

#: Name of the run-time parameter change records of a recording.
UPDATE_RECORD = 'leadscrew_sim_parameters_update'


def joints(msg):
    """Return {joint name: (position, velocity, effort)} of a JointState."""
    return {n: (p, v, e) for n, p, v, e in zip(msg.name, msg.position, msg.velocity, msg.effort)}


def by_stamp(msgs):
    """Return {stamp [ns]: joints(msg)}."""
    return {stamp_ns(m): joints(m) for m in msgs}


def three_sigma(n, p):
    """Return (low, high): the 3-sigma band of a Binomial(n, p) count."""
    mean, half = n * p, 3.0 * math.sqrt(n * p * (1.0 - p))
    return mean - half, mean + half


def status_of(arr):
    """Return (DiagnosticStatus, {key: value}) of the node's diagnostics message."""
    st = arr.status[0]
    return st, {kv.key: kv.value for kv in st.values}


class Axis:
    """A node process with the test side's state subscriptions, command publisher and clients."""

    def __init__(self, run_exe, ros, *params, mode='lockstep', record=False):
        """Start the node, subscribe to its states and diagnostics, wait for the matches."""
        self.ros = ros
        self.proc = start_node(run_exe, f'clock_mode:={mode}', *AXIS, *params, record=record)
        self.states, self.truth, self.diags = [], [], []
        node = ros.node
        subs = [node.create_subscription(JointState, 'axis/joint_states', self.states.append,
                                         DEEP),
                node.create_subscription(JointState, 'sim/joint_states', self.truth.append,
                                         DEEP)]
        node.create_subscription(DiagnosticArray, 'diagnostics', self.diags.append, 50)
        self.pub = node.create_publisher(Float64, 'torque_command', 10)
        self._clients = {}
        ok = ros.spin_until(lambda: self.dead() or (
            self.pub.get_subscription_count() > 0
            and all(s.get_publisher_count() > 0 for s in subs)), 60.0)
        assert ok and not self.dead(), self.proc.output()
        # Our readers matched the node's writers; give the writers' side of the match a
        # moment too (discovery is symmetric, not simultaneous): in lockstep nothing is
        # published before our first command, so nothing can be lost before that.
        ros.spin_for(0.3)
        self.sent = 0

    def dead(self):
        """Return True if the node process ended."""
        return self.proc.proc.poll() is not None

    def tick(self, torques, window=4):
        """
        Send one torque command per lockstep tick; return when every tick is done.

        At most ``window`` commands are under way (sent, their tick's truth not yet
        received): the node's command subscription keeps the last 10, so none is lost.
        """
        for value in torques:
            self.pub.publish(Float64(data=float(value)))
            self.sent += 1
            due = self.sent - window + 1
            assert self.ros.spin_until(lambda: len(self.truth) >= due or self.dead(), 10.0), \
                (self.sent, len(self.truth), self.proc.output())
        assert self.ros.spin_until(lambda: len(self.truth) >= self.sent, 10.0), \
            (self.sent, len(self.truth), self.proc.output())
        assert not self.dead(), self.proc.output()

    def call(self, srv_type, name, request, timeout=10.0):
        """Call one of the node's services (a client per service, kept) and return the answer."""
        cli = self._clients.get(name)
        if cli is None:
            cli = self._clients[name] = self.ros.node.create_client(srv_type, f'{NODE}/{name}')
        assert self.ros.spin_until(cli.service_is_ready, timeout), f'{name} not available'
        fut = cli.call_async(request)
        assert self.ros.spin_until(fut.done, timeout), f'{name} did not answer'
        return fut.result()

    def set_params(self, values):
        """Set parameters {ROS name: value} through SetParameters; assert each is taken."""
        res = self.call(SetParameters, 'set_parameters', SetParameters.Request(
            parameters=[param_msg(k, v) for k, v in values.items()]))
        assert [r.successful for r in res.results] == [True] * len(values), \
            [r.reason for r in res.results]

    def trigger(self, name):
        """Call a std_srvs/Trigger service of the node; return the response."""
        return self.call(Trigger, name, Trigger.Request())

    def diagnostic(self, pred, after=0, timeout=5.0):
        """
        Wait for a diagnostics message (index >= after) with pred(status, values) true.

        Returns (index, status, values). The node publishes them once a wall second in
        every clock mode, so 5 s is several periods.
        """
        found = []

        def check():
            for i in range(after, len(self.diags)):
                st, kv = status_of(self.diags[i])
                if pred(st, kv):
                    found.append((i, st, kv))
                    return True
            return False
        assert self.ros.spin_until(check, timeout), (
            status_of(self.diags[-1]) if self.diags else 'no diagnostics')
        return found[0]


def motor_efforts(truth):
    """Return the applied motor torque of each truth message (sim/joint_states motor_joint)."""
    return [joints(m)['motor_joint'][2] for m in truth]


# ---------------------------------------------------------------------------
# Delays
# ---------------------------------------------------------------------------

@pytest.mark.timeout(60)
def test_state_delay_delivers_the_truth_of_d_ticks_ago(run_exe, ros):
    """axis/joint_states at tick n: stamp and true values of tick n - d; the truth: never late."""
    d, r, n = 3, 1e-6, 60
    # Ideal encoder (exact truth), quantised linear scale of resolution r. With the default
    # drive_rate (4000 Hz) a tr12x3 step has 18 substeps and a drive period 5 of them, so
    # most steps do not end on a drive sample: the reading must still be of the step's end.
    ax = Axis(run_exe, ros, f'state_delay:={d}', f'scale_resolution:={r}')
    assert '18 substeps/step' in ax.proc.output()      # the premise of the comment above
    for k in range(1, n + 1):
        ax.tick([0.3], window=1)
        # The truth of tick k is stamped k dt and arrives with tick k.
        assert stamp_ns(ax.truth[-1]) == k * MS
        assert ros.spin_until(lambda: len(ax.states) >= k - d, 5.0), (k, len(ax.states))
        # A sample delivered early would be published with tick k's truth: give it a moment
        # to arrive (the final count below is the strict check of the last d samples).
        ros.spin_for(0.005)
        assert len(ax.states) == max(0, k - d), (k, len(ax.states))
        if k > d:
            assert stamp_ns(ax.states[-1]) == (k - d) * MS
    ros.spin_for(0.3)
    # No further tick: the samples of the last d ticks are still in the line.
    assert [stamp_ns(m) for m in ax.states] == [j * MS for j in range(1, n - d + 1)]
    assert [stamp_ns(m) for m in ax.truth] == [j * MS for j in range(1, n + 1)]
    truth = by_stamp(ax.truth)
    for m in ax.states:
        s, t = joints(m), truth[stamp_ns(m)]
        # Ideal encoder: the true screw angle and rate of the sample's tick, bit for bit;
        # the effort is the applied motor torque of that tick.
        assert s['screw_joint'][:2] == t['screw_joint'][:2], stamp_ns(m)
        assert s['screw_joint'][2] == t['motor_joint'][2]
        # Scale reading floor(x / r) r: 0 <= x - reading < r; 1e-15 m covers the rounding
        # of x / r and of the product (x ~ 1e-3 m, ulp ~ 2e-19 m).
        x, reading = t['nut_joint'][0], s['nut_joint'][0]
        assert -1e-15 <= x - reading < r + 1e-15, (stamp_ns(m), x, reading)
        assert abs(reading / r - round(reading / r)) < 1e-6
        # Axial force: the total (axis/joint_states) and nut A's share (truth) agree without a
        # split nut up to the rounding of the sum of the contact terms.
        assert abs(s['nut_joint'][2] - t['nut_joint'][2]) <= 1e-9 * (1.0 + abs(t['nut_joint'][2]))
    # Not vacuous: the nut crossed many scale quanta and the screw turned.
    assert abs(truth[n * MS]['nut_joint'][0] - truth[MS]['nut_joint'][0]) > 100 * r
    assert len({v['screw_joint'][0] for v in truth.values()}) == n


@pytest.mark.timeout(60)
def test_command_delay_acts_d_ticks_later(run_exe, ros):
    """A command sent before tick k acts on the state of tick k + 1 + d; with delay 0, of k + 1."""
    d = 3
    ax = Axis(run_exe, ros, f'command_delay:={d}')
    # Distinct torques below max_torque (1 N m), so each tick tells which command acted.
    first = [0.25 + 1e-3 * i for i in range(30)]
    ax.tick(first)
    ax.set_params({'command_delay': 0})
    second = [0.35 - 1e-3 * i for i in range(30)]
    ax.tick(second)
    ros.spin_for(0.2)
    assert [stamp_ns(m) for m in ax.truth] == [j * MS for j in range(1, 61)]
    # State i (stamped (i + 1) dt) is step i. Delay d: step i gets the command sent before
    # step i - d; the first d steps keep the initial 0 N m. Delay 0 (log-time rule): step
    # i gets the command sent before it; the d commands still under way are superseded.
    expected = [0.0] * d + first[:-d] + second
    assert motor_efforts(ax.truth) == expected
    # axis/joint_states (no state delay) reports the same applied torque on the same stamps.
    assert [(stamp_ns(m), joints(m)['screw_joint'][2]) for m in ax.states] == [
        ((i + 1) * MS, e) for i, e in enumerate(expected)]


# ---------------------------------------------------------------------------
# Lost states and commands
# ---------------------------------------------------------------------------

@pytest.mark.timeout(90)
def test_state_drops_follow_the_binomial_bound_and_stop_at_rate_zero(run_exe, ros):
    """With fault.state_drop_rate p, N p +- 3 sigma of N ticks lack axis/joint_states; 0: none."""
    seed, p = 5, 0.3
    na, nb, nc = 100, 2000, 200
    ax = Axis(run_exe, ros, f'sensor_seed:={seed}')
    # 0.3 N m: the screw turns, so every tick's state differs (the value check below).
    ax.tick([0.3] * na)
    ax.set_params({'fault.state_drop_rate': p})
    ax.tick([0.3] * nb)
    ax.set_params({'fault.state_drop_rate': 0.0})
    ax.tick([0.3] * nc)
    total = na + nb + nc
    ros.spin_for(0.3)
    ticks = [j * MS for j in range(1, total + 1)]
    assert [stamp_ns(m) for m in ax.truth] == ticks         # the truth has every tick
    got = [stamp_ns(m) for m in ax.states]
    assert got == sorted(set(got)) and set(got) <= set(ticks)
    missing = sorted(set(ticks) - set(got))

    def lost(lo, hi):
        return [s for s in missing if lo * MS < s <= hi * MS]
    assert lost(0, na) == [] and lost(na + nb, total) == []     # rate 0: every tick
    n_lost = len(lost(na, na + nb))
    low, high = three_sigma(nb, p)
    print(f'state drops: {n_lost} of {nb} (3-sigma band {low:.1f} .. {high:.1f})')
    assert low <= n_lost <= high
    # The delivered samples are the truth of their stamp (ideal sensors, no delay).
    truth = by_stamp(ax.truth)
    assert all(joints(m)['screw_joint'][:2] == truth[stamp_ns(m)]['screw_joint'][:2]
               for m in ax.states)
    # The documented seeded rule, across the process boundary: the sample of tick n is
    # lost iff uniform(sensor_seed, STREAM_STATE_DROP, n) < p.
    assert lost(na, na + nb) == [n * MS for n in range(na + 1, na + nb + 1)
                                 if uniform(seed, STREAM_STATE_DROP, n) < p]
    _i, _st, kv = ax.diagnostic(lambda st, kv: kv['sim_time_s'] == f'{total / 1000:.6f}')
    assert kv['dropped_states'] == str(n_lost)
    assert kv['active_faults'] == 'none'


@pytest.mark.timeout(90)
def test_command_drops_follow_the_binomial_bound_and_diagnostics_count_them(run_exe, ros):
    """With fault.command_drop_rate p, N p +- 3 sigma of N commands are lost; diagnostics agree."""
    seed, p = 9, 0.3
    na, nb = 50, 2000
    ax = Axis(run_exe, ros, f'sensor_seed:={seed}')
    # Distinct torques (0.25 .. 0.27 N m): the applied torque of a step names its command.
    torques = [0.25 + 1e-5 * k for k in range(na + nb)]
    ax.tick(torques[:na])
    ax.set_params({'fault.command_drop_rate': p})
    ax.tick(torques[na:])
    ros.spin_for(0.2)
    assert [stamp_ns(m) for m in ax.truth] == [j * MS for j in range(1, na + nb + 1)]
    applied = motor_efforts(ax.truth)
    # Log-time rule: command k (sent before step k) acts on the state of step k.
    dropped = [k for k in range(na + nb) if applied[k] != torques[k]]
    held = 0.0
    for k in range(na + nb):        # a lost command leaves the last taken one held
        if k not in dropped:
            held = torques[k]
        assert applied[k] == held, k
    assert all(k >= na for k in dropped)                    # rate 0: every command acts
    low, high = three_sigma(nb, p)
    print(f'command drops: {len(dropped)} of {nb} (3-sigma band {low:.1f} .. {high:.1f})')
    assert low <= len(dropped) <= high
    # The documented seeded rule: the n-th drive command received since start (n from 0,
    # the commands before the change count too) is lost iff uniform(seed, 3, n) < p.
    assert dropped == [n for n in range(na, na + nb)
                       if uniform(seed, STREAM_COMMAND_DROP, n) < p]
    # Diagnostics are published in lockstep too (once a wall second): the last tick's.
    _i, st, kv = ax.diagnostic(
        lambda st, kv: kv['sim_time_s'] == f'{(na + nb) / 1000:.6f}')
    assert kv['dropped_commands'] == str(len(dropped))
    assert kv['active_faults'] == f'fault.command_drop_rate={p:g}'
    assert st.level == DiagnosticStatus.WARN


# ---------------------------------------------------------------------------
# Faults set at run time
# ---------------------------------------------------------------------------

@pytest.mark.timeout(60)
def test_encoder_freeze_holds_the_reading_and_diagnostics_warn(run_exe, ros):
    """fault.encoder_freeze holds the screw reading while the truth moves; diagnostics WARN."""
    ax = Axis(run_exe, ros, 'real_time_factor:=0.5', 'command_timeout:=0.0', mode='stepped')
    ax.pub.publish(Float64(data=0.3))      # held (no timeout): the screw turns steadily

    def screw(m):
        return joints(m)['screw_joint'][0]
    assert ros.spin_until(lambda: len(ax.truth) > 1 and abs(
        screw(ax.truth[-1]) - screw(ax.truth[0])) > 1.0, 20.0), ax.proc.output()
    before_on = stamp_ns(ax.truth[-1])     # the node's tick at the change is at least this
    ax.set_params({'fault.encoder_freeze': True})
    i_on, st_on, kv_on = ax.diagnostic(
        lambda st, kv: 'fault.encoder_freeze' in kv['active_faults'])
    ros.spin_for(0.2)
    before_off = stamp_ns(ax.truth[-1])
    ax.set_params({'fault.encoder_freeze': False})
    # Every message between the two changes says the freeze is on: a later 'none' is new.
    _i, st_off, kv_off = ax.diagnostic(lambda st, kv: kv['active_faults'] == 'none',
                                       after=i_on + 1)
    ros.spin_for(0.3)
    truth, sensor = by_stamp(ax.truth), by_stamp(ax.states)
    # The node ticked before our readers matched, and the last tick's truth may still be on
    # its way: compare the stamps both topics have between their common ends.
    lo, hi = max(min(truth), min(sensor)), min(max(truth), max(sensor))
    truth = {s: v for s, v in truth.items() if lo <= s <= hi}
    sensor = {s: v for s, v in sensor.items() if lo <= s <= hi}
    assert list(sensor) == list(truth)          # no drops, no delay: every tick, in order
    assert list(truth) == list(range(lo, hi + MS, MS))
    frozen = [s for s, j in sensor.items()
              if j['screw_joint'][0] != truth[s]['screw_joint'][0]]
    assert frozen
    a, b = frozen[0], frozen[-1]
    # One block of frozen samples, from after the request to at least the last tick seen
    # before the release; a live ideal encoder reports the true angle exactly elsewhere.
    assert frozen == [s for s in sensor if a <= s <= b]
    assert before_on < a and b >= before_off
    held = {sensor[s]['screw_joint'][:2] for s in frozen}
    value = truth[a - MS]['motor_joint'][0]     # the last live reading (motor angle)
    assert held == {(value, 0.0)}, held
    assert abs(truth[b]['screw_joint'][0] - value) > 1.0   # the truth turned meanwhile
    # The linear scale (ideal) stays live throughout; the encoder is live again after.
    assert all(sensor[s]['nut_joint'][0] == truth[s]['nut_joint'][0] for s in sensor)
    assert sum(1 for s in sensor if s > b) > 50
    print(f'encoder frozen for {len(frozen)} ticks at {value:.6f} rad while the screw turned '
          f'{truth[b]["screw_joint"][0] - value:.3f} rad')
    assert st_on.level == DiagnosticStatus.WARN
    assert st_on.message == 'injected faults active: fault.encoder_freeze'
    assert kv_on['active_faults'] == 'fault.encoder_freeze'
    assert st_off.level == DiagnosticStatus.OK, st_off.message
    assert int(round(float(kv_off['sim_time_s']) * 1000)) * MS > b


@pytest.mark.timeout(60)
def test_injected_drive_fault_latches_until_cleared_after_release(run_exe, ros):
    """fault.drive_fault turns the torque off; ~/clear_fault fails while it is true, then works."""
    torque = 0.2
    ax = Axis(run_exe, ros)
    ax.tick([torque] * 10)
    ax.set_params({'fault.drive_fault': True})
    ax.tick([torque] * 10)
    r = ax.trigger('clear_fault')
    assert not r.success and 'fault.drive_fault' in r.message, r.message
    _i, st, kv = ax.diagnostic(lambda st, kv: kv['sim_time_s'] == '0.020000')
    assert kv['drive_state'] == 'fault: injected'
    assert st.level == DiagnosticStatus.ERROR
    assert 'fault.drive_fault' in kv['active_faults']
    ax.set_params({'fault.drive_fault': False})
    ax.tick([torque] * 5)                 # released, but latched until ~/clear_fault
    r = ax.trigger('clear_fault')
    assert r.success and 'injected' in r.message, r.message
    ax.tick([torque] * 10)
    # Latched at the next step after the change (torque off exactly); a torque command
    # after the clear acts at once (log-time rule).
    assert motor_efforts(ax.truth) == [torque] * 10 + [0.0] * 15 + [torque] * 10
    _i, st, kv = ax.diagnostic(lambda st, kv: kv['sim_time_s'] == '0.035000')
    assert kv['drive_state'] == 'enabled' and kv['active_faults'] == 'none'
    assert st.level == DiagnosticStatus.OK, st.message
    assert ax.trigger('clear_fault').success          # nothing latched any more


# ---------------------------------------------------------------------------
# A faulted recording and its re-simulation
# ---------------------------------------------------------------------------

@pytest.mark.timeout(120)
def test_faulted_lockstep_recording_resim_is_bit_identical(run_exe, ros, tmp_path):
    """A recording with noisy sensors, delays and run-time faults re-simulates bit-identically."""
    n, delay = 600, 2
    ax = Axis(run_exe, ros, 'encoder_counts:=4096', 'encoder_noise:=2e-4',
              'scale_resolution:=1e-6', 'scale_noise:=3e-7', 'velocity_filter_time:=0.002',
              'sensor_seed:=42', f'state_delay:={delay}', 'command_delay:=1',
              f'record_dir:={tmp_path}', 'record_prefix:=faults', record=True)
    torques = [0.3 + 1e-3 * math.sin(k / 7.0) for k in range(n)]
    changes = {
        100: {'fault.state_drop_rate': 0.2},
        150: {'fault.command_drop_rate': 0.2},
        250: {'fault.encoder_freeze': True},
        300: {'fault.encoder_freeze': False, 'fault.motor_torque_scale': 0.8},
        350: None,                                   # the jam, 1 mm below the nut
        500: {'fault.state_drop_rate': 0.0, 'fault.command_drop_rate': 0.0},
    }
    done, jam = 0, None
    for k in sorted(changes) + [n]:
        ax.tick(torques[done:k])
        done = k
        if k in changes:
            if changes[k] is None:
                jam = joints(ax.truth[-1])['nut_joint'][0] - 1e-3
                changes[k] = {'fault.jam_position': jam, 'fault.jam': True}
            ax.set_params(changes[k])
    ros.spin_for(0.3)
    assert ax.proc.stop(signal.SIGINT, timeout=30.0) == 0, ax.proc.output()
    files = sorted(Path(tmp_path).glob('faults_*.mcap'))
    assert len(files) == 1, files

    # The jam stopped the nut (positive torque drives a right-hand nut toward -x): at rest
    # against it, the jam's spring carries the thread's push and the weight of nut and
    # payload (tr12x3: 0.1 + 10 kg, vertical), so the static penetration is
    # (-F_axial + m g) / end_stop_stiffness (1e7 N/m). 2 % allows what is left of the
    # guide's viscous force and the end stop damping at the final speed (printed).
    x = [joints(m)['nut_joint'][0] for m in ax.truth]
    v = [joints(m)['nut_joint'][1] for m in ax.truth]
    f_axial = joints(ax.truth[-1])['nut_joint'][2]
    pre = load_preset('tr12x3')
    weight = (pre.nut_mass + pre.payload_mass) * pre.gravity * math.sin(pre.inclination)
    static = (-f_axial + weight) / pre.end_stop_stiffness
    print(f'jam at {jam:.6f} m (nut {x[349]:.6f} m, {v[349]:.4g} m/s at the change); end '
          f'penetration {jam - x[-1]:.4g} m (static {static:.4g} m), {v[-1]:.3g} m/s')
    assert abs((jam - x[-1]) - static) <= 0.02 * static
    assert min(x[350:]) > jam - 2 * static             # never far through it

    r = cli_ok('resim', files[0], '--output', tmp_path / 'faults.resim.mcap', '--quiet')
    print(r.stdout)
    m = re.search(r'compared (\d+) recorded ticks; overall max \|diff\|: (\S+)', r.stdout)
    assert m and float(m.group(2)) == 0.0 and '(bit-identical)' in r.stdout, r.stdout
    assert int(m.group(1)) >= n - delay, r.stdout

    # An independent reader: the recorded states and the update records.
    with open(files[0], 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        msgs = [(c.topic, msg.log_time, d) for _s, c, msg, d in
                reader.iter_decoded_messages(log_time_order=False)]
        updates = [dict(rec.metadata) for rec in reader.iter_metadata()
                   if rec.name == UPDATE_RECORD]
    truth = [(lt, d) for t, lt, d in msgs if t == '/sim/joint_states']
    assert [(lt, stamp_ns(d)) for lt, d in truth] == [(j * MS, j * MS) for j in range(1, n + 1)]
    sensor = [(lt, d) for t, lt, d in msgs if t == '/axis/joint_states']
    # Logged when delivered: state_delay ticks after the stamp; some lost between the
    # changes of fault.state_drop_rate (ticks 101 .. 500), none elsewhere.
    assert all(lt == stamp_ns(d) + delay * MS for lt, d in sensor)
    missing = set(range(1, n - delay + 1)) - {stamp_ns(d) // MS for _lt, d in sensor}
    assert missing and min(missing) > 100 and max(missing) <= 500, sorted(missing)
    # The sensors were the quantised ones asked for: whole counts of 2 pi / 4096 rad and
    # whole steps of 1e-6 m (1e-6 of a count: the rounding of the products).
    for _lt, d in sensor:
        counts, steps = d.position[0] * 4096 / (2 * math.pi), d.position[1] / 1e-6
        assert abs(counts - round(counts)) < 1e-6 and abs(steps - round(steps)) < 1e-6
    # The recording holds what the live subscriber got.
    assert [(stamp_ns(d), tuple(d.position), tuple(d.velocity), tuple(d.effort))
            for _lt, d in sensor] == [
        (stamp_ns(d), tuple(d.position), tuple(d.velocity), tuple(d.effort))
        for d in ax.states]
    # Every change, in order, with the log time of the tick it came before.
    got = [(int(u['log_time_ns']), name, u[name]) for u in updates
           for name in u if name not in ('log_time_ns', 'messages_at_log_time')]
    want = [(k * MS, name, value) for k, c in sorted(changes.items()) for name, value in c.items()]
    assert len(got) == len(want), got
    for (lt, name, text), (lt_w, name_w, value) in zip(got, want):
        assert (lt, name) == (lt_w, name_w)
        assert (text == str(value)) if isinstance(value, bool) else float(text) == value
