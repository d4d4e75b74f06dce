"""The run library of the ``identify`` verb family."""
