"""
The realtime node's stamps against the system clock, at the start and after a stall.

The node runs as a real process; a subscriber in this process stamps each
``axis/joint_states`` with ``time.time_ns()`` (the system clock, CLOCK_REALTIME,
the clock the node's ROS time reads) when it arrives. The arrival is after the
tick (DDS delivery), so ``arrival - stamp`` bounds the stamp's error from above:
its minimum over a window (the fastest delivery: the stamp's offset from the
clock plus the least transport time) must be below 1 ms, no stamp may lie in
the future of its arrival, and its lower decile stays within a few ms (on a
loaded host this process is often late to take a message, which only adds).
The stall is real: the process is stopped (SIGSTOP) for 1.5 s.
Oracles: the system clock; the recording read by the mcap library (every step
recorded, one dt apart); ``resim`` reproducing the run bit for bit.
"""
import signal
import statistics
import time

from helpers import cli_ok, stamp_ns, start_node, wait_states
from mcap.reader import make_reader
import pytest
from sensor_msgs.msg import JointState

MS = 1_000_000


def arrivals(ros, topic):
    """Subscribe to ``topic``; return the list of (arrival time.time_ns(), stamp [ns])."""
    got = []
    ros.node.create_subscription(JointState, topic,
                                 lambda m: got.append((time.time_ns(), stamp_ns(m))), 100)
    return got


def lags_ms(pairs):
    """Return arrival - stamp [ms] of (arrival, stamp) pairs."""
    return [(a - s) / MS for a, s in pairs]


def decile(values):
    """Return the lower decile of values."""
    return statistics.quantiles(values, n=10)[0]


@pytest.mark.timeout(240)
def test_stamps_stay_on_the_system_clock_through_a_stall(run_exe, ros, tmp_path):
    """Stamps within 1 ms of the clock at start and after a 1.5 s SIGSTOP; every step recorded."""
    from diagnostic_msgs.msg import DiagnosticArray
    proc = start_node(run_exe, f'record_dir:={tmp_path}', 'record_prefix:=clk', record=True)
    got = arrivals(ros, 'axis/joint_states')
    diags = ros.collect(DiagnosticArray, 'diagnostics')
    wait_states(ros, got, proc, timeout=60.0)
    ros.spin_for(0.5)
    del got[:]
    ros.spin_for(2.0)
    before = lags_ms(got)
    assert len(before) > 1000, proc.output()
    # A stamp offset from the clock (t0 taken apart from the loop's start) would show in
    # every message. Delivery plus stamp error is 0.2-0.4 ms on a quiet host; a stamp
    # never lies ahead of its arrival.
    assert min(before) < 1.0 and decile(before) < 5.0, (min(before), decile(before))
    assert min(before) > -0.05, min(before)

    proc.send(signal.SIGSTOP)
    time.sleep(1.5)
    proc.send(signal.SIGCONT)
    ros.spin_for(1.0)
    del got[:]
    ros.spin_for(2.0)
    after = lags_ms(got)
    print(f'arrival - stamp before the stall: min {min(before):.3f} ms, decile '
          f'{decile(before):.3f} ms, median {statistics.median(before):.3f} ms; after: min '
          f'{min(after):.3f} ms, decile {decile(after):.3f} ms, median '
          f'{statistics.median(after):.3f} ms')
    # a stall's missed ticks, shifted instead of integrated, would add its length here
    assert min(after) < 1.0 and decile(after) < 5.0, (min(after), decile(after))
    assert min(after) > -0.05, min(after)
    assert ros.spin_until(lambda: diags and int(
        {kv.key: kv.value for kv in diags[-1].status[0].values}['skipped_steps']) > 0, 5.0)
    values = {kv.key: kv.value for kv in diags[-1].status[0].values}
    # the stall's steps beyond the catch-up budget were counted, not hidden
    assert int(values['skipped_steps']) >= 1500 - 2 * (1 + 10) - 100, values
    assert int(values['overruns']) >= 1
    log = proc.output()
    assert 'loop stalled' in log, log
    assert proc.stop(signal.SIGINT, timeout=30.0) == 0, proc.output()

    path, = tmp_path.glob('clk_*.mcap')
    with open(path, 'rb') as fh:
        stamps = [m.log_time for _s, c, m in make_reader(fh).iter_messages()
                  if c.topic == '/sim/joint_states']
    dt = MS                             # update_rate 1000 Hz, the default
    # every step recorded, the stall's included: one dt apart, no gap, no shift
    gaps = {b - a for a, b in zip(stamps, stamps[1:])}
    assert gaps == {dt}, sorted(gaps)[:5]
    r = cli_ok('resim', path, '--output', tmp_path / 'clk.resim.mcap', '--quiet')
    assert '(bit-identical)' in r.stdout, r.stdout
