"""``info`` (``summary``): one screen about a recording (any ros2-profile MCAP)."""
from .args import verb_flags
from .event_lines import print_events
from ..offline.info import info

HELP = 'one screen about a recording'


def add_arguments(p):
    """Add the options of ``info`` to parser ``p``."""
    p.add_argument('file', help='the recording (any ros2-profile MCAP, or a rosbag2 bag '
                   'directory)')
    p.add_argument('--no-resim', action='store_true',
                   help='skip the re-simulation (stick fraction, energy)')
    p.add_argument('--figures', metavar='PROFILE', nargs='?', const='auto',
                   help='also print the derived figures of an identification run (breakaway, '
                        'sweep, reversals, iso230; without a name: the profile simulate '
                        '--excite recorded)')
    p.add_argument('--quiet', '-q', action='store_true', help='no progress bar')


def run(args):
    """Print one screen about a recording (:func:`..offline.info.info`); return 0."""
    r = info(args.file, figures=args.figures, resim=not args.no_resim, quiet=args.quiet)
    _print_channels(r)
    if not r.leadscrew:
        print('(not a leadscrew_sim recording)')
        for line in r.survey_text(verb_flags(add_arguments)):
            print(line)
        return 0
    run = {k: '?' if v is None else v for k, v in r.run.items()}
    print(f'leadscrew_sim run: preset {run["preset"]}, {run["update_rate"]} Hz, '
          f'clock_mode {run["clock_mode"]}')
    _print_states(r.states)
    print('timing: ' + (', '.join(f'{k} {v}' for k, v in r.timing.items()) if r.timing else
                        'no overrun/late-tick counts in the metadata'))
    if r.thread is not None and r.thread.source.startswith('recorded'):
        _print_thread(r.thread)
    if r.ageing is not None:
        _print_ageing(r.ageing)
    if r.thread is not None and not r.thread.source.startswith('recorded'):
        _print_thread(r.thread)
    print_events(r.events)
    if r.figures:
        _print_figures(r.figures)
    return 0


def _print_channels(r):
    """Print the file, its duration and the message count and rate [Hz] of each channel."""
    print(f'file:      {r.path} ({r.kind}, {r.size} B), profile {r.profile!r}, '
          f'library {r.library!r}')
    print(f'duration:  {r.duration:.6f} s (log time {r.start:.6f} .. {r.end:.6f} s), '
          f'{r.messages} messages')
    print(f'{"topic":<28} {"type":<34} {"count":>8} {"rate Hz":>9}')
    for ch in r.channels:
        rate = '-' if ch.rate is None else f'{ch.rate:.1f}'
        print(f'{ch.topic:<28} {ch.type:<34} {ch.count:>8} {rate:>9}')


def _print_states(s):
    """Print the range of the nut position [m] and the largest velocities and torque."""
    if 'nut_min' in s:
        print(f'nut position: min {s["nut_min"]:.6g} m, max {s["nut_max"]:.6g} m, '
              f'final {s["nut_final"]:.6g} m')
    if 'max_nut_speed' in s:
        print(f'max |velocity|: nut {s["max_nut_speed"]:.6g} m/s, screw '
              f'{s["max_screw_speed"]:.6g} rad/s')
    if 'max_motor_torque' in s:
        print(f'max |motor torque|: {s["max_motor_torque"]:.6g} N m')


def _print_thread(th):
    """Print the stick and contact shares and the energy balance [J]."""
    e = th.energy
    print(f'({th.source}) thread stuck {100 * th.stick:.1f}% of loaded steps; contact ' +
          ', '.join(f'{k} {100 * v:.1f}%' for k, v in th.contact.items()))
    print(f'energy: input work {e["input_work"]:.6g} J, friction dissipated '
          f'{e["friction_dissipation"]:.6g} J, damping dissipated '
          f'{e["damping_dissipation"]:.6g} J (balance residual {th.residual:.3g} J)')


def _print_ageing(a):
    """Print how the axis aged over the recording."""
    first, last = a['first'], a['last']
    t_lo, t_hi = a['temperature_range']
    print(f'ageing: wear leading {first["wear_leading"] * 1e6:.4g} -> '
          f'{last["wear_leading"] * 1e6:.4g} um, trailing {first["wear_trailing"] * 1e6:.4g} '
          f'-> {last["wear_trailing"] * 1e6:.4g} um; backlash {first["backlash"] * 1e6:.4g} -> '
          f'{last["backlash"] * 1e6:.4g} um; lubricant {first["lubricant"]:.4g} -> '
          f'{last["lubricant"]:.4g} (mu_k {last["mu_k"]:.4g}); screw {t_lo:.4g} .. '
          f'{t_hi:.4g} degC, growth at the nut {last["thermal_growth"] * 1e6:.4g} um')


def _print_figures(f):
    """Print the derived figures of an identification profile run (core.figures)."""
    from .figure_lines import format_figures
    print(f'derived figures of the {f["profile"]} run (core.figures, from joint_states and '
          f'{f["kind"]}_command):')
    for line in format_figures(f['figures']):
        print('  ' + line)
