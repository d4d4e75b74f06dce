"""The verbs' shared parser pieces: the one-line parser, its usage error, shared options."""
import argparse

from ..offline.options import RunError

PROG = 'leadscrew_sim'


class UsageError(RunError):
    """A command-line usage error (exit status 2)."""


class Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line (no usage dump)."""

    def error(self, message):
        """Raise UsageError instead of printing the usage and exiting."""
        raise UsageError(message)


def add_compression_argument(p):
    """Add ``--compression`` (of the MCAP chunks written) to parser ``p``."""
    p.add_argument('--compression', choices=('lz4', 'zstd', 'none'), default='lz4',
                   help='chunk compression of the MCAP written (default lz4: written and read '
                        'about twice as fast as zstd, files about a third larger)')
