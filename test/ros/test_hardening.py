"""
Hardening: the node as a real process under hostile or extreme input.

Every test starts ``python -m leadscrew_sim.node`` (fixture ``run_exe``) on
the session's isolated DDS domain and talks to it over real middleware; no
mocks. Covered: command fuzzing, a command flood from another process,
parameter abuse at run time, physically extreme parameter sets at start-up,
recording faults (unwritable directory, disk full, SIGKILL) and recording
path safety. The numbers each test prints (inputs tried, rates kept) feed
the README's Reliability table.
"""
import math
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from helpers import (command_publisher, DEEP, MS, NODE, NS, param_msg, stamp_ns, start_node,
                     wait_states)
from leadscrew_sim.core import load_preset, ScrewParams
from leadscrew_sim.core.settings import PREFIX_RE
from leadscrew_sim.io.session import recover
from mcap.reader import make_reader
import pytest
from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import (DescribeParameters, GetParameters, ListParameters,
                                SetParameters, SetParametersAtomically)
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import SetBool

PRESET = load_preset('tr12x3')


def diag_values(msg):
    """Return {key: value} of the node's DiagnosticStatus in a DiagnosticArray."""
    return {kv.key: kv.value for kv in msg.status[0].values}


def finite_state(msg):
    """Return True if every number of a JointState is finite."""
    return all(math.isfinite(v) for v in (*msg.position, *msg.velocity, *msg.effort))


def finite_wrench(msg):
    """Return True if every number of a WrenchStamped is finite."""
    f, t = msg.wrench.force, msg.wrench.torque
    return all(math.isfinite(v) for v in (f.x, f.y, f.z, t.x, t.y, t.z))


def param_value(pv):
    """Return the Python value of an rcl_interfaces/ParameterValue."""
    return {ParameterType.PARAMETER_BOOL: pv.bool_value,
            ParameterType.PARAMETER_INTEGER: pv.integer_value,
            ParameterType.PARAMETER_DOUBLE: pv.double_value,
            ParameterType.PARAMETER_STRING: pv.string_value}.get(pv.type)


# ---------------------------------------------------------------------------
# 1. Command fuzzing
# ---------------------------------------------------------------------------

#: (value published on torque_command, effort the node applies or None: rejected).
TORQUE_CASES = [
    (float('nan'), None), (float('inf'), None), (float('-inf'), None),
    (1e308, PRESET.max_torque), (-1e308, -PRESET.max_torque),
    (sys.float_info.max, PRESET.max_torque), (-0.3, -0.3), (5e-324, 5e-324),
    (-5e-324, -5e-324), (0.25, 0.25),
]

#: (JointState published on axis/joint_commands, effort applied, or 'rejected' / 'ignored').
JOINT_CASES = [
    (JointState(name=['screw_joint', 'nut_joint'], effort=[0.11]), 'rejected'),
    (JointState(name=['screw_joint'], effort=[0.12, 0.13]), 'rejected'),
    (JointState(name=['screw_joint', 'screw_joint'], effort=[0.14, 0.15]), 'rejected'),
    (JointState(name=[], effort=[]), 'ignored'),
    (JointState(name=['other_joint'], effort=[0.16]), 'ignored'),
    # an axial force on the nut joint is the motor torque F / k, k = h 2 pi / l [rad/m]
    (JointState(name=['nut_joint', 'other'], effort=[0.17, 0.18]),
     0.17 / (PRESET.hand_sign * 2 * math.pi / PRESET.lead)),
    (JointState(name=['screw_joint'], effort=[float('nan')]), 'rejected'),
    (JointState(name=['screw_joint'], effort=[float('-inf')]), 'rejected'),
    (JointState(name=['screw_joint'], effort=[]), 'rejected'),
    (JointState(name=['nut_joint', 'screw_joint'], effort=[0.5, 0.3]), 'rejected'),   # both
    (JointState(name=['other', 'screw_joint'], effort=[0.5, -1e308]), -PRESET.max_torque),
    (JointState(name=['screw_joint'], position=[float('nan')], effort=[0.19]), 0.19),
]

#: (value published on external_force, True if it must be rejected).
FORCE_CASES = [
    (float('nan'), True), (float('inf'), True), (1e308, True), (-1e308, True),
    (5e-324, False), (-2.0, False), (0.0, False),
]


@pytest.mark.timeout(90)
def test_command_fuzzing_keeps_the_node_finite_and_counts_rejections(run_exe, ros):
    # the torques run the axis past the preset's overspeed trip: off here (max_screw_velocity 0)
    proc = start_node(run_exe, 'command_timeout:=0.0', 'max_screw_velocity:=0.0')
    states = ros.collect(JointState, 'axis/joint_states')
    xs = ros.collect(Float64, 'nut_position')
    wrenches = ros.collect(WrenchStamped, 'thread_force')
    diags = ros.collect(DiagnosticArray, 'diagnostics', qos=10)
    wait_states(ros, states, proc)
    tpub = command_publisher(ros)
    jpub = command_publisher(ros, 'axis/joint_commands', JointState)
    fpub = command_publisher(ros, 'external_force')
    rejected = ignored = 0

    def settle():
        # The node takes every command on its next 1 ms tick; 30 ms keeps the
        # depth-10 command queue far from full on a loaded machine.
        ros.spin_for(0.03)

    def applied(value):
        # Effort of the latest state equals the applied torque (exact: no lag).
        assert ros.spin_until(lambda: states[-1].effort[0] == value, 10.0), \
            (value, states[-1].effort[0], proc.output()[-2000:])

    for value, expect in TORQUE_CASES:
        tpub.publish(Float64(data=value))
        settle()
        if expect is None:
            rejected += 1
        else:
            applied(expect)
    for msg, expect in JOINT_CASES:
        jpub.publish(msg)
        settle()
        if expect == 'rejected':
            rejected += 1
        elif expect == 'ignored':
            ignored += 1
        else:
            applied(expect)
    tpub.publish(Float64(data=0.0))
    applied(0.0)
    for value, bad in FORCE_CASES:
        fpub.publish(Float64(data=value))
        settle()
        rejected += bad

    def counters():
        return diags and diag_values(diags[-1]).get('rejected_commands') == str(rejected)

    assert ros.spin_until(counters, 5.0), (rejected, diag_values(diags[-1]))
    last = diag_values(diags[-1])
    assert last['ignored_commands'] == str(ignored), last
    # Still alive, publishing and commandable.
    n = len(states)
    wait_states(ros, states, proc, n + 200, timeout=10.0)
    tpub.publish(Float64(data=0.05))
    applied(0.05)
    assert proc.proc.poll() is None
    assert diags[-1].status[0].level == b'\x00', diags[-1].status[0].message
    efforts = {s.effort[0] for s in states}
    for msg, expect in JOINT_CASES:
        if isinstance(expect, str):
            assert not efforts & set(msg.effort), (msg, expect)
    assert all(abs(e) <= PRESET.max_torque for e in efforts)
    assert all(finite_state(s) for s in states)
    assert all(math.isfinite(x.data) for x in xs)
    assert all(finite_wrench(w) for w in wrenches)
    stamps = [stamp_ns(s) for s in states]
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
    print(f'fuzz: {len(TORQUE_CASES)} torque_command, {len(JOINT_CASES)} joint_commands, '
          f'{len(FORCE_CASES)} external_force inputs; {rejected} rejected, {ignored} ignored; '
          f'{len(states)} joint_states, {len(xs)} nut_position, {len(wrenches)} thread_force '
          'checked finite')


# ---------------------------------------------------------------------------
# 2. Flood
# ---------------------------------------------------------------------------

FLOOD_N = 100_000
#: Shortest flood [s]: at least two of the node's 1 Hz diagnostics windows fall inside
#: it, however fast this machine publishes.
FLOOD_MIN_S = 3.0

FLOOD = """
import sys, time, rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64
rclpy.init()
node = rclpy.create_node('flooder')
pub = node.create_publisher(Float64, 'torque_command',
                            QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
end = time.monotonic() + 30.0
while pub.get_subscription_count() == 0 and time.monotonic() < end:
    time.sleep(0.01)
time.sleep(1.0)
msg = Float64()
print('start', time.monotonic_ns(), flush=True)
n, until = int(sys.argv[1]), time.monotonic() + float(sys.argv[2])
k = 0
while k < n or time.monotonic() < until:
    msg.data = 0.02 if k & 1024 else -0.02
    pub.publish(msg)
    k += 1
print('end', time.monotonic_ns(), flush=True)
print('sent', k, flush=True)
msg.data = 0.0
pub.publish(msg)
time.sleep(0.5)
"""

#: axis/joint_states received by this test's subscriber inside the flood window,
#: as a share of update_rate. Measured here with the flood publisher at nice
#: 19 (65-75 k commands/s over 3 s): 100.0 % in 3 of 3 runs; with the publisher at
#: normal priority taking a whole core of the 2, 89-99 %. 90 % still fails a
#: loop that the callbacks starve (76 % before the per-tick spin budget).
FLOOD_KEPT = 0.90

#: The node's achieved rate over the ~1 s diagnostics windows during the
#: flood, as a share of update_rate: mean and worst window. Catch-up keeps it
#: at 100 % unless the thread is descheduled for more than max_catchup_steps
#: periods (declared skipped steps). Measured with the niced publisher:
#: 999.85-1000.15 Hz in every window of 3 runs. The bars leave room for this
#: shared machine's multi-ms stalls (a 20 ms stall costs 1 % of a window).
FLOOD_NODE_RATE = 0.97
FLOOD_WINDOW_RATE = 0.90


@pytest.mark.timeout(120)
def test_flood_of_commands_does_not_starve_the_loop(run_exe, ros, tmp_path):
    rate = 1000.0
    proc = start_node(run_exe, f'update_rate:={rate}')
    raw = []
    ros.node.create_subscription(JointState, 'axis/joint_states',
                                 lambda d: raw.append((time.monotonic_ns(), d)), DEEP,
                                 raw=True)
    diags = ros.collect(DiagnosticArray, 'diagnostics', qos=10)
    wait_states(ros, raw, proc)
    log = open(tmp_path / 'flood.log', 'w+')
    # The flood publisher runs at nice 19: what is under test is the node's
    # handling of a message flood (bounded callbacks per tick), not a 2-core
    # machine with one core taken by the publisher's own busy loop, where the
    # node's thread is descheduled whatever the node does.
    flood = subprocess.Popen([sys.executable, '-c', FLOOD, str(FLOOD_N), str(FLOOD_MIN_S)],
                             stdout=log,
                             stderr=subprocess.STDOUT, env=dict(os.environ),
                             preexec_fn=lambda: os.nice(19))
    try:
        done = ros.spin_until(lambda: flood.poll() is not None, 90.0)
    finally:
        if flood.poll() is None:
            flood.kill()
        flood.wait(timeout=5)
    ros.spin_for(1.5)
    log.seek(0)
    out = log.read()
    log.close()
    assert done and flood.returncode == 0, out
    marks = dict(line.split() for line in out.splitlines()
                 if line.startswith(('start ', 'end ', 'sent ')))
    t0, t1, sent = int(marks['start']), int(marks['end']), int(marks['sent'])
    window = (t1 - t0) / NS
    inside = [d for t, d in raw if t0 <= t < t1]
    kept = len(inside) / (window * rate)
    from rclpy.serialization import deserialize_message
    msgs = [deserialize_message(d, JointState) for _t, d in raw]
    stamps = [stamp_ns(m) for m in msgs]
    gaps = {b - a for a, b in zip(stamps, stamps[1:])}
    during = [diag_values(d) for d in diags
              if t0 <= stamp_ns(d) - stamp_ns(msgs[0]) + raw[0][0] <= t1]
    print(f'flood: {sent} torque commands in {window:.2f} s '
          f'({sent / window:.0f}/s); joint_states received in the window: {len(inside)} '
          f'= {100 * kept:.1f} % of {rate:g} Hz; node achieved_rate_hz during: '
          f'{[d["achieved_rate_hz"] for d in during]}; commands taken '
          f'{diag_values(diags[-1])["commands"]}, skipped steps '
          f'{diag_values(diags[-1])["skipped_steps"]}')
    assert window > 0.5, 'flood too short to measure'
    # The node's own rate (steps per second of wall time, catch-up included)
    # over the diagnostics windows that fall in the flood.
    rates = [float(d['achieved_rate_hz']) for d in during]
    assert rates and sum(rates) / len(rates) >= FLOOD_NODE_RATE * rate, rates
    assert min(rates) >= FLOOD_WINDOW_RATE * rate, rates
    assert kept >= FLOOD_KEPT, kept
    # Stamps step by whole periods. A gap wider than one period is a skip the
    # node declared (an overrun: its thread was descheduled for more than
    # max_catchup_steps periods on this shared machine) and counted in
    # skipped_steps; nothing else may go missing between node and subscriber.
    period_ns = int(NS / rate)
    assert all(g > 0 and g % period_ns == 0 for g in gaps), sorted(gaps)[:10]
    missing = sum((b - a) // period_ns - 1 for a, b in zip(stamps, stamps[1:]))
    # skipped_steps counts from start-up, so it bounds the skips seen here.
    assert ros.spin_until(lambda: stamp_ns(diags[-1]) >= stamps[-1], 5.0)
    skipped = int(diag_values(diags[-1])['skipped_steps'])
    assert missing <= skipped, (missing, skipped)
    assert all(finite_state(m) for m in msgs)
    # Alive and responsive afterwards: no backlog of stale command events.
    assert proc.proc.poll() is None
    states = ros.collect(JointState, 'axis/joint_states')
    pub = command_publisher(ros)
    sent = time.monotonic()
    pub.publish(Float64(data=0.03))
    assert ros.spin_until(lambda: states and states[-1].effort[0] == 0.03, 10.0)
    print(f'flood: first command after the flood applied within '
          f'{1e3 * (time.monotonic() - sent):.1f} ms')


# ---------------------------------------------------------------------------
# 3. Parameter abuse at run time
# ---------------------------------------------------------------------------

BAD_RECORD_NAMES = ['../../etc', '/tmp/x/../..', 'a/b', 'a\nb', 'a\x00b', '', '.', '..',
                    'x' * 65, 'a b', '$(reboot)']


def abuse_values(name, desc):
    """Return values a run-time set of parameter ``name`` (descriptor desc) must refuse."""
    t = desc.type
    huge = 'x' * 100_000
    if t == ParameterType.PARAMETER_DOUBLE:
        # An integer is taken as the number (then range-checked): 2**62 is out of every range.
        bad = [1e308, -1e308, float('nan'), float('inf'), float('-inf'), 'abc', True, 2 ** 62,
               [1.0, 2.0]]
        for r in desc.floating_point_range:
            bad += [r.to_value + max(1.0, abs(r.to_value)),
                    r.from_value - max(1.0, abs(r.from_value))]
    elif t == ParameterType.PARAMETER_INTEGER:
        bad = [2 ** 63 - 1, -2 ** 63, 1.5, 1e308, float('nan'), 'abc', True, [1, 2]]
        for r in desc.integer_range:
            bad += [min(2 ** 63 - 1, r.to_value + max(1, abs(r.to_value))),
                    r.from_value - max(1, abs(r.from_value))]
    elif t == ParameterType.PARAMETER_BOOL:
        bad = [1.0, 1e308, float('nan'), 'true', 1, [True]]
    else:
        bad = [1e308, float('nan'), -1, True, ['a']]
        if name in ('record_prefix', 'record_dir', 'stats_file'):
            bad += BAD_RECORD_NAMES + [huge]
        elif name == 'joint_prefix':
            bad += [huge, 'a\nb', 'a b', '\t']
        else:
            bad += ['bogus', '', huge]
    # Sizes that would start a new recording file for every message.
    bad += {'record_split_bytes': [1, 4095], 'record_split_seconds': [1e-9, 0.5]}.get(name, [])
    return bad


@pytest.mark.timeout(120)
def test_parameter_abuse_is_refused_and_changes_nothing(run_exe, ros):
    proc = start_node(run_exe)
    states = ros.collect(JointState, 'axis/joint_states')
    wait_states(ros, states, proc)
    names = ros.call(ListParameters, f'{NODE}/list_parameters',
                     ListParameters.Request()).result.names
    descs = dict(zip(names, ros.call(DescribeParameters, f'{NODE}/describe_parameters',
                                     DescribeParameters.Request(names=names)).descriptors))

    def get_all():
        r = ros.call(GetParameters, f'{NODE}/get_parameters',
                     GetParameters.Request(names=list(names)))
        return {n: (v.type, param_value(v)) for n, v in zip(names, r.values)}

    before = get_all()
    assert set(ScrewParams.parameter_names()) <= set(names)
    tried = refused = accepted = 0
    read_only = sorted(n for n in names if descs[n].read_only)
    for name in names:
        bad = abuse_values(name, descs[name])
        res = ros.call(SetParameters, f'{NODE}/set_parameters', SetParameters.Request(
            parameters=[param_msg(name, v) for v in bad]))
        for value, r in zip(bad, res.results):
            tried += 1
            if name == 'record_prefix' and value == 'a\x00b':
                # CDR strings end at NUL: the node receives 'a', a valid prefix.
                assert r.successful, r.reason
                accepted += 1
                continue
            assert not r.successful, (name, repr(value)[:80])
            assert r.reason, (name, repr(value)[:80])
            refused += 1
        # The current value: accepted unless read-only.
        res = ros.call(SetParameters, f'{NODE}/set_parameters', SetParameters.Request(
            parameters=[param_msg(name, before[name][1])]))
        tried += 1
        assert res.results[0].successful != descs[name].read_only, (name,
                                                                    res.results[0].reason)
        accepted += res.results[0].successful
        refused += not res.results[0].successful
    # All or nothing: one bad member refuses the batch.
    batches = [[('mu_k', 0.1), ('backlash', float('nan'))],
               [('mu_k', 0.1), ('record_prefix', 'a/b')],
               [('mu_k', 0.1), ('pitch', 0.004)],
               [('command_timeout', 1.0), ('max_torque', 1e308)],
               [('mu_k', 0.1), ('mu_s', 0.12), ('contact_stiffness', 1e11), ('nut_mass', 1e-6),
                ('payload_mass', 0.0)]]
    for batch in batches:
        res = ros.call(SetParametersAtomically, f'{NODE}/set_parameters_atomically',
                       SetParametersAtomically.Request(
                           parameters=[param_msg(n, v) for n, v in batch]))
        tried += 1
        refused += 1
        assert not res.result.successful, batch
    after = get_all()
    assert after == before
    # An integer for a floating-point parameter is that number, stored as a double.
    res = ros.call(SetParameters, f'{NODE}/set_parameters', SetParameters.Request(
        parameters=[param_msg('backlash', 0), param_msg('mu_k', -1)]))
    assert res.results[0].successful, res.results[0].reason
    assert not res.results[1].successful
    assert 'mu_k' in res.results[1].reason and '-1.0' in res.results[1].reason
    r = ros.call(GetParameters, f'{NODE}/get_parameters', GetParameters.Request(
        names=['backlash']))
    assert (r.values[0].type, r.values[0].double_value) == (ParameterType.PARAMETER_DOUBLE, 0.0)
    tried += 2
    accepted += 1
    refused += 1
    n = len(states)
    wait_states(ros, states, proc, n + 200, timeout=10.0)
    assert proc.proc.poll() is None
    assert all(finite_state(s) for s in states[-200:])
    print(f'parameters: {len(names)} declared ({len(read_only)} read-only: '
          f'{", ".join(read_only)}); {tried} sets tried, {refused} refused, '
          f'{accepted} accepted (current values, NUL-truncated prefix)')


# ---------------------------------------------------------------------------
# 4. Physically extreme but valid parameter sets at start-up
# ---------------------------------------------------------------------------

#: (label, -p overrides). tan(lambda) of 'lead_45deg': 11 starts x 3 mm lead over
#: pi x 10.5 mm pitch diameter = 1.0004.
EXTREME_SETS = [
    ('stiff_contact', {'contact_stiffness': 1e11}),
    ('tiny_masses', {'nut_mass': 1e-6, 'payload_mass': 0.0}),
    ('stiff_and_tiny', {'contact_stiffness': 1e11, 'nut_mass': 1e-6, 'payload_mass': 0.0}),
    ('zero_backlash', {'backlash': 0.0}),
    ('huge_backlash', {'backlash': 0.9 * PRESET.pitch}),
    ('frictionless', {'mu_s': 0.0, 'mu_k': 0.0}),
    ('lead_45deg', {'starts': 11, 'mu_s': 0.05, 'mu_k': 0.04}),
    ('lead_45deg_jams', {'starts': 11, 'mu_s': 1.0, 'mu_k': 0.9}),
    ('tiny_substep', {'substep': 1e-9}),
    ('slow_and_stiff', {'update_rate': 1.0, 'contact_stiffness': 1e11}),
    ('fast_20kHz', {'update_rate': 20000.0}),
    ('small_masses', {'nut_mass': 1e-4, 'payload_mass': 0.0, 'contact_damping': 20.0}),
    ('velocity_weakening', {'mu_viscous': -100.0, 'stribeck_velocity': 1e-6}),
    ('stiff_end_stops', {'end_stop_stiffness': 1e11, 'end_stop_damping': 0.0,
                         'initial_position': PRESET.stroke_max}),
]


def expected_start(overrides):
    """Return (None, nsub) if the set must run, else (parameter named, None)."""
    from leadscrew_sim.core.engine.packing import auto_substep, MAX_SUBSTEPS_PER_STEP
    from leadscrew_sim.core.params import ParameterError
    phys = {k: v for k, v in overrides.items() if k != 'update_rate'}
    try:
        p = ScrewParams.from_dict(phys, base=PRESET)
    except ParameterError as exc:
        return exc.name, None
    dt = 1.0 / overrides.get('update_rate', 1000.0)
    n = math.ceil(dt / auto_substep(p) - 1e-9)
    if n > MAX_SUBSTEPS_PER_STEP:
        return ('substep' if p.substep and dt / p.substep > MAX_SUBSTEPS_PER_STEP
                else 'contact_stiffness'), None
    return None, n


@pytest.mark.timeout(240)
def test_extreme_parameter_sets_run_finite_or_refuse_in_one_line(run_exe, ros):
    def start(label, overrides):
        # Each set in its own namespace: no late message of a previous node counts.
        args = ['--ros-args', '-r', f'__ns:=/{label}', '-p', 'record:=false']
        for k, v in overrides.items():
            args += ['-p', f'{k}:={v!r}']
        return run_exe('leadscrew_sim.node', *args, name=label)

    results = []
    # Start the refusals together: they exit before publishing anything.
    refusals = {}
    for label, ov in EXTREME_SETS:
        name, _n = expected_start(ov)
        if name is not None:
            refusals[label] = (name, start(label, ov))
    for label, (name, proc) in refusals.items():
        rc = proc.wait(timeout=60)
        out = proc.output()
        lines = [ln for ln in out.splitlines() if ln.strip()]
        print(f'extreme {label}: exit {rc}: {lines[-1] if lines else ""}')
        assert rc == 2, out
        assert 'Traceback' not in out, out
        errors = [ln for ln in lines if 'error' in ln.lower()]
        assert len(errors) == 1 and f"parameter '{name}'" in errors[0], out
        results.append((label, 'refused'))
    for label, ov in EXTREME_SETS:
        if label in refusals:
            continue
        _name, nsub = expected_start(ov)
        states = ros.collect(JointState, f'/{label}/axis/joint_states')
        proc = start(label, ov)
        wait_states(ros, states, proc, timeout=60.0)
        first = time.monotonic()
        ros.spin_for(1.0)
        ros.spin_until(lambda: len(states) >= 10, 10.0)
        span = (stamp_ns(states[-1]) - stamp_ns(states[0])) / NS
        print(f'extreme {label}: {nsub} substeps/step, {len(states)} joint_states over '
              f'{time.monotonic() - first:.2f} s wall ({span:.3f} s sim)')
        assert len(states) >= 10, proc.output()
        assert all(finite_state(s) for s in states), label
        assert proc.proc.poll() is None, proc.output()
        assert proc.stop() == 0
        assert 'Traceback' not in Path(proc.log_path).read_text(errors='replace')
        results.append((label, 'ran'))
    print(f'extreme sets: {len(results)} tried: {results}')


# ---------------------------------------------------------------------------
# 5. Recording faults
# ---------------------------------------------------------------------------

def record_node(run_exe, directory, *params, prefix='hard'):
    """Start a recording node writing <directory>/<prefix>_*.mcap."""
    return run_exe('leadscrew_sim.node', '--ros-args', '-p', f'record_dir:={directory}',
                   '-p', f'record_prefix:={prefix}', *(a for p in params for a in ('-p', p)))


def wait_recording_error(ros, diags, proc, timeout):
    """Wait for a diagnostics message with recording_error set; return its values."""
    def err():
        return diags and diag_values(diags[-1]).get('recording_error')
    assert ros.spin_until(lambda: err() or proc.proc.poll() is not None, timeout), \
        (diags and diag_values(diags[-1]), proc.output()[-3000:])
    assert proc.proc.poll() is None, proc.output()
    return diag_values(diags[-1])


@pytest.mark.timeout(90)
def test_unusable_record_dir_keeps_simulating(run_exe, ros, tmp_path):
    blocker = tmp_path / 'a_file'
    blocker.write_text('not a directory')
    for i, directory in enumerate((blocker / 'sub', '/proc/leadscrew_sim_no_such_dir')):
        states = ros.collect(JointState, f'/rec{i}/axis/joint_states')
        diags = ros.collect(DiagnosticArray, f'/rec{i}/diagnostics', qos=10)
        proc = run_exe('leadscrew_sim.node', '--ros-args', '-r', f'__ns:=/rec{i}',
                       '-p', f'record_dir:={directory}')
        wait_states(ros, states, proc)
        values = wait_recording_error(ros, diags, proc, 20.0)
        status = diags[-1].status[0]
        print(f'record_dir {directory}: diagnostics level {status.level[0]} '
              f'"{status.message}"')
        assert status.level == b'\x01' and 'recording' in status.message
        assert values['recording'] == 'False' or values['recording_file'] == ''
        n = len(states)
        wait_states(ros, states, proc, n + 500, timeout=10.0)
        assert all(finite_state(s) for s in states)
        assert proc.stop() == 0
    assert blocker.read_text() == 'not a directory'


@pytest.fixture
def tiny_fs(tmp_path):
    """Yield a directory on a 200 KiB tmpfs; skip if mounting is not allowed."""
    mnt = tmp_path / 'tiny'
    mnt.mkdir()
    r = subprocess.run(['mount', '-t', 'tmpfs', '-o', 'size=200k', 'tmpfs', str(mnt)],
                       capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f'cannot mount a tmpfs: {r.stderr.strip()}')
    try:
        yield mnt
    finally:
        subprocess.run(['umount', '-l', str(mnt)], capture_output=True)


@pytest.mark.timeout(120)
def test_disk_full_keeps_publishing_and_leaves_a_recoverable_file(run_exe, ros, tiny_fs,
                                                                  tmp_path):
    states = ros.collect(JointState, 'axis/joint_states')
    diags = ros.collect(DiagnosticArray, 'diagnostics', qos=10)
    proc = record_node(run_exe, tiny_fs, 'record_flush_interval:=0.2')
    wait_states(ros, states, proc)
    values = wait_recording_error(ros, diags, proc, 60.0)
    print(f'disk full after {len(states)} joint_states: {values["recording_error"]}')
    assert 'No space left' in values['recording_error'] or 'ENOSPC' in \
        values['recording_error'], values
    n = len(states)
    wait_states(ros, states, proc, n + 1000, timeout=10.0)
    assert all(finite_state(s) for s in states)
    assert proc.stop() == 0
    files = sorted(tiny_fs.glob('hard_*.mcap'))
    assert len(files) == 1, files
    with open(files[0], 'rb') as f:
        try:
            complete = make_reader(f).get_summary() is not None
        except Exception:  # noqa: B902 - a cut file may raise anything
            complete = False
    fixed = tmp_path / 'fixed.mcap'
    n = len(recover(files[0], fixed).messages)
    with open(fixed, 'rb') as f:
        got = [(c.topic, m.log_time) for _s, c, m in make_reader(f).iter_messages(
            log_time_order=False)]
    js = [t for topic, t in got if topic == '/axis/joint_states']
    print(f'disk full: file of {files[0].stat().st_size} B, summary {complete}, '
          f'recover() got {n} messages, {len(js)} joint_states')
    assert n == len(got) > 0 and len(js) > 100
    assert {b - a for a, b in zip(js, js[1:])} == {MS}


#: Flush interval of the SIGKILL test [s] and what is allowed on top: pipe and
#: child process scheduling on 2 shared cores, a chunk compression stall.
KILL_FLUSH = 0.5
KILL_MARGIN = 0.5


@pytest.mark.timeout(90)
def test_sigkill_mid_recording_recovers_up_to_the_flush_bound(run_exe, ros, tmp_path):
    states = ros.collect(JointState, 'axis/joint_states')
    proc = record_node(run_exe, tmp_path / 'rec', f'record_flush_interval:={KILL_FLUSH}')
    wait_states(ros, states, proc)
    ros.spin_for(3.0)
    os.killpg(proc.proc.pid, signal.SIGKILL)         # the node and its recorder child
    proc.wait(timeout=10)
    kill = stamp_ns(states[-1])
    files = sorted((tmp_path / 'rec').glob('hard_*.mcap'))
    assert len(files) == 1, files
    fixed = tmp_path / 'fixed.mcap'
    n = len(recover(files[0], fixed).messages)
    with open(fixed, 'rb') as f:
        js = sorted(m.log_time for _s, c, m in make_reader(f).iter_messages(
            log_time_order=False) if c.topic == '/axis/joint_states')
    bound = kill - int((KILL_FLUSH + KILL_MARGIN) * NS)
    print(f'SIGKILL: recover() got {n} messages; joint_states up to '
          f'{(kill - js[-1]) / NS:.3f} s before the last one seen live '
          f'(bound {KILL_FLUSH} + {KILL_MARGIN} s)')
    assert js[-1] >= bound
    live = {stamp_ns(s) for s in states if stamp_ns(s) < bound}
    assert live <= set(js)


# ---------------------------------------------------------------------------
# 6. Recording path safety
# ---------------------------------------------------------------------------

#: <prefix>_<YYYYmmdd-HHMMSS>_<NNN>.mcap, the names a RecordingSession generates.
FILE_RE = re.compile(PREFIX_RE.pattern.rstrip('$') + r'_\d{8}-\d{6}_\d{3}\.mcap$')


def tree(*roots):
    """Return the set of files under some directories (missing ones are empty)."""
    out = set()
    for root in roots:
        for dirpath, _dirs, files in os.walk(root):
            out.update(os.path.join(dirpath, f) for f in files)
    return out


@pytest.mark.timeout(90)
def test_record_path_parameters_cannot_escape_the_directory(run_exe, ros, tmp_path):
    rec = tmp_path / 'work' / 'rec'
    watched = [tmp_path, '/etc', '/tmp/x']
    before = tree(*watched[1:])
    states = ros.collect(JointState, 'axis/joint_states')
    proc = record_node(run_exe, rec, prefix='safe')
    wait_states(ros, states, proc)
    tried = 0
    for name in ('record_dir', 'record_prefix'):
        for value in BAD_RECORD_NAMES + [str(tmp_path), '/tmp/x']:
            if name == 'record_prefix' and value in ('a\x00b',):
                continue                    # arrives as 'a' (CDR strings end at NUL)
            res = ros.call(SetParameters, f'{NODE}/set_parameters',
                           SetParameters.Request(parameters=[param_msg(name, value)]))
            tried += 1
            assert not res.results[0].successful, (name, value)
    # A valid prefix is taken at the next start of the recording.
    assert ros.call(SetParameters, f'{NODE}/set_parameters', SetParameters.Request(
        parameters=[param_msg('record_prefix', 'safe2')])).results[0].successful
    # Message content never names a file.
    jpub = command_publisher(ros, 'axis/joint_commands', JointState)
    for name in ('../../etc/evil', '/tmp/x/evil', 'a/b', 'evil\n', '$(touch /tmp/x/e)'):
        jpub.publish(JointState(name=[name, 'screw_joint'], effort=[0.0, 0.01]))
        ros.spin_for(0.02)
    for on in (False, True, False, True):
        res = ros.call(SetBool, f'{NODE}/record', SetBool.Request(data=on))
        assert res.success, res.message
    ros.spin_for(0.5)
    assert proc.stop() == 0
    files = tree(tmp_path)
    names = sorted(os.path.basename(f) for f in files if f.endswith('.mcap'))
    print(f'path safety: {tried} record_dir/record_prefix values refused; files: {names}')
    assert all(os.path.dirname(f) == str(rec) for f in files if not f.endswith('.log'))
    assert all(FILE_RE.match(n) for n in names), names
    assert sum(n.startswith('safe_') for n in names) == 1
    assert sum(n.startswith('safe2_') for n in names) == 2
    assert tree(*watched[1:]) == before
