"""
The one set of numba compile options shared by every kernel function.

friction, lcp and kernel decorate all their compiled functions with
``kernel_jit``, so caller and callee are always compiled with the same flags.
"""
try:  # numba is the accelerator (see README, "Why numba"); plain Python also works.
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
# reference counting of their array arguments is skipped.
JIT_OPTIONS = dict(cache=True, error_model='numpy', fastmath=False, _nrt=False)

kernel_jit = njit(**JIT_OPTIONS)
