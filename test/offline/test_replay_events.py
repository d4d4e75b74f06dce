"""
RecordedEvents: the recorded events in the order resim applies them.

The oracle is Python's stable ``sorted`` on (log time, key) over the events in
the order they were added, and the events' own tuples.
"""
import numpy as np

from leadscrew_sim.offline.replay.events import RecordedEvents


def _float_rows(values):
    """Return std_msgs/Float64 messages of ``values`` as uint8 rows (n, 12)."""
    rows = np.zeros((len(values), 12), dtype=np.uint8)
    rows[:, 1] = 1                                   # CDR little-endian header
    rows[:, 4:] = np.asarray(values, dtype='<f8').view(np.uint8).reshape(-1, 8)
    return rows


def test_events_come_in_log_time_then_key_order_as_a_stable_sort():
    """Two topics and records, interleaved and tied in time, sort as sorted() does."""
    rng = np.random.default_rng(3)
    a_t = np.sort(rng.integers(0, 50, 40)) * 1000
    b_t = np.sort(rng.integers(0, 50, 30)) * 1000
    a_rows = _float_rows(rng.standard_normal(40))
    b_data = [bytes([i]) * (1 + i % 3) for i in range(30)]          # of unequal length
    a_keys, b_keys = rng.integers(1, 4, 40), rng.integers(1, 4, 30)
    item_t = rng.integers(0, 50, 5) * 1000
    items = [(int(t), 'update', {'n': str(i)}) for i, t in enumerate(item_t)]
    item_keys = [2.5, float('inf'), 0.5, 1.5, 2.5]
    ev = RecordedEvents()
    ev.add_topic('torque_command', a_t, a_keys, a_rows)
    ev.add_topic('external_force', b_t, b_keys, b_data)
    ev.add_items(items, item_keys)
    ev.sort()
    added = ([(int(t), float(k), ('torque_command', a_rows[i].tobytes()))
              for i, (t, k) in enumerate(zip(a_t, a_keys))]
             + [(int(t), float(k), ('external_force', b_data[i]))
                for i, (t, k) in enumerate(zip(b_t, b_keys))]
             + [(t, k, (kind, d)) for (t, kind, d), k in zip(items, item_keys)])
    want = [(t, kind, d) for t, _k, (kind, d) in sorted(added, key=lambda e: (e[0], e[1]))]
    assert len(ev) == len(want)
    assert [ev[i] for i in range(len(ev))] == want
    assert ev[3:9] == want[3:9]
    assert list(ev.times) == [w[0] for w in want]
    code = {'torque_command': 0, 'update': 7}
    assert ev.codes(code).tolist() == [code.get(w[1], -1) for w in want]
    assert [ev.kind(i) for i in range(len(ev))] == [w[1] for w in want]


def test_rows_of_a_run_are_the_topic_rows_else_none():
    """rows() gives a run of one topic's consecutive messages as its rows, and nothing else."""
    rows = _float_rows(np.arange(6.0))
    ev = RecordedEvents()
    ev.add_topic('position_command', np.arange(6) * 10, np.ones(6), rows)
    ev.add_items([(25, 'reset', {})], [np.inf])          # between the 3rd and the 4th
    ev.sort()
    assert [ev.kind(i) for i in range(7)] == ['position_command'] * 3 + ['reset'] + \
        ['position_command'] * 3
    assert np.array_equal(ev.rows(0, 3), rows[0:3])
    assert np.array_equal(ev.rows(4, 7), rows[3:6])
    assert ev.rows(2, 5) is None                      # the reset lies inside
    assert ev.rows(3, 4) is None                      # a record, not a topic's rows
    lists = RecordedEvents()
    lists.add_topic('torque_command', [0, 1], [1, 1], [b'ab', b'cd'])
    lists.sort()
    assert lists.rows(0, 2) is None and lists[1] == (1, 'torque_command', b'cd')
