"""
``simulate``: run the model without ROS and write an MCAP file in the node's recording layout.

The run is :func:`leadscrew_sim.offline.simulate.run.simulate`; this verb parses
its options and prints what it wrote.
"""
import sys

from .args import add_compression_argument, add_deprecated_alias, flag_text, PROG
from .event_lines import print_events
from ..analysis.excitation.profiles import PROFILES
from ..offline.options import DEFAULT_PRESET
from ..offline.simulate.run import simulate

HELP = 'run the model offline and write an MCAP file'


def add_arguments(p):
    """Add the options of ``simulate`` to parser ``p``."""
    p.add_argument('--preset', help=f'preset name or YAML path (default {DEFAULT_PRESET})')
    p.add_argument('--params', help='ROS 2 parameter file (<node>: ros__parameters:)')
    p.add_argument('--set', action='append', metavar='NAME=VALUE',
                   help='override a physics parameter or joint_prefix (repeatable; YAML '
                   'scalar in the parameter\'s unit)')
    p.add_argument('--duration', type=float, help='simulated time [s] (default 1, or the '
                   'duration of the --excite profile)')
    p.add_argument('--update-rate', dest='rate', type=float, metavar='HZ',
                   help='update rate [Hz], dt = 1/rate (default 1000)')
    add_deprecated_alias(p, '--rate', '--update-rate', 'rate', float)
    p.add_argument('--torque', type=float, help='constant motor torque [N m]')
    p.add_argument('--torque-csv', help='CSV time,torque [s, N m], zero-order hold')
    p.add_argument('--profile', choices=('step', 'ramp', 'sine', 'move', 'trapezoid'),
                   help='torque profile (step, ramp, sine: --amplitude [N m]; move: PD position '
                        'control to --target), or '
                        'trapezoid: a trapezoidal move to --target through the drive\'s '
                        'position loop (--speed, --accel)')
    p.add_argument('--velocity', type=float, help='constant nut velocity command [m/s] '
                   '(the drive\'s velocity mode)')
    p.add_argument('--velocity-csv', help='CSV time,velocity [s, m/s], zero-order hold')
    p.add_argument('--position', type=float, help='constant nut position target [m] '
                   '(the drive\'s position mode)')
    p.add_argument('--position-csv', help='CSV time,position [s, m], zero-order hold')
    p.add_argument('--accel', type=float, default=0.1, help='trapezoid acceleration [m/s^2]')
    p.add_argument('--amplitude', type=float, help='profile torque amplitude [N m] '
                   '(default max_torque/2)')
    p.add_argument('--frequency', type=float, default=1.0, help='sine frequency [Hz]')
    p.add_argument('--step-time', type=float, default=0.1, help='step profile time [s]')
    p.add_argument('--target', type=float, help='move target nut position [m] '
                   '(default initial + 10 mm)')
    p.add_argument('--speed', type=float, default=0.01, help='move reference speed [m/s]')
    p.add_argument('--excite', metavar='PROFILE', help='a profile of `leadscrew_sim excite` '
                   f'({", ".join(PROFILES)}) as the input')
    p.add_argument('--excite-opt', action='append', metavar='NAME=VALUE',
                   help='an option of the --excite profile (repeatable; SI units)')
    p.add_argument('--force', type=float, help='constant external axial force [N]')
    p.add_argument('--force-csv', help='CSV time,force [s, N], zero-order hold')
    p.add_argument('--faults', metavar='FILE', help='fault schedule: CSV time,parameter,value '
                   '[s, a parameter such as fault.jam, a YAML scalar]; each change acts from '
                   'the first step at or after its time')
    p.add_argument('--clock', action='store_true', help='also record /clock every tick')
    p.add_argument('--ageing-from', metavar='RECORDING', help='start the axis worn, '
                   'lubricated and warm as this recording of the same axis ended')
    add_compression_argument(p)
    p.add_argument('--output', '-o', metavar='FILE.mcap',
                   help='output MCAP (default runs/sim_<preset>_<time>.mcap)')
    p.add_argument('--quiet', '-q', action='store_true', help='no progress bar')


def run(args):
    """Run the model offline and record it in the node's layout; return the exit status."""
    done = simulate(args, _warn)
    sim_s, wall, stats = done.simulated, done.wall, done.stats
    print(f'wrote {done.path}: {sim_s:g} s simulated at {done.rate:g} Hz ({done.steps} steps, '
          f'{done.substeps} substeps/step) in {wall:.2f} s wall ({sim_s / wall:.1f}x real '
          f'time), {done.size} B')
    print(f'nut position {stats["x_min"]:.6g} .. {stats["x_max"]:.6g} m, final '
          f'{stats["x_end"]:.6g} m; max |torque| {stats["tq_max"]:.4g} N m')
    print_events(done.events)
    return 0


def _warn(text):
    """Print a warning of the run on stderr."""
    print(f'{PROG}: warning: {flag_text(add_arguments, text)}', file=sys.stderr)
