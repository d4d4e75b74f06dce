"""The offline runs' malloc settings: taken by glibc, once per process."""
import platform

import pytest

from leadscrew_sim.offline import options as args


@pytest.mark.skipif(platform.libc_ver()[0] != 'glibc', reason='glibc only')
def test_glibc_takes_the_malloc_settings():
    """The C library takes both mallopt thresholds; a second call keeps the first answer."""
    assert args.keep_freed_memory() is True
    assert args.keep_freed_memory() is True
