"""The run library of the ``freqresp`` verb family."""
