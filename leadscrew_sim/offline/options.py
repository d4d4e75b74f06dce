"""
What the offline runs share: the user-facing error, ``set``, parameters, progress, memory.

The verbs of the command line parse arguments and call this run library; a
:class:`RunError` it raises is printed by the verb as one line, and a failed
integration becomes one in :func:`simulation_faults`.
"""
import contextlib
import ctypes
import difflib
import gc
import math
from pathlib import Path
import re
import sys
import time

from ..core import yamlio
from ..core.faults import SimulationFault
from ..core.fields import field_name
from ..core.params import ParameterError, ScrewParams
from ..core.presets import load_preset, physics_subset, read_parameter_file
from ..io.mcap_reader import Recording
from ..io.rosbag2 import BagRecording, is_bag
from ..core.errors import LeadscrewError

#: Nanoseconds per second.
NS = 1_000_000_000
DEFAULT_PRESET = 'tr12x3'


#: An option named in a message, by its keyword: ``<<name>>``.
_OPTION = re.compile(r'<<([a-z][a-z0-9_]*)>>')


def option_text(template, name_of=None):
    """
    Return ``template`` with each ``<<name>>`` named by ``name_of(name)`` (default the keyword).

    The run library names the options of its calls by their keywords; the
    command line names them by their flags, through this one function.
    """
    return _OPTION.sub(lambda m: m.group(1) if name_of is None else name_of(m.group(1)),
                       template)


class RunError(LeadscrewError):
    """
    A user-facing error of an offline run: printed as one line, exit status 1.

    Its message names an option of the call as ``<<name>>``: ``str()`` reads
    the keyword (``step_rate``), and :meth:`naming` gives the text with
    another name of each, as the command line does with its flags.
    """

    def __init__(self, message=''):
        """Keep the message with its option marks; the error's text names the keywords."""
        self.template = str(message)
        super().__init__(option_text(self.template))

    def naming(self, name_of):
        """Return the message with each option named by ``name_of(keyword)``."""
        return option_text(self.template, name_of)


@contextlib.contextmanager
def simulation_faults(where=''):
    """
    Raise a failed integration inside the block as the run's one-line :class:`RunError`.

    The model raises :class:`~leadscrew_sim.core.faults.SimulationFault` when
    its state becomes non-finite; the error reads ``simulation fault<where>:
    <the fault>``.

    Parameters
    ----------
    where : str
        Said after ``simulation fault`` (for example the steps that ran).

    """
    try:
        yield
    except SimulationFault as exc:
        raise RunError(f'simulation fault{where}: {exc}') from None


def parse_scalar(text):
    """Parse a ``set`` value as a YAML scalar; '1e-4' counts as a number."""
    try:
        value = yamlio.load(text)
    except yamlio.YAMLError:
        value = text
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            pass
    return value


def parse_sets(items):
    """Return (physics overrides, run-setting overrides) from ``name=value`` strings."""
    names = ScrewParams.names()
    phys, run = {}, {}
    for item in items or ():
        name, sep, text = item.partition('=')
        name = name.strip()
        if not sep or not name:
            raise RunError(f'<<set>> {item!r}: expected name=value')
        value = parse_scalar(text)
        if field_name(name) in names:
            phys[field_name(name)] = value
        elif name == 'joint_prefix':
            run[name] = '' if value is None else str(text)
        else:
            raise RunError(f"<<set>>: unknown parameter '{name}' ({did_you_mean(name)})")
    return phys, run


def did_you_mean(name):
    """Return the hint for an unknown ``set`` name: its nearest accepted names."""
    known = ScrewParams.parameter_names() + ('joint_prefix',)
    close = difflib.get_close_matches(name, known, n=3)
    if close:
        return f'did you mean {" or ".join(close)}?'
    return ('no parameter of a similar name; the physics parameters are in doc/model.md, '
            'the run setting is joint_prefix')


def parse_options(items, option='opt'):
    """Return {name: value} of ``name=value`` strings given to the option of keyword ``option``."""
    out = {}
    for item in items or ():
        name, sep, text = item.partition('=')
        name = name.strip()
        if not sep or not name:
            raise RunError(f'<<{option}>> {item!r}: expected name=value')
        out[name] = parse_scalar(text)
    return out


def check_finite(name, value):
    """Raise RunError unless the option of keyword ``name`` has a finite ``value``."""
    if not math.isfinite(value):
        raise RunError(f'<<{name}>> {value!r} is not a finite number')


def load_params(args, phys_overrides):
    """Return (ScrewParams, preset label, extra settings from a ``params`` file)."""
    if args.params and args.preset:
        raise RunError('give <<preset>> or <<params>>, not both')
    extra = {}
    if args.params:
        try:
            values = read_parameter_file(args.params)
        except OSError as exc:
            raise RunError(f'<<params>> {args.params}: {exc.strerror or exc}') from None
        except ParameterError:
            raise RunError(f'<<params>> {args.params}: no "<node>: ros__parameters:" '
                           'section') from None
        except Exception as exc:  # noqa: B902 - YAML syntax errors of many kinds
            raise RunError(f'<<params>> {args.params}: cannot parse YAML: '
                           f'{str(exc).splitlines()[0]}') from None
        phys, other = physics_subset(values)
        preset = other.get('preset')
        base = load_preset(preset) if isinstance(preset, str) else ScrewParams()
        params = ScrewParams.from_dict(phys, base=base)
        extra = {k: other[k] for k in ('update_rate', 'joint_prefix') if k in other}
        label = Path(args.params).stem
    else:
        label = args.preset or DEFAULT_PRESET
        params = load_preset(label)
    if phys_overrides:
        params = ScrewParams.from_dict(phys_overrides, base=params)
    return params, label, extra


class Progress:
    """
    A progress bar on stderr, shown only once a run has taken ``delay`` s of wall time.

    Parameters
    ----------
    total : int
        Number of steps of the run.
    label : str
        Text before the bar.
    quiet : bool
        Never show the bar.
    delay : float
        Wall time [s] before the bar appears.

    """

    def __init__(self, total, label, quiet=False, delay=2.0):
        """Start the clock."""
        self.total = max(1, total)
        self.label = label
        self.quiet = quiet or not total
        self.t0 = time.monotonic()
        self.delay = delay
        self.next = self.t0 + delay
        self.shown = False

    def update(self, done):
        """Redraw with ``done`` steps done, at most 4 times a second."""
        now = time.monotonic()
        if self.quiet or now < self.next:
            return
        self.next = now + 0.25
        self.shown = True
        frac = done / self.total
        bar = '#' * int(30 * frac)
        rate = done / (now - self.t0)
        eta = (self.total - done) / rate if rate > 0 else 0.0
        sys.stderr.write(f'\r{self.label} [{bar:<30}] {100 * frac:5.1f}% ETA {eta:5.1f} s ')
        sys.stderr.flush()

    def done(self):
        """Clear the bar."""
        if self.shown:
            sys.stderr.write('\r' + ' ' * 70 + '\r')
            sys.stderr.flush()


def compression_of(args):
    """Return the McapWriter compression of the ``compression`` option."""
    return '' if args.compression == 'none' else args.compression


#: glibc's mallopt parameters, and the values the offline runs set.
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
_MMAP_THRESHOLD = 32 << 20          # glibc's ceiling of its own dynamic threshold, 64-bit
_TRIM_THRESHOLD = 512 << 20
_MALLOC_TUNED = []


def keep_freed_memory():
    """
    Have glibc's malloc serve blocks up to 32 MiB from its heap and keep freed memory.

    By default glibc maps each large block (the chunks' records, the topics'
    arrays, the run's columns) afresh and unmaps it when freed, so every block
    is first touched page by page again: in resim's reading that took about
    half of the time. Kept in the heap, freed blocks are reused as they are.
    Once per process; elsewhere than glibc (no ``mallopt``) nothing changes.
    Returns True when the settings were taken.
    """
    if not _MALLOC_TUNED:
        ok = False
        try:
            mallopt = ctypes.CDLL(None).mallopt      # the process's own symbols: libc's
            ok = bool(mallopt(_M_MMAP_THRESHOLD, _MMAP_THRESHOLD)
                      and mallopt(_M_TRIM_THRESHOLD, _TRIM_THRESHOLD))
        except (OSError, AttributeError):
            pass
        _MALLOC_TUNED.append(ok)
    return _MALLOC_TUNED[0]


@contextlib.contextmanager
def gc_paused():
    """
    Pause Python's cyclic garbage collector inside the block (and keep freed memory).

    Reading and writing a recording makes hundreds of thousands of small
    acyclic objects (message tuples and bytes); each of them counts toward a
    collection that finds nothing to free, about a third of resim's reading
    time. Reference counting still frees them. Also sets
    :func:`keep_freed_memory` for the rest of the process.
    """
    keep_freed_memory()
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def open_recording(path, **kwargs):
    """
    Open a recording: one MCAP file or a rosbag2 bag directory, saying if it is cut.

    A file is a :class:`leadscrew_sim.io.mcap_reader.Recording`, a directory a
    :class:`leadscrew_sim.io.rosbag2.BagRecording` (its split files merged in
    log-time order, the same attributes). A file cut short by a crash is read
    up to its last whole chunk, with one warning line on stderr that names
    ``leadscrew_sim recover``.

    Parameters
    ----------
    path : str or Path
        The MCAP file or the bag directory.
    **kwargs
        ``topics``, ``load_messages``: as Recording takes them.

    """
    rec = BagRecording(path, **kwargs) if is_bag(path) else Recording(path, **kwargs)
    if rec.cut:
        print(f'leadscrew_sim: warning: {path} is cut short or damaged ({rec.cut}); '
              f'`leadscrew_sim recover {path}` writes a complete copy', file=sys.stderr)
    return rec
