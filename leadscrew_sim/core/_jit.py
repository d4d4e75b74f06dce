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

# fastmath: LLVM may fuse a * b + c into one FMA instruction, and nothing else (no
# reassociation; NaN and Inf semantics kept). It shortens the substep's dependency
# chain (bench/README.md); results are bit-identical from run to run on a machine.
CONTRACT = {'contract'}

# cache: compiled code is kept on disk (NUMBA_CACHE_DIR). error_model 'numpy': a
# division by zero gives inf/nan instead of raising. _nrt=False: the functions
# allocate nothing, so they are compiled without the numba runtime and the
# reference counting of their array arguments is skipped.
JIT_OPTIONS = dict(cache=True, error_model='numpy', fastmath=CONTRACT, _nrt=False)

kernel_jit = njit(**JIT_OPTIONS)
