"""
Read an MCAP file front to back as far as its records are whole: the data of a cut file.

A recording cut by a crash has no summary and ends in an incomplete record.
:func:`scan` walks the records from the start, checks each record's length
against the bytes that remain, decompresses each chunk within a stated bound
and checks its CRC, and stops at the first record that is not whole. What it
returns is every schema, channel, metadata record and message before that
point, and where and why it stopped.

Memory is bounded: no record is read that is longer than the rest of the
file, and no chunk is decompressed beyond :data:`MAX_CHUNK_BYTES` or beyond
the size its record states.
"""
import dataclasses
import io
import os
import struct
import zlib

import lz4.frame
from mcap.data_stream import ReadDataStream
from mcap.records import Channel, Header, Metadata, Schema
import zstandard

from .mcap_writer import MAGIC

#: The largest decompressed chunk accepted [B]: the writers here close a chunk at a few MiB.
MAX_CHUNK_BYTES = 64 << 20

_HEAD = struct.Struct('<BQ')                  # opcode, record length
_CHUNK_FIXED = struct.Struct('<QQQI')         # start, end, uncompressed size, crc
_U32 = struct.Struct('<I')
_U64 = struct.Struct('<Q')
_MESSAGE_FIXED = struct.Struct('<HIQQ')      # channel, sequence, log time, publish time
_OP_HEADER, _OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE = 0x01, 0x02, 0x03, 0x04, 0x05
_OP_CHUNK, _OP_METADATA, _OP_DATA_END = 0x06, 0x0C, 0x0F
_PARSED = {_OP_HEADER: Header, _OP_SCHEMA: Schema, _OP_CHANNEL: Channel,
           _OP_METADATA: Metadata}


@dataclasses.dataclass
class Scan:
    """
    What a front-to-back read of an MCAP file found.

    Attributes
    ----------
    header : mcap.records.Header or None
        The header record.
    schemas, channels : dict
        Schema and Channel records by id.
    metadata : list of (str, dict)
        The metadata records, in file order.
    messages : list of tuple
        Every whole message, in file order: (log time [ns], channel id, data,
        publish time [ns], sequence).
    size : int
        The file's size [B].
    end : int
        Offset just after the last whole record [B].
    complete : bool
        The data section ended properly (a DataEnd or Footer record).
    problem : str
        Why the read stopped before the end ('' when complete).

    """

    header: object = None
    schemas: dict = dataclasses.field(default_factory=dict)
    channels: dict = dataclasses.field(default_factory=dict)
    metadata: list = dataclasses.field(default_factory=list)
    messages: list = dataclasses.field(default_factory=list)
    size: int = 0
    end: int = 0
    complete: bool = False
    problem: str = ''

    @property
    def lost_bytes(self):
        """Bytes after the last whole record [B] (0 for a complete file)."""
        return 0 if self.complete else self.size - self.end


class _Stop(Exception):
    """The walk ends here: the record at this point is not whole."""


def scan(path, max_chunk_bytes=MAX_CHUNK_BYTES):
    """
    Read ``path`` front to back up to its first record that is not whole.

    Parameters
    ----------
    path : str or Path
        The MCAP file.
    max_chunk_bytes : int
        The largest decompressed chunk accepted [B].

    Returns
    -------
    Scan

    Raises
    ------
    OSError
        If the file cannot be read.
    ValueError
        If the file does not start with the MCAP magic bytes.

    """
    out = Scan()
    with open(path, 'rb') as fh:
        out.size = os.fstat(fh.fileno()).st_size
        if fh.read(len(MAGIC)) != MAGIC:
            raise ValueError('not an MCAP file (bad magic bytes)')
        out.end = len(MAGIC)
        try:
            _walk(fh, out, max_chunk_bytes)
        except _Stop as stop:
            out.problem = str(stop)
    return out


def _walk(fh, out, max_chunk_bytes):
    """Read the top-level records of ``fh`` into ``out`` until the data section ends."""
    while True:
        at = out.end
        head = fh.read(_HEAD.size)
        if len(head) < _HEAD.size:
            raise _Stop(f'the file ends at byte {at} without a data end record'
                        if not head else f'an incomplete record header at byte {at}')
        op, length = _HEAD.unpack(head)
        if length > out.size - at - _HEAD.size:
            raise _Stop(f'the record at byte {at} (opcode 0x{op:02x}) claims {length} B, '
                        f'{out.size - at - _HEAD.size} B remain')
        body = fh.read(length)
        if op in (_OP_DATA_END, _OP_FOOTER):
            out.end = at + _HEAD.size + length
            out.complete = True
            return
        if op == _OP_CHUNK:
            records = _chunk_records(body, at, max_chunk_bytes)
            _take_all(records, at, out)
        else:
            _take(op, body, at, out)
        out.end = at + _HEAD.size + length


def _chunk_records(body, at, max_chunk_bytes):
    """Return the decompressed, CRC-checked records of a Chunk record's body."""
    try:
        _start, _end, size, crc = _CHUNK_FIXED.unpack_from(body, 0)
        pos = _CHUNK_FIXED.size
        n = _U32.unpack_from(body, pos)[0]
        compression = bytes(body[pos + 4:pos + 4 + n]).decode()
        pos += 4 + n
        n = _U64.unpack_from(body, pos)[0]
    except (struct.error, UnicodeDecodeError):
        raise _Stop(f'a corrupt chunk at byte {at}') from None
    packed = body[pos + 8:pos + 8 + n]
    if len(packed) != n:
        raise _Stop(f'a chunk at byte {at} whose records overrun it')
    if size > max_chunk_bytes:
        raise _Stop(f'a chunk at byte {at} claims {size} B uncompressed '
                    f'(the bound is {max_chunk_bytes} B)')
    try:
        if compression == 'zstd':
            data = zstandard.ZstdDecompressor().decompress(packed, max_output_size=size)
        elif compression == 'lz4':
            data = lz4.frame.LZ4FrameDecompressor().decompress(packed, max_length=size)
        elif compression == '':
            data = bytes(packed)
        else:
            raise _Stop(f'a chunk at byte {at} with unknown compression {compression!r}')
    except (zstandard.ZstdError, RuntimeError, ValueError) as exc:
        raise _Stop(f'a chunk at byte {at} that does not decompress ({exc})') from None
    if len(data) != size or (crc and zlib.crc32(data) != crc):
        raise _Stop(f'a chunk at byte {at} with a bad size or CRC')
    return data


def _take_all(records, at, out):
    """Parse the records of a chunk into ``out``; a chunk is taken whole or not at all."""
    taken = Scan()
    taken.schemas, taken.channels = dict(out.schemas), dict(out.channels)
    messages = taken.messages
    unpack_head, unpack_message = _HEAD.unpack_from, _MESSAGE_FIXED.unpack_from
    head, fixed = _HEAD.size, _HEAD.size + _MESSAGE_FIXED.size
    pos, end = 0, len(records)
    while pos < end:
        if end - pos < head:
            raise _Stop(f'a chunk at byte {at} with a truncated record')
        op, length = unpack_head(records, pos)
        nxt = pos + head + length
        if nxt > end:
            raise _Stop(f'a chunk at byte {at} with a record that overruns it')
        if op == _OP_MESSAGE and length >= _MESSAGE_FIXED.size:
            channel, sequence, log_time, publish_time = unpack_message(records, pos + head)
            messages.append((log_time, channel, records[pos + fixed:nxt], publish_time,
                             sequence))
        else:
            _take(op, records[pos + head:nxt], at, taken)
        pos = nxt
    out.schemas, out.channels = taken.schemas, taken.channels
    out.metadata.extend(taken.metadata)
    out.messages.extend(messages)


def _take(op, body, at, out):
    """Parse one record's body into ``out`` (records of other kinds are skipped)."""
    try:
        if op == _OP_MESSAGE:
            channel, sequence, log_time, publish_time = _MESSAGE_FIXED.unpack_from(body, 0)
            # a message record shorter than its fixed fields raises struct.error: corrupt
            out.messages.append((log_time, channel, bytes(body[_MESSAGE_FIXED.size:]),
                                 publish_time, sequence))
            return
        cls = _PARSED.get(op)
        if cls is None:
            return
        record = cls.read(ReadDataStream(io.BytesIO(body)))
    except Exception as exc:  # noqa: B902 - mcap's parsers raise many kinds on bad bytes
        raise _Stop(f'a corrupt record (opcode 0x{op:02x}) at byte {at} ({exc})') from None
    if op == _OP_HEADER:
        out.header = record
    elif op == _OP_SCHEMA:
        out.schemas[record.id] = record
    elif op == _OP_CHANNEL:
        out.channels[record.id] = record
    else:
        out.metadata.append((record.name, dict(record.metadata)))
