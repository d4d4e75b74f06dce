"""
The offline command line ``leadscrew_sim``: one module per verb.

- ``simulate``: run the model without ROS and write an MCAP file in the
  node's recording layout (same topics, types, joint names, metadata).
- ``info`` (``summary``): one screen about a recording (any ros2-profile MCAP).
- ``resim``: re-run the recorded commands through the model with the recorded
  (or overridden) parameters and report the difference from the recorded states.
- ``play``: republish the messages of any ros2-profile MCAP with their timing.
- ``plot``: one PNG with four panels of a leadscrew_sim recording.

Each verb module has ``add_arguments(parser)`` and ``run(args)``;
:func:`main` (:mod:`.main`) builds the parser and prints errors as one line.
"""
from .main import main

__all__ = ['main']
