"""The run library of the ``replay`` verb family."""
