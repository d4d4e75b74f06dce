"""The one error type of a failed integration."""


from .errors import LeadscrewError


class SimulationFault(LeadscrewError, FloatingPointError):
    """
    The integration met a non-finite state and stopped; the state is the one before the step.

    Raised by :class:`leadscrew_sim.core.model.LeadScrewModel`; the model keeps
    refusing to step until :meth:`~leadscrew_sim.core.model.LeadScrewModel.reset`.
    ``time`` is the simulated time [s] of the last good state.
    """

    def __init__(self, message, time=float('nan')):
        """Keep the message and the simulated time [s] of the last good state."""
        super().__init__(message)
        self.time = time
