"""
Message records of fixed-layout CDR messages, written straight into a chunk's block.

:class:`EncodedRows` holds n messages of one fixed layout (a
:class:`~leadscrew_sim.io.cdr.Template`, a TF message) as their stamps and
doubles, not as bytes. :class:`RowLayout` is a row of message records, one
per channel, and says where each varying 8-byte and 4-byte field of a row
goes (sequence numbers, log and publish times, stamps, doubles); the
sources of a block's fields are stacked into two arrays, one row per
source, and :func:`scatter`, one compiled call per block, copies the row's
template into each record and each field into its place. The bytes are
those of the layout's ``rows``.
"""
import numpy as np

from .cdr import stamp_rows


class Stamps:
    """
    Stamps [ns] of n messages with their CDR words (sec, then nanosec), formed once.

    Every message of a tick carries the tick's stamp: pass one ``Stamps`` to
    each :class:`EncodedRows` of a block instead of the int array.

    Parameters
    ----------
    stamps_ns : array_like of int
        The stamps [ns]; the seconds must fit in int32.

    """

    __slots__ = ('ns', 'words')

    def __init__(self, stamps_ns):
        """Form the words."""
        self.ns = np.asarray(stamps_ns, dtype=np.int64)
        halves = stamp_rows(self.ns).view('<u4').astype(np.uint64)
        self.words = halves[:, 0] | (halves[:, 1] << np.uint64(32))

    def __len__(self):
        """Return the number of stamps."""
        return len(self.ns)


class EncodedRows:
    """
    n messages of one fixed layout: stamps [ns] and doubles, encoded when written.

    Parameters
    ----------
    template : bytes
        The message with zero stamps and doubles.
    stamp_offsets : sequence of int
        Where each copy of the stamp goes (sec, nanosec; none for stamp-less types).
    offsets : sequence of int
        Where each double goes.
    stamps_ns : numpy.ndarray of int64, Stamps or None
        The stamp of each message (None: stamp-less).
    columns : list of numpy.ndarray
        One float array (n,) per double, in the order of ``offsets``.

    """

    __slots__ = ('template_bytes', 'tmpl', 'stamp_offsets', 'offsets', 'stamps', 'columns',
                 'n')

    def __init__(self, template, stamp_offsets, offsets, stamps_ns, columns):
        """Keep the layout, the stamps as 8-byte words and the doubles' columns."""
        self.template_bytes = bytes(template)
        self.tmpl = np.frombuffer(self.template_bytes, dtype=np.uint8)
        self.stamp_offsets = tuple(int(o) for o in stamp_offsets)
        self.offsets = tuple(int(o) for o in offsets)
        if len(self.offsets) != len(columns):
            raise ValueError(f'{len(self.offsets)} columns needed, not {len(columns)}')
        self.columns = [_words(c) for c in columns]
        self.n = len(columns[0]) if columns else len(stamps_ns)
        self.stamps = None
        if self.stamp_offsets:
            if not isinstance(stamps_ns, Stamps):
                stamps_ns = Stamps(stamps_ns)
            self.stamps = stamps_ns.words

    @classmethod
    def of_template(cls, template, stamps_ns, columns):
        """
        Return the messages of a :class:`~leadscrew_sim.io.cdr.Template`.

        Parameters
        ----------
        template : Template
            The layout (one stamp or none, its doubles).
        stamps_ns : numpy.ndarray of int64, Stamps or None
            The stamps [ns] (ignored for stamp-less types).
        columns : list of numpy.ndarray
            One float array per double of the template.

        """
        stamped = template.stamp_off is not None
        return cls(template.tmpl, [template.stamp_off] if stamped else [], template.offsets,
                   stamps_ns if stamped else None, columns)

    def __len__(self):
        """Return the number of messages."""
        return self.n

    def __getitem__(self, index):
        """Return the messages of a slice."""
        if not isinstance(index, slice):
            raise TypeError('EncodedRows take slices only')
        out = EncodedRows.__new__(EncodedRows)
        out.template_bytes, out.tmpl = self.template_bytes, self.tmpl
        out.stamp_offsets, out.offsets = self.stamp_offsets, self.offsets
        out.stamps = None if self.stamps is None else self.stamps[index]
        out.columns = [c[index] for c in self.columns]
        out.n = len(range(*index.indices(self.n)))
        return out

    @property
    def width(self):
        """Return the message length [B]."""
        return len(self.tmpl)

    def fields(self, start):
        """Return the (byte offset, 8-byte words (n,)) of its varying fields, from ``start``."""
        out = [(start + off, self.stamps) for off in self.stamp_offsets]
        out += [(start + off, c) for off, c in zip(self.offsets, self.columns)]
        return out

    def tobytes_rows(self):
        """Return the messages as a uint8 array (n, width), as the layout's ``rows`` does."""
        return encode_rows(self)


def _words(values):
    """Return float values as the bit patterns of their doubles (uint64)."""
    a = np.asarray(values)
    if a.dtype != np.float64:
        a = a.astype(np.float64)
    return a.view(np.uint64)


class RowLayout:
    """
    The record row of a set of channels, and where each varying field of a row goes.

    A row holds one message record per channel: header (opcode, length,
    channel, sequence, log time, publish time) and payload. The template
    ``row`` has every fixed byte; the sequence numbers, the times and the
    fields of :class:`EncodedRows` payloads vary per row and are written over
    it by :func:`scatter`; payloads given as bytes are copied whole.

    Parameters
    ----------
    headers : list of bytes
        Each channel's record header with zero sequence and times (31 B).
    payloads : list of int or EncodedRows
        Each channel's payload: its length (bytes given per row) or its layout.

    """

    def __init__(self, headers, payloads):
        """Lay the row out."""
        row, self.starts, self.plain = bytearray(), [], []
        dst8, dst4 = [], []
        for j, (head, p) in enumerate(zip(headers, payloads)):
            s = len(row)
            self.starts.append(s)
            dst4.append(s + 11)
            row += head
            if isinstance(p, EncodedRows):
                row += p.template_bytes
            else:
                self.plain.append((j, s + len(head), int(p)))
                row += bytes(int(p))
        self.width = len(row)
        self.row = np.frombuffer(bytes(row), dtype=np.uint8)
        self.time_dst = [d for s in self.starts for d in (s + 15, s + 23)]
        for s, p in zip(self.starts, payloads):
            if isinstance(p, EncodedRows):
                dst8 += [off for off, _w in p.fields(s + len(headers[0]))]
        self.payload_dst = dst8
        self.dst8 = np.array(self.time_dst + dst8, dtype=np.uint64)
        self.dst4 = np.array(dst4, dtype=np.uint64)
        self.at4 = np.arange(len(dst4), dtype=np.uint64)
        self._payload_at = np.arange(len(dst8), dtype=np.uint64)

    def sources(self, payloads, log_times, sequences, n):
        """
        Return the arguments of :meth:`scatter` for n rows of messages.

        Parameters
        ----------
        payloads : list of numpy.ndarray or EncodedRows
            As laid out, n messages each.
        log_times : list of numpy.ndarray
            Per channel, the log (= publish) times [ns].
        sequences : list of numpy.ndarray or int
            Per channel, the sequence numbers, or the first of n consecutive ones.
        n : int
            The number of rows.

        """
        slots, time_at, words = {}, [], []
        for t in log_times:                  # one source per distinct times array
            u = slots.get(id(t))
            if u is None:
                u = slots[id(t)] = len(words)
                words.append(np.asarray(t[:n], dtype=np.int64).view(np.uint64))
            time_at += [u, u]
        for p in payloads:
            if isinstance(p, EncodedRows):
                words += [w for _off, w in p.fields(0)]
        at8 = np.concatenate([np.array(time_at, dtype=np.uint64),
                              self._payload_at + np.uint64(len(slots))])
        if all(isinstance(q, (int, np.integer)) for q in sequences):
            src4 = (np.array(sequences, dtype=np.uint64)[:, None]
                    + np.arange(n, dtype=np.uint64)).astype(np.uint32)
        else:
            src4 = np.stack([np.arange(q, q + n) if isinstance(q, (int, np.integer))
                             else np.asarray(q[:n]) for q in sequences]).astype(np.uint32)
        return np.stack(words), at8, self.dst8, src4, self.at4, self.dst4

    def scatter(self, block, k, sources, payloads):
        """
        Write rows ``k .. k + len(block) - 1`` of messages into ``block`` (r, width).

        ``sources``: what :meth:`sources` returned; ``payloads``: as given there.
        """
        r = len(block)
        scatter(block.reshape(-1), self.width, r, self.row, k, *sources)
        for j, start, width in self.plain:
            block[:, start:start + width] = payloads[j][k:k + r]


def encode_rows(rows):
    """Return the messages of :class:`EncodedRows` as a uint8 array (n, width)."""
    fields = rows.fields(0)
    out = np.empty((rows.n, rows.width), dtype=np.uint8)
    words = [w for _o, w in fields] or [np.zeros(rows.n, dtype=np.uint64)]
    none = np.zeros(0, dtype=np.uint64)
    scatter(out.reshape(-1), rows.width, rows.n, rows.tmpl, 0, np.stack(words),
            np.arange(len(fields), dtype=np.uint64),
            np.array([o for o, _w in fields], dtype=np.uint64),
            np.zeros((1, rows.n), dtype=np.uint32), none, none)
    return out


def _scatter(flat, width, r, row, k, src8, at8, dst8, src4, at4, dst4):
    """
    Write r rows of records: the template ``row`` and, over it, each row's fields.

    Each word is stored byte by byte, little-endian, with unsigned indices:
    the compiled loop has no negative-index checks and LLVM merges the
    bytes into one unaligned store.

    Parameters
    ----------
    flat : numpy.ndarray of uint8, shape (r * width,)
        The records written, row after row.
    width, r : int
        The row length [B] and the number of rows.
    row : numpy.ndarray of uint8, shape (width,)
        The template of a record row.
    k : int
        The source column of the block's first row.
    src8, src4 : numpy.ndarray of uint64 (sources, n) and uint32 (sources, n)
        The words of each source.
    at8, dst8, at4, dst4 : numpy.ndarray of uint64
        Per field: its source and its byte offset in a row.

    """
    w = np.uint64(width)
    b8 = np.uint64(255)
    b4 = np.uint32(255)
    for i in range(r):
        base = np.uint64(i) * w
        for c in range(width):
            flat[base + np.uint64(c)] = row[c]
        ki = np.uint64(k + i)
        for f in range(at8.shape[0]):
            v = src8[at8[f], ki]
            o = base + dst8[f]
            for q in range(8):
                flat[o + np.uint64(q)] = np.uint8((v >> np.uint64(8 * q)) & b8)
        for f in range(at4.shape[0]):
            v = src4[at4[f], ki]
            o = base + dst4[f]
            for q in range(4):
                flat[o + np.uint64(q)] = np.uint8((v >> np.uint32(8 * q)) & b4)


def _scatter_numpy(flat, width, r, row, k, src8, at8, dst8, src4, at4, dst4):
    """Do what :func:`_scatter` does, in numpy (without numba)."""
    block = flat.reshape(r, width)
    block[:] = row
    for src, at, dst, w in ((src8, at8, dst8, 8), (src4, at4, dst4, 4)):
        for u, o in zip(at.tolist(), dst.tolist()):
            block[:, o:o + w] = src[u, k:k + r].astype(f'<u{w}').view(np.uint8).reshape(r, w)


_COMPILED = []


def scatter(*args):
    """
    Run :func:`_scatter` compiled (numba, imported at the first call), else in numpy.

    numba is imported only here, so a process that writes messages one by one
    (the node's recording child) never loads it.
    """
    if not _COMPILED:
        try:
            from numba import njit
            _COMPILED.append(njit(cache=True, nogil=True)(_scatter))
        except ImportError:  # pragma: no cover
            _COMPILED.append(_scatter_numpy)
    _COMPILED[0](*args)
