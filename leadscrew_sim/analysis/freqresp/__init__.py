"""
Frequency response of the axis (physics.md section 13): linear, simulated and from a recording.

- :mod:`.response`: :class:`FrequencyResponse`, what every source returns.
"""
from .response import FrequencyResponse

__all__ = ['FrequencyResponse']
