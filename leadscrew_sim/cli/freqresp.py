"""
The ``freqresp`` verb: the axis's frequency response (Bode plot) from three sources.

Parses the flags (doc/frequency_response.md) and calls
:func:`leadscrew_sim.offline.freqresp.run.freqresp_run`; prints its summary.
"""
from .args import flag_text
from ..offline.freqresp.run import freqresp_run

HELP = ('frequency response: linear model, simulated sine dwell / chirp / multisine, or a '
        'recording (CSV, Bode PNG, margins)')


def _model_arguments(p):
    p.add_argument('file', nargs='?', metavar='RUN.mcap',
                   help='a recording with broadband excitation (excite chirp / multisine)')
    p.add_argument('--preset', help='preset name (default: the default preset)')
    p.add_argument('--params', help='ROS 2 parameter file (<node>: ros__parameters:)')
    p.add_argument('--set', action='append', metavar='NAME=VALUE',
                   help='override a physics parameter (repeatable)')
    p.add_argument('--input', help='torque [N m] | velocity_command [m/s] | position_command '
                   '[m] | external_force [N] (default velocity_command)')
    p.add_argument('--output', help='motor_angle [rad] | motor_velocity [rad/s] | nut_position '
                   '[m] | nut_velocity [m/s] | thread_force [N] | following_error [rad] | '
                   'motor_torque [N m] (default motor_velocity)')
    p.add_argument('--loop', help='velocity | position: a loop quantity at the controller\'s '
                   'summing point (instead of --input/--output)')
    p.add_argument('--quantity', help='L | S | T (with --loop; default L)')
    p.add_argument('--mode', help='drive mode under --input external_force: torque | velocity '
                   '| position (default position)')
    p.add_argument('--speed', type=float, default=0.0, help='operating point: nut speed [m/s] '
                   '(default 0: at rest on the loaded flank; a sine dwell while sliding: the '
                   'velocity loop only)')
    p.add_argument('--rest', default='stuck', help='the linear model at rest: stuck (the '
                   'thread held by stiction, default) | free (its friction left out)')


def add_arguments(p):
    """Add the verb's flags to the parser ``p``."""
    _model_arguments(p)
    p.add_argument('--linear', action='store_true', help='the linearised model\'s FRF')
    p.add_argument('--sampling', default='continuous', help='--linear: continuous | drive '
                   '(sampled at the drive period) | step (exact hold at the step rate)')
    p.add_argument('--method', default='sine', help='simulated measurement: sine (dwell, '
                   'default) | chirp | multisine')
    p.add_argument('--fmin', type=float, help='lowest frequency [Hz] (default 1)')
    p.add_argument('--fmax', type=float, help='highest frequency [Hz] (default 100), below the '
                   'Nyquist frequency of the step rate')
    p.add_argument('--points', type=int, default=30, help='frequencies (default 30)')
    p.add_argument('--amplitude', metavar='A[,A2,...]', help='test amplitude(s) in the input\'s '
                   'SI unit, each > 0 (default from the axis)')
    p.add_argument('--settle', type=int, default=3, help='sine dwell: periods discarded '
                   '(default 3, at least the settling time)')
    p.add_argument('--periods', type=int, default=5, help='sine dwell: periods kept (default 5)')
    p.add_argument('--step-rate', dest='step_rate', type=float, metavar='HZ',
                   help='step rate [Hz] (default 1000; a recording: from its stamps)')
    p.add_argument('--workers', type=int, help='local worker processes (default: the cores)')
    p.add_argument('--scheduler', metavar='tcp://HOST:PORT', help='run on a Dask scheduler')
    p.add_argument('--segments', type=int, default=8, help='a recording: Welch segments')
    p.add_argument('--state-topic', help='a recording: JointState topic of the states')
    p.add_argument('--command-topic', help='a recording: command topic')
    p.add_argument('--command-kind', help='a recording: torque | velocity | position, what a '
                   'Float64 --command-topic carries')
    p.add_argument('--screw-joint', help='a recording: joint name of the screw (motor)')
    p.add_argument('--nut-joint', help='a recording: joint name of the nut')
    p.add_argument('--command-index', type=int, metavar='N',
                   help='a recording: entry of a Float64MultiArray command (default 0)')
    p.add_argument('--command-joint', metavar='NAME',
                   help='a recording: joint of JointState commands')
    p.add_argument('--command-delay', type=float, metavar='S',
                   help='a recording: command-to-state delay [s] (default 0)')
    p.add_argument('--map', metavar='FILE.yaml', help='a recording: the mapping keys in a '
                   'YAML file (doc/bags.md)')
    p.add_argument('--output-csv', '-o', dest='output_csv', metavar='FILE.csv',
                   help='write frequency [Hz], magnitude_db, phase_deg, coherence, amplitude')
    p.add_argument('--plot', metavar='FILE.png', help='write the Bode plot (coherence below)')
    p.add_argument('--quiet', '-q', action='store_true', help='no summary')


def run(args):
    """Run the verb; return the exit status."""
    res = freqresp_run(args)
    if not args.quiet:
        print(flag_text(add_arguments, '\n'.join(res['lines'])))
    return 0
