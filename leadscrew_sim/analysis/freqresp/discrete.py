"""The zero-order-hold discretisation shared by the linear and the lifted responses."""
import numpy as np
from scipy.linalg import expm

__all__ = ['zoh']


def zoh(a, b, t):
    """Return (Phi, Gamma) = (e^(A t), integral_0^t e^(A s) ds B) for a held input (B: (n, m))."""
    n, m = b.shape
    big = np.zeros((n + m, n + m))
    big[:n, :n] = a * t
    big[:n, n:] = b * t
    e = expm(big)
    return e[:n, :n], e[:n, n:]
