"""
The node's main loops, one per clock mode: a mix-in of the node class.

- ``realtime``: absolute-deadline loop on CLOCK_MONOTONIC, step n due at
  ``t0 + n dt``; a late tick takes every step due and publishes the last
  ``1 + max_catchup_steps`` of them (the older ones of a stall are integrated
  and recorded, counted as skipped, not published).
- ``stepped``: sim time from 0, as fast as possible or paced at ``real_time_factor``.
- ``lockstep``: one tick per received command (the command callbacks step).

The node provides ``_step``, ``_spin`` budget, the recorder, the loop
statistics and the diagnostics; these loops only pace and count.
"""
import time

from .timing import DeadlineSleeper

NS = 1_000_000_000


class ClockLoops:
    """The clock modes' main loops (a mix-in: uses the node's state and methods)."""

    def stop(self):
        """Ask the main loop to finish (signal-safe)."""
        self._running = False

    def run(self, executor):
        """Run the clock mode's main loop until stop()."""
        self._executor = executor
        self.loop.run_start = time.monotonic_ns()
        self._next_diag = self.loop.run_start + NS
        getattr(self, f'_run_{self.mode}')()
        self.loop.run_end = time.monotonic_ns()

    def _spin(self):
        """
        Process the pending events: one spin_once, again while commands keep coming.

        At most 16 events and about a quarter of a period per tick: a command
        flood (tens of thousands per second from another process) then delays
        commands (the latest one wins anyway) instead of starving the loop.
        """
        ex = self._executor
        end = time.monotonic_ns() + self._spin_budget_ns
        for _ in range(16):
            before = self._events
            ex.spin_once(timeout_sec=0)
            if self._events == before or time.monotonic_ns() >= end:
                break

    def _run_realtime(self):
        """
        Step n is due at ``t0_mono + n dt`` on CLOCK_MONOTONIC, the instant of its stamp.

        A late tick takes every step due: the last ``1 + max_catchup_steps``
        publish, the older ones (a stall) are integrated and recorded but not
        published, counted as skipped and logged. The model never falls
        behind the clock, so every stamp stays the system time of its tick.
        """
        period, loop = self.dt_ns, self.loop
        sleeper = DeadlineSleeper()
        origin = self.t0_mono_ns
        before = (time.monotonic_ns() - origin) // period - self.n
        if before > 0:          # the time from t0 (construction) to the loop's start
            self.get_logger().info(f'loop started {before * period / 1e6:.1f} ms after t0: '
                                   f'{before} steps integrated and recorded, not published')
            self.tick_time = origin + (self.n + 1) * period
            self._silent_steps(before)
        while self._running:
            deadline = origin + (self.n + 1) * period
            sleeper.sleep_until(deadline)
            now = time.monotonic_ns()
            if now < deadline:
                continue                    # woken early by a signal
            late = now - deadline
            loop.late(late)
            self.tick_time = deadline
            self._spin()
            due = 1 + late // period
            steps = min(due, 1 + self.settings.max_catchup_steps)
            if due > steps:
                self._stall(due - steps, late)
            for i in range(due - steps, due):
                self._step(deadline + i * period)
            loop.catch_up(due, steps)
            loop.steps(due)
            self.recorder.flush()
            if now >= self._next_diag:
                self._publish_diagnostics(now)

    def _stall(self, silent, late_ns):
        """Integrate (and record) the ``silent`` oldest due steps of a stall without publishing."""
        self.get_logger().warn(
            f'loop stalled {late_ns / 1e6:.1f} ms: {silent} steps integrated without '
            f'publishing (skipped_steps {self.loop.skipped_steps + silent} so far)',
            throttle_duration_sec=1.0)
        self._silent_steps(silent)

    def _silent_steps(self, count):
        """Take ``count`` steps from the deadline ``tick_time`` on, recorded but not published."""
        deadline = self.tick_time
        self._publishing = False
        try:
            for i in range(count):
                self._step(deadline + i * self.dt_ns)
        finally:
            self._publishing = True

    def _run_stepped(self):
        sleeper = DeadlineSleeper()
        deadline = 0
        while self._running:
            rtf = self.settings.real_time_factor
            if rtf > 0.0:
                period = int(round(self.dt_ns / rtf))
                if self._pace_reset:
                    deadline = time.monotonic_ns()
                    self._pace_reset = False
                deadline += period
                sleeper.sleep_until(deadline)
            self.tick_time = self._sim_now()
            self._spin()
            self._step(self.tick_time)
            self.loop.steps(1)
            self.recorder.flush()
            now = time.monotonic_ns()
            if now >= self._next_diag:
                self._publish_diagnostics(now)

    def _run_lockstep(self):
        ex = self._executor
        self._pub_clock.publish(self._ser_clock(self._sim_now(), ()))
        while self._running:
            ex.spin_once(timeout_sec=0.05)
            now = time.monotonic_ns()
            if now >= self._next_diag:
                self._publish_diagnostics(now)
                self._pub_clock.publish(self._ser_clock(self._sim_now(), ()))
