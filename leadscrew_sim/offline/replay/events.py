"""
The recorded events of a recording in log-time order, held as arrays.

A recording's events are its command messages and its model records
(parameter updates, resets, fault clearings). :class:`RecordedEvents` keeps,
per event, its log time and where it comes from (a topic's message rows, or
a list of (kind, payload)), and forms the ``(log_time, kind, payload)`` tuple
of an event only when it is asked for; a run of consecutive messages of one
topic is handed out whole, as the topic's rows (:meth:`RecordedEvents.rows`).
"""
import numpy as np


class RecordedEvents:
    """
    Events in log-time order: ``events[i]`` is ``(log_time [ns], kind, payload)``.

    Built from sources with :meth:`add_topic` and :meth:`add_items`, then put in
    order once by :meth:`sort`.
    """

    def __init__(self):
        """Start with no event."""
        self._kinds = []            # per source: its kind (None: per item)
        self._data = []             # per source: rows (n, L), a list of bytes, or of items
        self._parts = []            # per source: (times, sort keys, source number)
        self.times = np.zeros(0, dtype=np.int64)
        self.source = np.zeros(0, dtype=np.int64)
        self.index = np.zeros(0, dtype=np.int64)

    def add_topic(self, kind, log_times, keys, data):
        """
        Add the messages of one topic, in file order.

        Parameters
        ----------
        kind : str
            The topic's role (``'torque_command'``, ...).
        log_times : numpy.ndarray of int64
            Their log times [ns].
        keys : numpy.ndarray of float
            Their order among the events of one log time (rank in the file).
        data : numpy.ndarray of uint8 (n, L) or list of bytes
            Their payloads.

        """
        self._add(kind, np.asarray(log_times, dtype=np.int64), keys, data)

    def add_items(self, items, keys):
        """Add events ``[(log_time [ns], kind, payload)]`` with their order keys."""
        times = np.array([t for t, _k, _d in items], dtype=np.int64)
        self._add(None, times, keys, [(k, d) for _t, k, d in items])

    def _add(self, kind, times, keys, data):
        if len(times):
            self._parts.append((times, np.asarray(keys, dtype=float), len(self._kinds)))
            self._kinds.append(kind)
            self._data.append(data)

    def sort(self):
        """Put the events in order: by log time, then by key, then as added."""
        if not self._parts:
            return
        times = np.concatenate([p[0] for p in self._parts])
        keys = np.concatenate([p[1] for p in self._parts])
        source = np.concatenate([np.full(len(p[0]), p[2]) for p in self._parts])
        index = np.concatenate([np.arange(len(p[0])) for p in self._parts])
        same = times[1:] == times[:-1]
        if not ((times[1:] > times[:-1]) | (same & (keys[1:] >= keys[:-1]))).all():
            order = np.lexsort((keys, times))          # stable: as added among equals
            times, source, index = times[order], source[order], index[order]
        self.times, self.source, self.index = times, source, index

    def __len__(self):
        """Return the number of events."""
        return len(self.times)

    def __getitem__(self, i):
        """Return event ``i`` as ``(log_time, kind, payload)``, or a list of them for a slice."""
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        u, j = int(self.source[i]), int(self.index[i])
        data = self._data[u]
        if self._kinds[u] is None:
            kind, payload = data[j]
        else:
            kind = self._kinds[u]
            payload = data[j].tobytes() if isinstance(data, np.ndarray) else data[j]
        return int(self.times[i]), kind, payload

    def kind(self, i):
        """Return the kind of event ``i``."""
        u = int(self.source[i])
        return self._kinds[u] if self._kinds[u] is not None else self._data[u][self.index[i]][0]

    def codes(self, code, n=None):
        """Return ``code[kind]`` (-1 if absent) of each of the first ``n`` events (all)."""
        n = len(self) if n is None else n
        out = np.full(n, -1, dtype=np.int64)
        source, index = self.source[:n], self.index[:n]
        for u, kind in enumerate(self._kinds):
            at = np.flatnonzero(source == u)
            if kind is not None:
                out[at] = code.get(kind, -1)
            else:
                data = self._data[u]
                out[at] = [code.get(data[j][0], -1) for j in index[at].tolist()]
        return out

    def rows(self, e0, e1):
        """
        Return the payloads of events ``e0 .. e1 - 1`` as a uint8 array (n, L), or None.

        An array when they are consecutive messages of one topic read as fixed-length
        messages, else None.
        """
        if e1 <= e0:
            return None
        u = int(self.source[e0])
        data = self._data[u]
        if self._kinds[u] is None or not isinstance(data, np.ndarray):
            return None
        src, idx = self.source[e0:e1], self.index[e0:e1]
        if (src != u).any() or idx[-1] - idx[0] != e1 - e0 - 1 or (np.diff(idx) != 1).any():
            return None
        return data[idx[0]:idx[-1] + 1]
