"""
The recorder process: the node's MCAP recording, written off the simulation loop.

:class:`Recorder` (in the node) frames serialized messages onto a pipe;
:func:`recorder_child` (``python -m leadscrew_sim.io.recorder``) reads the
frames and writes them through a :class:`~leadscrew_sim.io.session.RecordingSession`.

Frame: ``FRAME`` header (channel id, length, log time [ns]) and the payload;
channel id 0 carries a JSON control record (``open`` with the session
configuration and channels, ``metadata``). The child reports its status as
one JSON line on stdout about twice a second and a ``final`` one at the end.

Neither side imports rclpy, a message package or numba: the child starts in
a fraction of the node's start-up time, and the parent takes any logger
with ``info`` and ``error`` methods.
"""
import fcntl
import json
import os
import signal
import struct
import subprocess
import sys
import time

__all__ = ['CHILD_BATCH_S', 'FRAME', 'Recorder', 'recorder_child']

#: Frame header: channel id (0: JSON control), payload length, log time [ns].
FRAME = struct.Struct('<IIq')
#: The recorder child reads the pipe every 10 ms.
CHILD_BATCH_S = 0.01


class Recorder:
    """
    Record through :class:`~leadscrew_sim.io.session.RecordingSession` in a child process.

    MCAP writing costs ~50 us per message in Python and stalls for 10-15 ms
    when a chunk is compressed and indexed; inside the 1 kHz loop (or in a
    thread, through the GIL) that would make ticks late. The node therefore
    only appends framed bytes to a pipe (a few us per tick); the child
    process ``recorder_child`` owns the session. The child ends on EOF (also
    when the node is killed: the file is closed cleanly) and ignores SIGINT
    and SIGTERM so a Ctrl-C to the process group cannot cut a write short.
    Errors never raise into the simulation loop; they are kept in ``error``
    and shown in diagnostics.

    A metadata record with a ``log_time_ns`` key (reset, parameter update) also
    gets ``messages_at_log_time``: the number of messages with that log time
    recorded before it, so a reader can tell whether, e.g., a reset came before
    or after a command logged in the same tick (``leadscrew_sim resim``).
    """

    MAX_PENDING = 64 << 20          # bytes buffered in the node before dropping

    def __init__(self, logger):
        """Create an idle recorder."""
        self._log = logger
        self._proc = None
        self._fd = None
        self._buf = bytearray()
        self._channels = {}
        self._status = {}
        self._status_tail = b''
        self._finishing = []
        self.error = None
        self.dropped = 0
        self._at_time = None            # log time of the last message queued
        self._at_count = 0              # messages queued with that log time

    @property
    def active(self):
        """Return True while a recording is open."""
        return self._fd is not None

    def start(self, options, channels, metadata):
        """
        Start a child process recording a new session.

        Parameters
        ----------
        options : leadscrew_sim.io.session.StorageOptions
            Where and how to record.
        channels : dict
            Topic -> (type name, offered QoS YAML or None, trim).
        metadata : dict
            The parameters record, ``{str: str}``.

        """
        self.stop(wait=False)
        self.error = None
        self._status = {}
        self.dropped = 0
        self._at_time, self._at_count = None, 0
        config = dict(options=options.to_dict(),
                      channels=[[t, typ, qos, trim] for t, (typ, qos, trim) in channels.items()],
                      metadata={'leadscrew_sim_parameters': metadata})
        try:
            proc = subprocess.Popen(
                [sys.executable, '-m', 'leadscrew_sim.io.recorder'],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, close_fds=True)
        except OSError as exc:
            self._fail(f'cannot start the recorder process: {exc}')
            return False
        self._proc = proc
        self._fd = proc.stdin.fileno()
        try:
            fcntl.fcntl(self._fd, 1031, 1 << 20)          # F_SETPIPE_SZ: 1 MiB
        except OSError:
            pass
        os.set_blocking(self._fd, False)
        os.set_blocking(proc.stdout.fileno(), False)
        self._channels = {t: i + 1 for i, t in enumerate(channels)}
        self._control({'op': 'open', **config})
        self.flush()
        return True

    def _control(self, obj):
        data = json.dumps(obj).encode()
        self._buf += FRAME.pack(0, len(data), 0) + data

    def write(self, topic, data, log_time_ns):
        """Queue one serialized message (sent to the child on the next flush())."""
        if self._fd is None:
            return
        if len(self._buf) > self.MAX_PENDING:
            self.dropped += 1
            return
        self._buf += FRAME.pack(self._channels[topic], len(data), log_time_ns)
        self._buf += data
        if log_time_ns == self._at_time:
            self._at_count += 1
        else:
            self._at_time, self._at_count = log_time_ns, 1

    def add_metadata(self, name, values):
        """Queue a metadata record (no-op when not recording)."""
        if self._fd is not None:
            data = {str(k): str(v) for k, v in values.items()}
            if 'log_time_ns' in values:
                same = int(values['log_time_ns']) == self._at_time
                data['messages_at_log_time'] = str(self._at_count if same else 0)
            self._control({'op': 'metadata', 'name': name, 'data': data})

    def flush(self):
        """Hand the queued bytes to the pipe without blocking (once per tick)."""
        if self._fd is None or not self._buf:
            return
        try:
            n = os.write(self._fd, self._buf)
        except BlockingIOError:
            return
        except OSError as exc:
            self._fail(f'recorder process gone: {exc}')
            return
        del self._buf[:n]

    def poll(self):
        """Read status lines from the child (non-blocking); call about once a second."""
        for proc in list(self._finishing):
            if proc.poll() is not None:
                self._finishing.remove(proc)
        proc = self._proc
        if proc is None:
            return
        try:
            chunk = os.read(proc.stdout.fileno(), 65536)
        except BlockingIOError:
            chunk = None
        except OSError:
            chunk = b''
        if chunk:
            lines = (self._status_tail + chunk).split(b'\n')
            self._status_tail = lines.pop()
            for line in lines:
                try:
                    self._status = json.loads(line)
                except ValueError:
                    pass
            if self._status.get('error') and not self.error:
                self.error = self._status['error']
                self._log.error(f'recording: {self.error}')
        if proc.poll() is not None and self._fd is not None:
            self._fail(f'recorder process exited with code {proc.returncode}')

    def stop(self, wait=True, timeout=20.0):
        """Close the recording: EOF to the child, which closes the file."""
        proc = self._proc
        if proc is None:
            return
        if self._fd is not None:
            os.set_blocking(self._fd, True)
            try:
                if self._buf:
                    proc.stdin.write(self._buf)
                proc.stdin.close()
            except OSError as exc:
                self.error = self.error or f'recorder process gone: {exc}'
            self._buf = bytearray()
            self._fd = None
        if wait:
            try:
                proc.wait(timeout=timeout)
                os.set_blocking(proc.stdout.fileno(), True)
                out = proc.stdout.read()
                proc.stdout.close()
                for line in (self._status_tail + (out or b'')).split(b'\n'):
                    try:
                        self._status = json.loads(line)
                    except ValueError:
                        pass
            except Exception:  # noqa: B902 - never raise at shutdown
                proc.kill()
            self._log.info(f'recording closed: {self._status.get("path")} '
                           f'({self._status.get("bytes")} B, '
                           f'{self._status.get("messages")} messages)')
            for other in self._finishing:
                try:
                    other.wait(timeout=timeout)
                except Exception:  # noqa: B902
                    other.kill()
            self._finishing = []
        else:
            self._finishing.append(proc)
        self._proc = None

    def wait_for_path(self, timeout):
        """
        Return the path of the file being written, waiting for the child to open it.

        Parameters
        ----------
        timeout : float
            Longest wait [s]; returns None if no file is open by then (or on an error).

        """
        end = time.monotonic() + timeout
        while self._proc is not None and not self.error:
            self.flush()
            self.poll()
            path = self._status.get('path')
            if path or time.monotonic() > end:
                return path or None
            time.sleep(0.005)
        return None

    def status(self):
        """Return (file, bytes, messages, error) for diagnostics."""
        st = self._status
        return (str(st.get('path') or ''), int(st.get('bytes') or 0),
                int(st.get('messages') or 0), self.error or st.get('error'))

    def _fail(self, message):
        self.error = message
        self._log.error(message)
        self._fd = None
        self._buf = bytearray()
        proc, self._proc = self._proc, None
        if proc is not None:
            try:
                proc.stdin.close()
            except OSError:
                pass
            self._finishing.append(proc)


def _lower_priority():
    """
    Yield to the node on wake-up, but keep a fair share of a loaded machine (SCHED_BATCH).

    SCHED_BATCH at nice 0: the child never preempts the node when it wakes
    (the scheduler treats it as a throughput task), yet it keeps the CPU share
    of any other process, which is several times the 3-7 % of a core it needs
    at 1 kHz. SCHED_IDLE (idle CPU only) would starve it on a saturated
    machine until the node's buffer (MAX_PENDING) fills and messages are lost.
    Where SCHED_BATCH is missing, the child stays at the default policy.
    """
    try:
        os.sched_setscheduler(0, os.SCHED_BATCH, os.sched_param(0))
    except (AttributeError, OSError):
        pass


def recorder_child():
    """Child process of Recorder: read frames from stdin, write the MCAP session."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    _lower_priority()
    src, out = sys.stdin.buffer, sys.stdout
    session, ids, error = None, {}, None
    last = 0.0

    def report(final=False):
        nonlocal out
        if out is None:
            return
        st = dict(path=str(session.current_path or '') if session else '',
                  bytes=session.bytes_written if session else 0,
                  messages=session.messages_written if session else 0,
                  error=error or (session.error if session else None), final=final)
        try:
            out.write(json.dumps(st) + '\n')
            out.flush()
        except OSError:
            # The node is gone (a killed node closes the status pipe): stop reporting,
            # point stdout at /dev/null so the exit flush cannot fail either, and go
            # on writing the file until the frame pipe ends.
            out = None
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            os.close(devnull)

    buf = bytearray()
    while True:
        chunk = src.read1(1 << 20)
        if not chunk:
            break
        buf += chunk
        pos = 0
        while len(buf) - pos >= FRAME.size:
            cid, n, t = FRAME.unpack_from(buf, pos)
            if len(buf) - pos - FRAME.size < n:
                break
            data = bytes(buf[pos + FRAME.size:pos + FRAME.size + n])
            pos += FRAME.size + n
            try:
                if cid:
                    if session is not None:
                        session.write(ids[cid], data, t)
                    continue
                ctl = json.loads(data)
                if ctl['op'] == 'open':
                    from .session import RecordingSession, StorageOptions
                    session = RecordingSession(StorageOptions(**ctl['options']),
                                               metadata=ctl['metadata'])
                    for i, (topic, typ, qos, trim) in enumerate(ctl['channels']):
                        ids[i + 1] = session.add_channel(topic, typ, qos, trim)
                    report()
                elif ctl['op'] == 'metadata' and session is not None:
                    session.add_metadata(ctl['name'], ctl['data'])
            except Exception as exc:  # noqa: B902 - report, keep draining the pipe
                if error is None:
                    error = f'{type(exc).__name__}: {exc}'.replace('\n', ' ')
                    report()
                session_bad = session
                session = None
                if session_bad is not None:
                    try:
                        session_bad.close()
                    except Exception:  # noqa: B902
                        pass
        del buf[:pos]
        now = time.monotonic()
        if now - last > 0.5:
            last = now
            report()
        # Let a few ticks pile up in the pipe (1 MiB): one wake-up per
        # CHILD_BATCH_S instead of one per tick. Adds at most that much to the
        # loss when the child itself is killed (a killed node only ends the pipe).
        time.sleep(CHILD_BATCH_S)
    if session is not None:
        session.close()
    report(final=True)


if __name__ == '__main__':
    recorder_child()
