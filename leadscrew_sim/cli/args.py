"""The verbs' shared parser pieces: the one-line parser, its usage error, shared options."""
import argparse
import sys

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


class _DeprecatedAlias(argparse.Action):
    """Store the value like the option it stands for and print one deprecation line."""

    def __init__(self, option_strings, dest, new=None, **kwargs):
        super().__init__(option_strings, dest, **kwargs)
        self.new = new

    def __call__(self, parser, namespace, values, option_string=None):
        """Print the deprecation line on stderr and store ``values`` in ``dest``."""
        print(f'{PROG}: warning: {option_string} is deprecated here; use {self.new}',
              file=sys.stderr)
        setattr(namespace, self.dest, values)


def add_deprecated_alias(p, old, new, dest, type=None):
    """
    Add ``old`` to parser ``p``: a hidden spelling of option ``new`` (same ``dest``).

    It takes one value of ``type``, is not shown in ``--help`` and prints
    ``leadscrew_sim: warning: OLD is deprecated here; use NEW`` on stderr when used.
    """
    p.add_argument(old, dest=dest, type=type, action=_DeprecatedAlias, new=new,
                   default=argparse.SUPPRESS, help=argparse.SUPPRESS)
