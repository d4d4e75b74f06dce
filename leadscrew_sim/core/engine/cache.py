"""
Where numba keeps the compiled kernel: one place for every way of running the package.

``make``, the plain virtual environment's commands and ``ros2 run`` in a colcon
workspace all compile into and load from the same directory:
``$NUMBA_CACHE_DIR`` when it is set, else ``$XDG_CACHE_HOME/leadscrew_sim/numba``
(``~/.cache/leadscrew_sim/numba`` by default). numba keys each entry on the
source file it came from, so a second installed copy of the package (a colcon
install space beside a source checkout) keeps entries of its own there.
"""
import os
import sys

#: The environment variable numba reads its cache directory from.
CACHE_ENV = 'NUMBA_CACHE_DIR'


def default_cache_dir():
    """Return the package's numba cache directory when ``NUMBA_CACHE_DIR`` is not set."""
    base = os.environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache')
    return os.path.join(base, 'leadscrew_sim', 'numba')


def use_cache_dir():
    """
    Point numba's cache at :func:`default_cache_dir` unless ``NUMBA_CACHE_DIR`` is set.

    Called before the compiled functions are defined; works whether or not
    numba is already imported. Returns the directory used.
    """
    path = os.environ.get(CACHE_ENV) or default_cache_dir()
    os.environ[CACHE_ENV] = path
    config = sys.modules.get('numba.core.config')
    if config is not None:
        config.CACHE_DIR = path
    return path
