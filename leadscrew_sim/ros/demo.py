"""
Demo: start the node and drive the nut up and down with torque pulses.

``python -m leadscrew_sim.cli.demo --preset tr12x3 --duration 0`` (``make
run``; the flags are parsed there, :func:`run` takes them as keywords)
starts ``leadscrew_sim_node`` as a child process, publishes a slow pulse
pattern on ``torque_command`` and prints, every 0.5 s, the time, the
commanded torque, the nut position [mm] and the thread contact state.
Between pulses it commands the torque in the middle of the holding band, so
a self-locking screw stands still; each pulse exceeds the raising or
lowering threshold by 15 % for 0.1 s and the nut steps by a few mm toward a
target of +20 mm or -20 mm, then turns around. A stepper axis (``drive_type``
stepper, e.g. ``--preset nema17_tr8x8``) takes no torque: the demo sends it
``position_command`` targets STEP_MM further every pulse period instead.
Ctrl-C (or the duration) stops the demo and the node.
"""
import math
import os
import signal
import subprocess
import sys
import time

DEFAULT_DOMAIN_ID = '42'
PULSE_PERIOD = 0.5          # s
PULSE_LENGTH = 0.1          # s
PULSE_GAIN = 1.15           # pulse torque beyond the threshold, relative
TARGET = 0.02               # m, turn-around points +-TARGET
PRINT_PERIOD = 0.5          # s
STEP_MM = 2.0               # mm, the stepper's move per pulse period


def torque_band(params):
    """
    Return (hold, half_width) [N m] of the static holding band (theta sense).

    Raising a load W along +x needs W r tan(lambda + phi), lowering it
    W r tan(phi - lambda) (negative: the load back-drives the screw); a
    torque between the two holds the nut. A right-hand thread moves the
    nut toward -x for a positive torque (doc/model.md section 3).
    """
    p = params
    load = p.moving_mass * p.gravity * math.sin(p.inclination) - p.external_force
    phi = math.atan(p.mu_s * p.thread_factor)
    lam = p.lead_angle
    t_raise = load * p.r_m * math.tan(lam + phi)
    t_lower = load * p.r_m * math.tan(phi - lam)
    hs = p.hand_sign                 # torque sign that moves the nut toward +x
    hold = hs * (t_raise - t_lower) / 2.0
    half = max(abs(t_raise + t_lower) / 2.0, 0.05 * p.max_torque)
    return hold, half


def pulse_torque(t, x, state, hold, half, hand_sign):
    """Return the torque at time t [s] for nut position x [m]; state holds the target."""
    phase = t % PULSE_PERIOD
    if phase < PULSE_LENGTH:
        if not state.get('pulsing'):
            state['pulsing'] = True
            if x is not None and (state['target'] - x) * state['target'] < 0.0:
                state['target'] = -state['target']
            state['dir'] = 1.0 if x is None or state['target'] > x else -1.0
        state['last'] = hold + state['dir'] * hand_sign * PULSE_GAIN * half
        return state['last']
    state['pulsing'] = False
    return hold


def step_target(t, state):
    """Return the stepper's position target [m] at time t [s]; state holds the pattern."""
    k = int(t // PULSE_PERIOD)
    if k != state.get('k'):
        state['k'] = k
        x = state.get('x_cmd', 0.0)
        if (state['target'] - x) * state['target'] <= 0.0:
            state['target'] = -state['target']
        step = STEP_MM * 1e-3 * (1.0 if state['target'] > x else -1.0)
        state['x_cmd'] = x + step
        state['last'] = state['x_cmd']
    return state['x_cmd']


def _load(preset):
    """Return (preset name, ScrewParams) or an exit code for a bad preset."""
    from .parameters import DEFAULT_PRESET
    from ..core import load_preset, ParameterError
    preset = DEFAULT_PRESET if preset in (None, 'default') else preset
    try:
        return preset, load_preset(preset)
    except ParameterError as exc:
        print(f'demo: {exc}', file=sys.stderr)
        return 2


def _isolate():
    """Stay off other people's ROS graph: this host only, and not domain 0."""
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.pop('ROS_LOCALHOST_ONLY', None)
    if not os.environ.get('ROS_DOMAIN_ID'):
        os.environ['ROS_DOMAIN_ID'] = DEFAULT_DOMAIN_ID


def _subscribe(node, latest):
    """Keep the latest nut position and contact/thread state in ``latest``."""
    from diagnostic_msgs.msg import DiagnosticArray
    from std_msgs.msg import Float64

    def on_x(msg):
        latest['x'] = msg.data

    def on_diag(msg):
        for status in msg.status:
            for kv in status.values:
                if kv.key in ('contact', 'thread'):
                    latest[kv.key] = kv.value

    node.create_subscription(Float64, 'nut_position', on_x, 10)
    node.create_subscription(DiagnosticArray, 'diagnostics', on_diag, 10)


def _drive(duration, params, hold, half, pub, executor, latest, child, stop):
    """Publish the pulse pattern and print the state until stopped; return the exit code."""
    from std_msgs.msg import Float64
    print('demo: waiting for the node...', flush=True)
    while latest['x'] is None and not stop['now']:
        executor.spin_once(timeout_sec=0.05)
        if child.poll() is not None:
            print(f'demo: the node exited with code {child.returncode}', file=sys.stderr)
            return child.returncode or 1
    state = {'target': TARGET}
    t0 = time.monotonic()
    next_print = PULSE_PERIOD / 2.0          # print between pulses
    while not stop['now']:
        t = time.monotonic() - t0
        if duration and t >= duration:
            break
        if params.drive_type == 'stepper':
            state.setdefault('x_cmd', latest['x'])
            value = step_target(t, state)
            what = f'target={value * 1e3:+8.3f} mm'
        else:
            value = pulse_torque(t, latest['x'], state, hold, half, params.hand_sign)
            what = f'torque={value:+8.4f} N m (last pulse {state.get("last", hold):+8.4f})'
        pub.publish(Float64(data=value))
        executor.spin_once(timeout_sec=0.01)
        if t >= next_print:
            next_print += PRINT_PERIOD
            x = latest['x']
            print(f't={t:7.2f} s  {what}  nut={x * 1e3:+9.3f} mm  '
                  f'contact={latest["contact"]} ({latest.get("thread", "?")})', flush=True)
        if child.poll() is not None:
            print(f'demo: the node exited with code {child.returncode}', file=sys.stderr)
            return child.returncode or 1
    return 0


def run(preset=None, duration=0.0):
    """
    Run the demo; return the exit code.

    Parameters
    ----------
    preset : str, optional
        Preset name or YAML path (None or 'default': the node's default preset).
    duration : float
        Seconds to run [s]; 0 until Ctrl-C.

    """
    loaded = _load(preset)
    if isinstance(loaded, int):
        return loaded
    preset, params = loaded
    _isolate()
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    from std_msgs.msg import Float64

    hold, half = torque_band(params)
    stepper = params.drive_type == 'stepper'
    if stepper:
        print(f'demo: preset {preset} (a stepper): position targets {STEP_MM:g} mm apart '
              f'every {PULSE_PERIOD:g} s between +-{TARGET * 1e3:g} mm; '
              f'ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}', flush=True)
    else:
        print(f'demo: preset {preset} ({params.hand}-hand thread: a positive torque moves the '
              f'nut toward {"-x" if params.hand == "right" else "+x"}); holding torque '
              f'{hold:+.3f} N m, pulses of +-{PULSE_GAIN * half:.3f} N m; '
              f'ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}', flush=True)
    child = subprocess.Popen(
        [sys.executable, '-m', 'leadscrew_sim.node', '--ros-args', '-p', f'preset:={preset}'],
        start_new_session=True)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('leadscrew_sim_demo')
    latest = {'x': None, 'contact': '?'}
    _subscribe(node, latest)
    pub = node.create_publisher(Float64, 'position_command' if stepper else 'torque_command',
                                10)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    stop = {'now': False}

    def on_signal(_signum, _frame):
        stop['now'] = True

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        code = _drive(duration, params, hold, half, pub, executor, latest, child, stop)
    finally:
        if child.poll() is None:
            child.send_signal(signal.SIGINT)
            try:
                child.wait(timeout=20)
            except subprocess.TimeoutExpired:
                child.kill()
                child.wait()
        executor.shutdown()
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    print(f'demo: stopped (node exit code {child.returncode})', flush=True)
    return code
