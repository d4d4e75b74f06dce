"""``python -m leadscrew_sim.node``: the ROS 2 node, :mod:`leadscrew_sim.ros.node`."""
import sys

from .ros.node import main

__all__ = ['main']

if __name__ == '__main__':
    sys.exit(main())
