"""
The messages of a block of ticks, written in the node's per-tick order in few calls.

Tick i of a block contributes its events (the commands logged at or before
the tick's start, in the order they came) and then its states (logged at
the tick's end). The file order is therefore ``E_0, S_0, E_1, S_1, ...``.
A regular stream, one command of one channel per tick, is written as rows
``(S_{i-1}, C_i)``: both carry the log time of tick i's start, so a row is
one log time and the writer may cut chunks between rows, at tick
boundaries only (:meth:`McapWriter.add_rows`). Other events go one by one.
"""


class Stream:
    """
    One command message of channel ``channel`` in each tick ``i0 .. i1 - 1`` of a block.

    Parameters
    ----------
    i0, i1 : int
        The block indices of its first tick and one past its last.
    channel : int
        Channel id.
    rows : numpy.ndarray of uint8, shape (i1 - i0, L)
        The messages, fixed length.
    log_times : numpy.ndarray of int64, shape (i1 - i0,)
        Their log times [ns].

    """

    __slots__ = ('i0', 'i1', 'channel', 'rows', 'log_times')

    def __init__(self, i0, i1, channel, rows, log_times):
        """Keep the ticks, the channel and the messages."""
        self.i0, self.i1, self.channel = int(i0), int(i1), channel
        self.rows, self.log_times = rows, log_times


class Events:
    """
    The events of tick ``i`` of a block: ``[(channel, bytes, log_time [ns])]`` in order.

    Parameters
    ----------
    i : int
        The block index of the tick.
    messages : list of tuple
        ``(channel id, message bytes, log time [ns])``.

    """

    __slots__ = ('i0', 'i1', 'messages')

    def __init__(self, i, messages):
        """Keep the tick and its messages."""
        self.i0, self.i1, self.messages = int(i), int(i) + 1, messages


def write_block(rec, pieces, state_channels, state_rows, state_times):
    """
    Write a block's events and states, tick by tick in the node's order, in few calls.

    Parameters
    ----------
    rec : leadscrew_sim.io.mcap_file.McapRecorder
        The recording (``write`` and ``write_rows``).
    pieces : sequence of Stream or Events
        The block's events in tick order, not overlapping; ticks with no piece
        have no events.
    state_channels : list of int
        The state channels, in the order of each tick's states.
    state_rows : list of numpy.ndarray of uint8
        Per state channel, one row (fixed-length message) per tick of the block.
    state_times : numpy.ndarray of int64
        The log time of each tick's states [ns].

    """
    n = len(state_times)
    m = len(state_channels)
    done = 0                        # the states of ticks < done are written

    def states(a, b):               # the states of ticks a .. b - 1 alone
        if b > a:
            rec.write_rows(state_channels, [r[a:b] for r in state_rows],
                           [state_times[a:b]] * m)

    for piece in pieces:
        if isinstance(piece, Events):
            states(done, piece.i0)
            for channel, data, log_time in piece.messages:
                rec.write(channel, data, log_time)
            done = piece.i0
            continue
        i0, i1 = piece.i0, piece.i1
        if i0 == 0:                 # no states before its first command
            rec.write(piece.channel, piece.rows[0].tobytes(), int(piece.log_times[0]))
            first = 1
        else:
            states(done, i0 - 1)
            first = 0
        a = i0 + first              # rows (S_{i-1}, C_i) for i = a .. i1 - 1
        if i1 > a:
            rec.write_rows(state_channels + [piece.channel],
                           [r[a - 1:i1 - 1] for r in state_rows] + [piece.rows[first:]],
                           [state_times[a - 1:i1 - 1]] * m + [piece.log_times[first:]])
        done = i1 - 1
    states(done, n)
