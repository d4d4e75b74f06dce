"""
Benchmark the node's real-time loop against the machine's noise floor.

Run: .venv/bin/python bench/bench_node.py [--duration 60] [--rate 1000] [--sensors | --foxglove]
(with AMENT_PREFIX_PATH and NUMBA_CACHE_DIR set as in the Makefile).

With ``--foxglove`` the runs are the node with ``foxglove_port`` 0 (is the
SDK loaded at all: /proc/<pid>/maps), the node serving Foxglove with no
client, and the node serving one client subscribed to every channel (a
separate process, ``--client``, reading every frame with websocket-client).

With ``--sensors`` the two runs are the node with every sensor model on
(:data:`SENSOR_MODELS`: encoder counts, noise and bias, a linear scale with its
resolution, noise and bias, the velocity filter, state and command delays)
and the same node with ideal sensors, instead of the node and the bare loop.

In one run, one after the other, for ``--duration`` s each:
1. ``leadscrew_sim_node`` (realtime, recording on, ``stats_file`` set);
2. a bare rclpy loop (``--bare``): the same clock_nanosleep absolute-deadline
   loop, one spin_once(0) of an EventsExecutor and one JointState published
   per tick, effort = the last torque_command (the noise floor).

For both it measures: achieved rate (ticks / wall time, and messages / s at
the subscriber), p50/p99/max of the tick start's lateness behind its
deadline, overruns, CPU share (/proc/<pid>/stat, recorder child separately)
and the command -> state latency: this process publishes a new torque every
100 ms with its send time and waits for the first axis/joint_states whose effort
equals it (p50/p99). Prints both side by side with ratios.
"""
import argparse
import json
import os
import signal
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
NS = 1_000_000_000

#: The sensor models of ``--sensors``: every one on.
SENSOR_MODELS = dict(encoder_counts=4096, encoder_noise=2e-4, encoder_bias=1e-4,
                     scale_resolution=1e-6, scale_noise=2e-7, scale_bias=1e-6,
                     velocity_filter_time=1e-3, sensor_seed=7, state_delay=2, command_delay=1)


def cpu_seconds(pid):
    """Return utime + stime [s] of a process, or None."""
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def children(pid):
    """Return the child pids of a process."""
    out = []
    for task in Path(f'/proc/{pid}/task').glob('*'):
        try:
            out += [int(c) for c in (task / 'children').read_text().split()]
        except OSError:
            pass
    return out


def isolate_ros_env():
    """Put the repo on PYTHONPATH and keep DDS on localhost in a domain of our own."""
    os.environ['PYTHONPATH'] = os.pathsep.join(
        [str(REPO)] + [p for p in os.environ.get('PYTHONPATH', '').split(os.pathsep) if p])
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.pop('ROS_LOCALHOST_ONLY', None)
    if not os.environ.get('ROS_DOMAIN_ID'):
        os.environ['ROS_DOMAIN_ID'] = str(101 + os.getpid() % 100)


def pct(values, q):
    """Nearest-rank percentile."""
    if not values:
        return float('nan')
    s = sorted(values)
    return s[min(len(s) - 1, max(0, int(round(q / 100.0 * len(s) + 0.5)) - 1))]


# ---------------------------------------------------------------------------
# The bare loop (noise floor)
# ---------------------------------------------------------------------------

def bare_loop(rate, stats_path):
    """Publish one JointState per tick with the node's timing loop; write stats at SIGINT."""
    import rclpy
    from rclpy.serialization import deserialize_message, serialize_message
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    from leadscrew_sim.ros.diagnostics import stamp_msg
    from leadscrew_sim.ros.node import COMMAND_QOS, make_executor, STATE_QOS
    from leadscrew_sim.ros.timing import DeadlineSleeper, percentiles

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bare_loop')
    held = {'torque': 0.0}

    def on_cmd(data):
        held['torque'] = deserialize_message(data, Float64).data

    node.create_subscription(Float64, 'torque_command', on_cmd, COMMAND_QOS, raw=True)
    pub = node.create_publisher(JointState, 'axis/joint_states', STATE_QOS)   # as the node
    ex = make_executor()
    ex.add_node(node)
    running = {'on': True}
    signal.signal(signal.SIGINT, lambda *_: running.update(on=False))
    signal.signal(signal.SIGTERM, lambda *_: running.update(on=False))
    period = int(round(NS / rate))
    sleeper = DeadlineSleeper()
    t0 = node.get_clock().now().nanoseconds
    msg = JointState(name=['screw_joint', 'nut_joint'])
    lateness = []
    n = 0
    start = time.monotonic_ns()
    deadline = start + period
    while running['on']:
        sleeper.sleep_until(deadline)
        now = time.monotonic_ns()
        if now < deadline:
            continue
        lateness.append(now - deadline)
        ex.spin_once(timeout_sec=0)
        due = 1 + (now - deadline) // period
        for _ in range(due):
            n += 1
            msg.header.stamp = stamp_msg(t0 + n * period)
            msg.position = [0.0, 0.0]
            msg.velocity = [0.0, 0.0]
            msg.effort = [held['torque'], 0.0]
            pub.publish(serialize_message(msg))
        deadline += due * period
    elapsed = (time.monotonic_ns() - start) / NS
    p = percentiles(lateness)
    Path(stats_path).write_text(json.dumps(dict(
        ticks=len(lateness), steps=n, elapsed_s=elapsed, achieved_rate=n / elapsed,
        lateness_p50_ns=p['p50'], lateness_p99_ns=p['p99'], lateness_max_ns=p['max'],
        overruns=0, late_ticks=sum(1 for x in lateness if x >= period))))
    node.destroy_node()
    rclpy.shutdown()


# ---------------------------------------------------------------------------
# Measurement (this process)
# ---------------------------------------------------------------------------

def foxglove_client(port, duration, stats_path):
    """Subscribe to every channel of a Foxglove server, read every frame for duration s."""
    import websocket
    end = time.monotonic() + 60
    while True:
        try:
            ws = websocket.create_connection(f'ws://127.0.0.1:{port}', timeout=5.0,
                                             subprotocols=['foxglove.sdk.v1'])
            break
        except (OSError, websocket.WebSocketException):
            if time.monotonic() > end:
                raise
            time.sleep(0.2)
    channels = {}
    t_adv = time.monotonic() + 2.0
    while time.monotonic() < t_adv:               # serverInfo, advertise
        ws.settimeout(0.5)
        try:
            opcode, frame = ws.recv_data()
        except websocket.WebSocketTimeoutException:
            continue
        if opcode == websocket.ABNF.OPCODE_TEXT:
            msg = json.loads(frame)
            if msg['op'] == 'advertise':
                channels.update({c['id']: c['topic'] for c in msg['channels']})
    subs = {i + 1: topic for i, topic in enumerate(channels.values())}
    ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
        {'id': sub, 'channelId': cid} for sub, cid in zip(subs, channels)]}))
    counts = dict.fromkeys(subs.values(), 0)
    nbytes = 0
    ws.settimeout(1.0)
    t0, cpu0 = time.monotonic(), time.process_time()
    while time.monotonic() - t0 < duration:
        try:
            opcode, frame = ws.recv_data()
        except websocket.WebSocketTimeoutException:
            continue
        if opcode == websocket.ABNF.OPCODE_BINARY and frame[:1] == b'\x01':
            counts[subs[struct.unpack_from('<I', frame, 1)[0]]] += 1
            nbytes += len(frame)
    wall = time.monotonic() - t0
    Path(stats_path).write_text(json.dumps(dict(
        topics=len(subs), cpu=(time.process_time() - cpu0) / wall,
        messages_per_s=sum(counts.values()) / wall,
        bytes_per_s=nbytes / wall, per_topic={t: n / wall for t, n in counts.items()})))
    ws.close()


def maps_foxglove(pid):
    """Return True if the process has the Foxglove SDK's library mapped."""
    try:
        return '_foxglove_py' in Path(f'/proc/{pid}/maps').read_text()
    except OSError:
        return None


def measure(argv, stats_path, duration, label, client=None):
    """
    Start argv, probe it for duration s, stop it with SIGINT; return the results.

    ``client``: (port, stats path) of a Foxglove client process to run meanwhile.
    """
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    proc = subprocess.Popen(argv, cwd=REPO, start_new_session=True)
    ctx = Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node(f'bench_probe_{os.getpid()}', context=ctx)
    received = []
    pending = {}
    latencies = []
    eff_off = {}

    def effort0(data):
        # The screw joint's effort is the first double of the last sequence: find it once.
        off = eff_off.get(len(data))
        if off is None:
            from rclpy.serialization import deserialize_message
            m = deserialize_message(data, JointState)
            tail = struct.pack('<2d', *m.effort)
            off = data.rfind(tail)
            eff_off[len(data)] = off
        return struct.unpack_from('<d', data, off)[0]

    def on_state(data):
        t = time.monotonic_ns()
        received.append(t)
        if pending:
            e = effort0(data)
            sent = pending.pop(e, None)
            if sent is not None:
                latencies.append(t - sent)

    node.create_subscription(JointState, 'axis/joint_states', on_state,
                             QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE),
                             raw=True)
    pub = node.create_publisher(Float64, 'torque_command', 10)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    try:
        end = time.monotonic() + 60
        while (not received or pub.get_subscription_count() == 0) and time.monotonic() < end:
            ex.spin_once(timeout_sec=0.01)
            if proc.poll() is not None:
                raise RuntimeError(f'{label} exited with code {proc.returncode}')
        client_proc = None
        if client is not None:
            client_proc = subprocess.Popen(
                [sys.executable, str(Path(__file__).resolve()), '--client', str(client[0]),
                 '--stats', str(client[1]), '--duration', str(duration + 4.0)])
        settle = time.monotonic() + (6.0 if client is not None else 2.0)
        while time.monotonic() < settle:
            ex.spin_once(timeout_sec=0.01)
        foxglove_loaded = maps_foxglove(proc.pid)
        kids = children(proc.pid)
        cpu0 = cpu_seconds(proc.pid)
        kcpu0 = {k: cpu_seconds(k) for k in kids}
        received.clear()
        t_start = time.monotonic()
        k = 0
        next_cmd = t_start
        while time.monotonic() - t_start < duration:
            now = time.monotonic()
            if now >= next_cmd:
                k += 1
                value = 0.01 + (k % 50) * 1e-4            # small: the nut stays put
                pending.clear()
                pending[value] = time.monotonic_ns()
                pub.publish(Float64(data=value))
                next_cmd += 0.1
            ex.spin_once(timeout_sec=0.001)
        wall = time.monotonic() - t_start
        cpu = (cpu_seconds(proc.pid) - cpu0) / wall
        kcpu = sum((cpu_seconds(c) or 0.0) - (v or 0.0) for c, v in kcpu0.items()) / wall
        sub_rate = (len(received) - 1) / ((received[-1] - received[0]) / NS)
        if client_proc is not None:
            client_proc.wait(timeout=30)
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
        ex.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
    stats = json.loads(Path(stats_path).read_text())
    out = dict(label=label, stats=stats, cpu=cpu, child_cpu=kcpu, sub_rate=sub_rate,
               lat_p50=pct(latencies, 50), lat_p99=pct(latencies, 99),
               lat_n=len(latencies), commands=k, foxglove_loaded=foxglove_loaded)
    if client is not None:
        out['client'] = json.loads(Path(client[1]).read_text())
    return out


def report(node, bare, names=('node', 'bare loop')):
    """Print the two runs side by side."""
    rows = [
        ('achieved rate (loop) [Hz]', lambda r: r['stats']['achieved_rate'], '{:.2f}'),
        ('rate at subscriber [Hz]', lambda r: r['sub_rate'], '{:.2f}'),
        ('tick lateness p50 [us]', lambda r: r['stats']['lateness_p50_ns'] / 1e3, '{:.1f}'),
        ('tick lateness p99 [us]', lambda r: r['stats']['lateness_p99_ns'] / 1e3, '{:.1f}'),
        ('tick lateness max [us]', lambda r: r['stats']['lateness_max_ns'] / 1e3, '{:.1f}'),
        ('late ticks (>= 1 period)', lambda r: r['stats']['late_ticks'], '{}'),
        ('overruns', lambda r: r['stats']['overruns'], '{}'),
        ('CPU share [% of one core]', lambda r: 100 * r['cpu'], '{:.1f}'),
        ('  recorder child CPU [%]', lambda r: 100 * r['child_cpu'], '{:.1f}'),
        ('cmd->state latency p50 [us]', lambda r: r['lat_p50'] / 1e3, '{:.1f}'),
        ('cmd->state latency p99 [us]', lambda r: r['lat_p99'] / 1e3, '{:.1f}'),
        ('latency samples', lambda r: r['lat_n'], '{}'),
    ]
    print(f'{"":32s}{names[0]:>14s}{names[1]:>14s}{"ratio":>10s}')
    for name, get, fmt in rows:
        a, b = get(node), get(bare)
        try:
            ratio = f'{a / b:.2f}' if b else '-'
        except TypeError:
            ratio = '-'
        print(f'{name:32s}{fmt.format(a):>14s}{fmt.format(b):>14s}{ratio:>10s}')


def foxglove_runs(node_argv, node_stats, tmp, duration):
    """Run the node without Foxglove, serving it idle, serving one client; print the three."""
    import socket
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        port = s.getsockname()[1]
    served_argv = node_argv + ['-p', f'foxglove_port:={port}']
    off = measure(node_argv, node_stats, duration, 'foxglove_port 0')
    idle = measure(served_argv, node_stats, duration, 'served, no client')
    one = measure(served_argv, node_stats, duration, 'served, 1 client',
                  client=(port, tmp / 'client.json'))
    print('\nfoxglove_port 0 vs served with no client:')
    report(off, idle, ('port 0', 'no client'))
    print('\nserved with one client subscribed to every channel vs foxglove_port 0:')
    report(one, off, ('1 client', 'port 0'))
    c = one['client']
    print(f'\nSDK library mapped: port 0 {off["foxglove_loaded"]}, no client '
          f'{idle["foxglove_loaded"]}, 1 client {one["foxglove_loaded"]}')
    print(f'client: {c["topics"]} topics, {c["messages_per_s"]:.0f} messages/s, '
          f'{c["bytes_per_s"] / 1e6:.2f} MB/s; /axis/joint_states '
          f'{c["per_topic"].get("/axis/joint_states", 0.0):.1f} /s; the client process itself '
          f'{100 * c["cpu"]:.1f} % of a core')
    print(f'CPU rise with the client: {100 * (one["cpu"] - off["cpu"]):+.1f} % of a core '
          f'(served idle: {100 * (idle["cpu"] - off["cpu"]):+.1f} %)')
    return 0


def main():
    """Run both measurements and print the comparison."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--duration', type=float, default=60.0)
    ap.add_argument('--rate', type=float, default=1000.0)
    ap.add_argument('--preset', default='tr12x3')
    ap.add_argument('--sensors', action='store_true', help='compare the node with every '
                    'sensor model on against the node with ideal sensors')
    ap.add_argument('--foxglove', action='store_true', help='compare the node with '
                    'foxglove_port 0, serving Foxglove without a client, and serving one '
                    'client subscribed to every channel')
    ap.add_argument('--bare', action='store_true', help=argparse.SUPPRESS)
    ap.add_argument('--client', type=int, help=argparse.SUPPRESS)
    ap.add_argument('--stats', help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.bare:
        bare_loop(args.rate, args.stats)
        return 0
    if args.client:
        foxglove_client(args.client, args.duration, args.stats)
        return 0
    isolate_ros_env()
    tmp = Path(tempfile.mkdtemp(prefix='bench_node_'))
    node_stats, bare_stats = tmp / 'node.json', tmp / 'bare.json'
    node_argv = [sys.executable, '-m', 'leadscrew_sim.node', '--ros-args',
                 '-p', f'preset:={args.preset}', '-p', f'update_rate:={args.rate}',
                 '-p', f'stats_file:={node_stats}', '-p', 'record:=true',
                 '-p', f'record_dir:={tmp / "runs"}', '-p', 'command_timeout:=0.0']
    bare_argv = [sys.executable, str(Path(__file__).resolve()), '--bare',
                 '--rate', str(args.rate), '--stats', str(bare_stats)]
    print(f'bench_node: {args.duration:g} s each at {args.rate:g} Hz, preset {args.preset}, '
          f'recording on; {os.cpu_count()} CPUs; files in {tmp}', flush=True)
    if args.sensors:
        real_stats = tmp / 'sensors.json'
        real_argv = [a.replace(str(node_stats), str(real_stats)) for a in node_argv]
        for name, value in SENSOR_MODELS.items():
            real_argv += ['-p', f'{name}:={value}']
        real = measure(real_argv, real_stats, args.duration, 'sensors on')
        ideal = measure(node_argv, node_stats, args.duration, 'ideal')
        report(real, ideal, ('sensors on', 'ideal'))
        return 0
    if args.foxglove:
        return foxglove_runs(node_argv, node_stats, tmp, args.duration)
    node = measure(node_argv, node_stats, args.duration, 'node')
    bare = measure(bare_argv, bare_stats, args.duration, 'bare loop')
    report(node, bare)
    rec = sorted((tmp / 'runs').glob('*.mcap'))
    if rec:
        print(f'recording: {rec[-1]} ({rec[-1].stat().st_size} B)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
