"""
Message records of fixed-layout CDR messages, written straight into a chunk's block.

:class:`EncodedRows` holds n messages of one fixed layout (a
:class:`~leadscrew_sim.io.cdr.Template`, a TF message) as their stamps and
doubles, not as bytes; :meth:`McapWriter.add_rows` writes each message
(template bytes, stamps and doubles) into the block of its chunk's records
with a few numpy copies per block: the template broadcast, then each run of
consecutive doubles at once, instead of encoding the messages first and
copying them after. The bytes are those of the layout's ``rows``.
"""
import numpy as np

from .cdr import stamp_rows


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
    stamps_ns : numpy.ndarray of int64 or None
        The stamp of each message (None: stamp-less).
    columns : list of numpy.ndarray
        One float array (n,) per double, in the order of ``offsets``.

    """

    __slots__ = ('template_bytes', 'tmpl', 'stamp_offsets', 'runs', 'stamps', 'values', 'n')

    def __init__(self, template, stamp_offsets, offsets, stamps_ns, columns):
        """Keep the layout; stack the stamps' and the doubles' bytes."""
        self.template_bytes = bytes(template)
        self.tmpl = np.frombuffer(self.template_bytes, dtype=np.uint8)
        self.stamp_offsets = tuple(int(o) for o in stamp_offsets)
        self.runs = _runs(offsets)
        n = len(columns[0]) if columns else len(stamps_ns)
        self.n = n
        self.stamps = None
        if self.stamp_offsets:
            self.stamps = stamp_rows(stamps_ns)
        values = np.empty((n, len(columns)), dtype='<f8')
        for j, c in enumerate(columns):
            values[:, j] = c
        self.values = values.view(np.uint8).reshape(n, 8 * len(columns))

    @classmethod
    def of_template(cls, template, stamps_ns, columns):
        """
        Return the messages of a :class:`~leadscrew_sim.io.cdr.Template`.

        Parameters
        ----------
        template : Template
            The layout (one stamp or none, its doubles).
        stamps_ns : numpy.ndarray of int64 or None
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
        out.stamp_offsets, out.runs = self.stamp_offsets, self.runs
        out.stamps = None if self.stamps is None else self.stamps[index]
        out.values = self.values[index]
        out.n = len(out.values)
        return out

    @property
    def width(self):
        """Return the message length [B]."""
        return len(self.tmpl)

    def tobytes_rows(self):
        """Return the messages as a uint8 array (n, width), as the layout's ``rows`` does."""
        out = np.empty((self.n, self.width), dtype=np.uint8)
        fill(out, 0, self, 0, self.n)
        return out


def _runs(offsets):
    """Return (first value, past the last, byte offset) of each run of adjacent doubles."""
    runs, j = [], 0
    offsets = [int(o) for o in offsets]
    while j < len(offsets):
        e = j + 1
        while e < len(offsets) and offsets[e] == offsets[e - 1] + 8:
            e += 1
        runs.append((j, e, offsets[j]))
        j = e
    return tuple(runs)


def fill(block, start, rows, k, r, template=True):
    """
    Write messages ``k .. k + r - 1`` of ``rows`` into ``block[:, start:]``, one per row.

    Parameters
    ----------
    block : numpy.ndarray of uint8, shape (r, row length)
        The records being built.
    start : int
        The column of the first payload byte.
    rows : EncodedRows
        The messages.
    k, r : int
        The first message and the number of messages.
    template : bool
        Also write the template's bytes (False: the block holds them already).

    """
    if template:
        block[:, start:start + rows.width] = rows.tmpl
    for off in rows.stamp_offsets:
        block[:, start + off:start + off + 8] = rows.stamps[k:k + r]
    values = rows.values[k:k + r]
    for j0, j1, off in rows.runs:
        block[:, start + off:start + off + 8 * (j1 - j0)] = values[:, 8 * j0:8 * j1]
