"""The run library of the ``simulate`` verb family."""
