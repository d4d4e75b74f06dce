"""
Fuzz of the recording readers: cut, bit-flipped, inflated and foreign files.

Every damaged file must end within 5 s, either in one RecordingError line
(the verbs: one line and a non-zero exit), or in a Recording marked ``cut``
that holds only messages of the original file and every message of the
chunks that lie whole before the damage. No case may allocate more than
:data:`ALLOC_BOUND` (Python's own allocations, numpy's and the
decompressors' output, as tracemalloc sees them).

The oracle of what a file holds is the ``mcap`` package's reader of the
undamaged file (its chunk indexes and messages), not our reader. The
examples are derandomized (the 'ci' profile), a few hundred per run.
"""
import collections
import io
import os
import signal
import struct
import tracemalloc

from hypothesis import given, HealthCheck, settings, strategies as st
from mcap.data_stream import EndOfFile
from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
from mcap.writer import Writer
import pytest

from leadscrew_sim.cli.main import main as cli_main
from leadscrew_sim.io.mcap_reader import Recording, RecordingError
from leadscrew_sim.io.mcap_scan import MAX_CHUNK_BYTES
from leadscrew_sim.io.mcap_writer import McapWriter

settings.register_profile('ci', derandomize=True)
settings.register_profile('explore', derandomize=False)
settings.load_profile(os.environ.get('HYPOTHESIS_PROFILE', 'ci'))

#: The most a case may allocate [B]: one chunk at the decompression bound, plus the
#: messages of the whole file several times over (records, tuples, sorting).
ALLOC_BOUND = MAX_CHUNK_BYTES + (48 << 20)
CASE_SECONDS = 5


class Hang(Exception):
    """A case ran longer than CASE_SECONDS."""


def _on_alarm(_sig, _frame):
    raise Hang(f'a read ran longer than {CASE_SECONDS} s')


class _Originals(dict):
    """The undamaged files by compression (a short repr in hypothesis's reports)."""

    def __repr__(self):
        return '<the undamaged lz4 and zstd files>'


@pytest.fixture(scope='module')
def originals(tmp_path_factory):
    """Write a short recording in chunks of 32 KiB (lz4, zstd); read it back with mcap."""
    d = tmp_path_factory.mktemp('fuzz')
    sim = d / 'sim.mcap'
    assert cli_main(['simulate', '--preset', 'tr12x3', '--duration', '0.4', '-q',
                     '-o', str(sim)]) == 0
    with open(sim, 'rb') as fh:
        reader = make_reader(fh)
        header, summary = reader.get_header(), reader.get_summary()
        metadata = [(m.name, dict(m.metadata)) for m in reader.iter_metadata()]
        source = list(reader.iter_messages(log_time_order=False))
    out = _Originals()
    for comp in ('lz4', 'zstd'):
        path = d / f'{comp}.mcap'
        with open(path, 'wb') as fh:
            w = McapWriter(fh, profile=header.profile, library='fuzz', chunk_size=32 << 10,
                           compression=comp)
            sids = {s.id: w.register_schema(s.name, s.encoding, s.data)
                    for s in summary.schemas.values()}
            cids = {c.id: w.register_channel(c.topic, c.message_encoding, sids[c.schema_id],
                                             dict(c.metadata))
                    for c in summary.channels.values()}
            for name, data in metadata:
                w.add_metadata(name, data)
            for _s, c, m in source:
                w.add_message(cids[c.id], m.log_time, m.data, m.publish_time, m.sequence)
            w.finish()
        raw = path.read_bytes()
        with open(path, 'rb') as fh:
            reader = make_reader(fh)
            summ = reader.get_summary()
            msgs = [(m.log_time, c.topic, bytes(m.data))
                    for _s, c, m in reader.iter_messages(log_time_order=False)]
        chunks = sorted(summ.chunk_indexes, key=lambda c: c.chunk_start_offset)
        assert len(chunks) >= 4, 'the fuzz needs files of several chunks'
        topics = {ch.id: ch.topic for ch in summ.channels.values()}
        per_chunk = []
        for c in chunks:
            one = raw[:8] + raw[c.chunk_start_offset:c.chunk_start_offset + c.chunk_length]
            per_chunk.append((c.chunk_start_offset + c.chunk_length, {
                (m.log_time, topics[m.channel_id], bytes(m.data))
                for m in _chunk_messages(one)}))
        out[comp] = dict(path=path, raw=raw, msgs=collections.Counter(msgs), n=len(msgs),
                         chunks=chunks, per_chunk=per_chunk)
    return out


def _chunk_messages(one):
    """Yield the Message records of the magic plus one chunk, read by mcap's stream reader."""
    stream = StreamReader(io.BytesIO(one), validate_crcs=True)
    try:
        for record in stream.records:
            if isinstance(record, Message):
                yield record
    except EndOfFile:            # one chunk: no data end, no footer
        return


def _damage(orig, kind, a, b):
    """Return (damaged bytes, offset of the first damaged byte) for a damage kind."""
    raw = bytearray(orig['raw'])
    n = len(raw)
    chunks = orig['chunks']
    if kind == 'cut_at_chunk':
        c = chunks[a % len(chunks)]
        edge = (c.chunk_start_offset, c.chunk_start_offset + c.chunk_length)[b % 2]
        at = min(n, max(0, edge + (b % 3) - 1))
        return bytes(raw[:at]), at
    if kind == 'cut':
        at = a % n
        return bytes(raw[:at]), at
    if kind == 'flip':
        at = a % n
        raw[at] ^= 1 << (b % 8)
        return bytes(raw), at
    if kind == 'record_length':
        c = chunks[a % len(chunks)]
        at = c.chunk_start_offset + 1                     # the chunk record's length field
        struct.pack_into('<Q', raw, at, (n * 4, 1 << 32, (1 << 63) - 1, n + 1)[b % 4])
        return bytes(raw), at
    if kind == 'uncompressed_size':
        c = chunks[a % len(chunks)]
        at = c.chunk_start_offset + 9 + 16                # start, end, then the size
        struct.pack_into('<Q', raw, at, (1 << 33, 1 << 40, MAX_CHUNK_BYTES + 1,
                                         c.uncompressed_size * 64)[b % 4])
        return bytes(raw), at
    if kind == 'magic':
        raw[a % 8] ^= 1 << (b % 8)
        return bytes(raw), 0
    raise AssertionError(kind)


def _read_bounded(path):
    """Read ``path`` with our reader under the time and allocation bounds."""
    old = signal.signal(signal.SIGALRM, _on_alarm)
    tracemalloc.start()
    signal.alarm(CASE_SECONDS)
    try:
        try:
            return Recording(path), None
        except RecordingError as exc:
            return None, exc
    finally:
        signal.alarm(0)
        _cur, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        signal.signal(signal.SIGALRM, old)
        assert peak <= ALLOC_BOUND, f'allocated {peak} B, bound {ALLOC_BOUND} B'


KINDS = ('cut_at_chunk', 'cut', 'flip', 'record_length', 'uncompressed_size', 'magic')


@settings(max_examples=300, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(comp=st.sampled_from(('lz4', 'zstd')), kind=st.sampled_from(KINDS),
       a=st.integers(0, 1 << 40), b=st.integers(0, 1 << 16))
def test_a_damaged_file_ends_in_one_line_or_in_the_data_before_the_damage(
        originals, tmp_path, comp, kind, a, b):
    orig = originals[comp]
    data, at = _damage(orig, kind, a, b)
    path = tmp_path / 'damaged.mcap'
    path.write_bytes(data)
    rec, err = _read_bounded(path)
    if err is not None:
        text = str(err)
        assert '\n' not in text and text.startswith(str(path)), text
        return
    # What we read is part of the original, message for message.
    got = collections.Counter(rec.messages)
    assert not got - orig['msgs'], 'messages that are not in the original'
    # Every chunk that lies whole before the damage is read whole.
    for end, msgs in orig['per_chunk']:
        if end <= at:
            assert msgs <= got.keys(), f'a whole chunk ending at {end} lost (damage at {at})'
    if len(rec.messages) < orig['n']:
        assert rec.cut, 'messages lost without the cut being reported'


def test_foreign_and_cut_files_through_the_verbs(originals, tmp_path, capsys):
    """info: one line, exit != 0 for a file it cannot use; a warning naming recover if cut."""
    foreign = tmp_path / 'foreign.mcap'
    with open(foreign, 'wb') as fh:
        w = Writer(fh)
        w.start(profile='x-other', library='test')
        sid = w.register_schema('s', 'jsonschema', b'{}')
        cid = w.register_channel('/t', 'json', sid)
        for i in range(10):
            w.add_message(cid, log_time=i, data=b'{}', publish_time=i)
        w.finish()
    not_mcap = tmp_path / 'not.mcap'
    not_mcap.write_bytes(b'PK\x03\x04' + bytes(1000))
    for path in (foreign, not_mcap):
        capsys.readouterr()
        rc = cli_main(['info', str(path)])
        err = capsys.readouterr().err.strip()
        assert rc != 0 and len(err.splitlines()) == 1 and 'error' in err, err
    orig = originals['lz4']
    cut_at = orig['chunks'][1].chunk_start_offset + orig['chunks'][1].chunk_length + 100
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(orig['raw'][:cut_at])
    capsys.readouterr()
    assert cli_main(['info', str(cut)]) == 0
    err = capsys.readouterr().err
    warn = [line for line in err.splitlines() if 'warning' in line]
    assert len(warn) == 1 and 'recover' in warn[0], err
