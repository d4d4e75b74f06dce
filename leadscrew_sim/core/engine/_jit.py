"""
The one set of numba compile options shared by every kernel function.

friction, lcp and kernel decorate all their compiled functions with
``kernel_jit``, so caller and callee are always compiled with the same flags.
"""
import hashlib
import os

from .cache import use_cache_dir

use_cache_dir()      # before numba reads its configuration

try:  # numba is the accelerator; plain Python also works.
    from numba import njit
except ImportError:  # pragma: no cover
    def njit(*args, **kwargs):
        """Identity decorator used when numba is not installed."""
        if args and callable(args[0]):
            return args[0]
        return lambda fn: fn

# No fastmath, not even 'contract' (FMA fusion): numba links a private copy of every
# callee into each caller's object code, and LLVM fuses a * b + c differently in each
# copy. Which copy runs depends on what was compiled and what was loaded from the
# cache, so with contraction a fresh compile and a cached load gave different bits.
# Without it every operation is one IEEE 754 operation and the results are the same
# in every cache state.

# cache: compiled code is kept on disk (NUMBA_CACHE_DIR). error_model 'numpy': a
# division by zero gives inf/nan instead of raising. _nrt=False: the functions
# allocate nothing, so they are compiled without the numba runtime and the
# reference counting of their array arguments is skipped. nogil: they touch no
# Python object, so they release the GIL while they run (simulate and resim
# compress and write the previous block in another thread meanwhile).
JIT_OPTIONS = dict(cache=True, error_model='numpy', fastmath=False, _nrt=False, nogil=True)

#: The compiled functions, for refresh_cache().
DISPATCHERS = []

#: The modules whose source the compiled code depends on: their own functions, and the
#: constants of layout, drive and the core's drive_modes that numba freezes into the code
#: of every user.
KERNEL_SOURCES = ('_jit.py', 'layout.py', 'drive.py', 'friction.py', 'lcp.py', 'sensors.py',
                  'stages.py', 'impulses.py', 'stepper.py',
                  'write_back.py', 'kernel.py', os.path.join('..', 'drive_modes.py'))

#: File beside numba's cache entries holding the digest of KERNEL_SOURCES they came from.
DIGEST_FILE = 'leadscrew_sim_kernel.sha256'


def kernel_jit(fn):
    """Compile ``fn`` with :data:`JIT_OPTIONS` and register it for :func:`refresh_cache`."""
    dispatcher = njit(**JIT_OPTIONS)(fn)
    DISPATCHERS.append(dispatcher)
    return dispatcher


def sources_digest():
    """Return the SHA-256 of the kernel's source files, in :data:`KERNEL_SOURCES` order."""
    here = os.path.dirname(os.path.abspath(__file__))
    h = hashlib.sha256()
    for name in KERNEL_SOURCES:
        with open(os.path.join(here, name), 'rb') as fh:
            h.update(fh.read())
    return h.hexdigest()


def refresh_cache():
    """
    Drop numba's cached kernel code if it was compiled from other sources than these.

    numba keys each cache entry on the source file of its own function only, so
    a change of a constant in layout.py (frozen into the code of friction.py,
    kernel.py, ...) or of the options here would otherwise go on running stale
    code. The digest of all kernel sources is kept beside the cache entries;
    when it differs, every entry is flushed before the first call compiles.
    Called once, by kernel.py, after all kernel functions are defined.
    """
    digest = sources_digest()
    by_dir = {}
    for d in DISPATCHERS:
        cache = getattr(d, '_cache', None)
        path = getattr(cache, 'cache_path', None)
        if path:
            by_dir.setdefault(path, []).append(cache)
    for path, caches in by_dir.items():
        stamp = os.path.join(path, DIGEST_FILE)
        try:
            with open(stamp) as fh:
                if fh.read().strip() == digest:
                    continue
        except OSError:
            pass
        for cache in caches:
            cache.flush()
        try:
            os.makedirs(path, exist_ok=True)
            with open(stamp, 'w') as fh:
                fh.write(digest + '\n')
        except OSError:
            pass                     # a read-only cache: numba then compiles in memory
