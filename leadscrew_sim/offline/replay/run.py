"""
The ``resim`` run: a recording's commands through the model again, its states compared.

A leadscrew_sim recording is re-simulated by :class:`.resim.Resim` (the
node's command rules, the model in blocks) into a new recording and compared
with the recorded states (:mod:`.compare`). A foreign recording, or one
given the twin's parameters or the mapping flags, is compared with its twin
(:func:`leadscrew_sim.offline.foreign.twin.twin_comparison`).
"""
import dataclasses
import os
from pathlib import Path

from .compare import compare, compared_ticks
from .resim import Resim
from ..foreign.mapping import Mapping
from ..foreign.twin import twin_comparison
from ..options import (compression_of, gc_paused, load_params, open_recording, parse_sets,
                       Progress, RunError)
from ..run_events import EventLog
from ...core.params import ScrewParams
from ...io.run_file import CLI_RECORD, PARAMS_RECORD, RunWriter


@dataclasses.dataclass
class ResimRun:
    """
    What :func:`resim` wrote and compared for a leadscrew_sim recording.

    ``sim``: the :class:`Resim`; ``path``: the MCAP file written; ``new``: the
    re-simulated states (:class:`.resim.NewStates`); ``rows``: (topic, field,
    max |diff|, rms diff, n) of :func:`.compare.compare`, in the recorded
    units; ``bit_differences``: compared values whose IEEE 754 bits differ;
    ``ticks``: the recorded ticks compared; ``events``: the run's events.
    """

    sim: Resim
    path: str
    new: object
    rows: list
    bit_differences: int
    ticks: int
    events: list


@dataclasses.dataclass
class TwinRun:
    """A foreign recording against its twin: ``comparison`` and the parameters' ``label``."""

    comparison: object
    label: str


def resim(args):
    """
    Re-simulate a recording as the options of ``resim`` say, or compare it with its twin.

    Parameters
    ----------
    args : argparse.Namespace
        The options of ``leadscrew_sim resim``.

    Returns
    -------
    ResimRun or TwinRun

    Raises
    ------
    RunError
        For an invalid option, output path or recording.

    """
    with gc_paused():
        return _resim(args)


def _resim(args):
    """Open the recording, then re-simulate it (or compare it with its twin)."""
    phys_ov, run_ov = parse_sets(args.set)
    if run_ov:
        raise RunError('resim <<set>> accepts physics parameters only')
    rec = open_recording(args.file, load_messages=False)
    mapping = Mapping.from_args(args)
    if mapping.given or args.preset or args.params or rec.record(PARAMS_RECORD) is None:
        return _twin(args, rec, mapping, phys_ov)
    sim = Resim(rec, phys_ov)
    out = output_path(args.file, args.output)
    w = RunWriter(out, sim.prefix, params=sim.params, compression=compression_of(args))
    meta = dict(sim.meta)
    meta.update({n: str(getattr(sim.params, n)) for n in ScrewParams.names()})
    w.rec.add_metadata(PARAMS_RECORD, meta)
    w.rec.add_metadata(CLI_RECORD, {'command': 'resim', 'source': str(args.file),
                                    'overrides': ' '.join(args.set or [])})
    try:
        w.write_description(sim.t0)
        progress = Progress(sim.n_steps, 'resim', args.quiet)
        log = EventLog(sim.params, sim.dt_ns)
        new, _model = sim.run(w, progress=progress, log=log)
        rows, bits = compare(sim, new)      # while the writer thread ends the file
    finally:
        w.close()
    return ResimRun(sim, out, new, rows, bits, compared_ticks(sim, new), log.events())


def output_path(source, output=None):
    """
    Return the MCAP file a resim of ``source`` writes: ``output``, else <stem>.resim.mcap.

    Parameters
    ----------
    source : str
        The recording re-simulated (MCAP file or bag directory).
    output : str, optional
        The path the user gave (the ``output`` option).

    Raises
    ------
    RunError
        For a directory, or for the input file itself.

    """
    src = Path(source)
    out = output or str(src.with_name(src.name[:-5] if src.name.endswith('.mcap')
                                      else src.name)) + '.resim.mcap'
    if os.path.isdir(out):
        raise RunError(f'<<output>> {out} is a directory')
    if os.path.abspath(out) == os.path.abspath(source):
        raise RunError(f'<<output>> {out} would overwrite the input file')
    return out


def _twin(args, rec, mapping, phys_ov):
    """Compare a foreign recording with its twin (the ``preset`` or ``params`` option)."""
    rec.require_ros2()
    if not (args.preset or args.params):
        raise RunError(f'{args.file}: not a leadscrew_sim recording: give the twin\'s '
                       'parameters (<<preset>> NAME or <<params>> FILE) and the mapping flags '
                       f'(`leadscrew_sim info {args.file}` prints those that fit)')
    params, label, _extra = load_params(args, phys_ov)
    return TwinRun(twin_comparison(rec, params, mapping), label)
