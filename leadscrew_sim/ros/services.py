"""
The node's services, ``~/reset``, ``~/clear_fault`` and ``~/record``: a mix-in of the node class.

Each handler changes the model or the recorder through the node's state and
records what it did (reset and clear_fault as metadata records with their
log time), so ``resim`` replays it at the same step.
"""
import rclpy

from ..core.commands import NutMap
from ..core.drive_modes import FAULT_NAMES, FAULT_NONE
from ..io.run_file import CLEAR_FAULT_RECORD, RESET_RECORD

NS = 1_000_000_000


class AxisServices:
    """The service handlers (a mix-in: uses the node's model, inputs and recorder)."""

    def _on_reset(self, _request, response):
        self.model.reset()
        self.inputs.reset(NutMap.of_model(self.model))
        self.delivery.reset()
        self.recorder.add_metadata(RESET_RECORD, {'log_time_ns': self._sim_now()})
        response.success = True
        response.message = (f'reset to the initial state at stamp {self._sim_now() / NS:.6f} s '
                            f'({"ROS time" if self.mode == "realtime" else "sim time"})')
        self.get_logger().info(response.message)
        return response

    def _on_clear_fault(self, _request, response):
        if self.params.fault_drive_fault:
            response.success = False
            response.message = ('fault.drive_fault is still true: the injected fault persists; '
                                'set it false first')
            return response
        code = self.model.clear_fault()
        self._fault_seen = 0
        if code != FAULT_NONE:
            self.recorder.add_metadata(CLEAR_FAULT_RECORD, {'log_time_ns': self._sim_now()})
        if code == FAULT_NONE:
            response.success, response.message = True, 'no drive fault latched'
        else:
            response.success = True
            response.message = (f'cleared the {FAULT_NAMES[code]} fault: holding the '
                                'position, waiting for a command')
            self.get_logger().info(response.message)
        return response

    def _on_record(self, request, response):
        result = self.set_parameters([rclpy.parameter.Parameter('record', value=request.data)])
        ok = result[0].successful
        if self.recorder.active:
            self.recorder.wait_for_path(timeout=5.0)
        file, _size, _n, err = self.recorder.status()
        response.success = bool(ok and (self.recorder.active == request.data))
        if not ok:
            response.message = result[0].reason
        elif self.recorder.active:
            response.message = f'recording to {file}' if file else 'recording (file not open yet)'
        else:
            response.message = err or 'recording stopped'
        return response
