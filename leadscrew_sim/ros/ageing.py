"""
The node's ageing: its state file, ``~/relubricate`` and the live ``sim/ageing``.

A mix-in of the node class. With ``ageing_state_file`` the node loads the
axis's ageing state at start (a missing file starts a new axis), writes it
every ``ageing_state_period`` of wall time and at shutdown, atomically
(:mod:`leadscrew_sim.io.ageing_file`). A file it cannot use (unreadable,
damaged, of another preset or axis) gets one error line; the node then runs
from a new axis's state and never writes over that file.

``~/relubricate`` (std_srvs/Trigger) renews the lubricant; the recording
notes it (:data:`~leadscrew_sim.io.run_file.RELUBRICATE_RECORD`) so ``resim``
replays it at the same step.

The recording holds ``sim/ageing`` (leadscrew_sim/msg/AgeingState) at every
recorded tick. On the graph the same values go out at 100 Hz at most as a
``std_msgs/msg/Float64MultiArray`` on ``sim/ageing``, one dimension whose
label names the fields in order (:data:`~leadscrew_sim.io.messages.AGEING_VALUES`):
the rclpy wheels cannot create a publisher of a message type without its
generated type support, which this package does not build.
"""
import os

from std_msgs.msg import Float64MultiArray, MultiArrayDimension
from std_srvs.srv import Trigger

from ..io.ageing_file import AgeingFileError, read_state, write_state
from ..io.messages import AGEING_VALUES
from ..io.run_file import AGEING_END_RECORD, ageing_record, RELUBRICATE_RECORD

NS = 1_000_000_000

#: Highest rate of the live sim/ageing [Hz].
AGEING_RATE = 100.0


class AxisAgeing:
    """The ageing state file, relubrication and live ageing topic (a mix-in of the node)."""

    def _start_ageing(self):
        """Load the state file (if set), create the service, the publisher and the timer."""
        s = self.settings
        self._ageing_file_ok = bool(s.ageing_state_file)
        if s.ageing_state_file:
            self._load_ageing(s.ageing_state_file)
            self.create_timer(s.ageing_state_period, self._save_ageing)
        self.create_service(Trigger, '~/relubricate', self._on_relubricate)
        self._pub_ageing = self.create_publisher(Float64MultiArray, 'sim/ageing', 10)
        self._ageing_every = max(1, round(s.update_rate / AGEING_RATE))
        self._ageing_msg = Float64MultiArray()
        self._ageing_msg.layout.dim = [MultiArrayDimension(
            label=','.join(AGEING_VALUES), size=len(AGEING_VALUES), stride=len(AGEING_VALUES))]

    def _load_ageing(self, path):
        log = self.get_logger()
        try:
            state = read_state(path, self.params, self.preset)
        except AgeingFileError as exc:
            if not os.path.exists(path):
                log.info(f'ageing_state_file {path!r} does not exist yet: a new axis; the '
                         'state is written there')
                return
            log.error(f'{exc}; running from a new axis, the file is left as it is')
            self._ageing_file_ok = False
            return
        self.model.set_ageing_state(state)
        self.model.reset()                      # the nut seated on its worn flanks
        log.info(f'ageing state loaded from {path!r}: wear {state["wear_leading_a"]:.3g} / '
                 f'{state["wear_trailing_a"]:.3g} m, lubricant {state["lubricant"]:.4g}, '
                 f'screw at {state["screw_temperature"]:.4g} degC')

    def _save_ageing(self):
        """Write the state file (never over a file the node refused to load)."""
        if not self._ageing_file_ok:
            return
        try:
            write_state(self.settings.ageing_state_file, self.model.ageing_state(),
                        self.params, self.preset, self._sim_now() / NS)
        except AgeingFileError as exc:
            self.get_logger().error(str(exc), throttle_duration_sec=60.0)

    def _on_relubricate(self, _request, response):
        self.model.relubricate()
        self.recorder.add_metadata(RELUBRICATE_RECORD, {'log_time_ns': str(self._sim_now())})
        response.success = True
        response.message = f'lubricant renewed at stamp {self._sim_now() / NS:.6f} s'
        self.get_logger().info(response.message)
        return response

    def _publish_ageing(self):
        """Publish the live sim/ageing (every _ageing_every-th step)."""
        if self.n % self._ageing_every == 0 and self._publishing:
            self._ageing_msg.data = list(self.model.ageing_values())
            self._pub_ageing.publish(self._ageing_msg)

    def ageing_metadata(self):
        """Return the parameters record's keys of the ageing state now (a recording's start)."""
        return ageing_record(self.model.ageing_state())

    def _note_ageing_end(self):
        """Record the ageing state at the end of a recording (simulate --ageing-from reads it)."""
        if self.recorder.active:
            self.recorder.add_metadata(AGEING_END_RECORD, {
                'log_time_ns': str(self._sim_now()), **ageing_record(self.model.ageing_state())})
