"""
The axis's sensors (doc/model.md section 17): motor encoder, linear scale and their noise.

The kernel samples both sensors at the end of every drive period (every
``m`` substeps, :func:`.drive.update_period`), in the drive's loop and in
torque mode alike; the drive's next update reads that sample. A step
reports the readings at its end: the drive's sample when a drive period
ends with the step (the drive rate a whole multiple of the update rate),
else :func:`readings` of the state at the step's end; the velocities are
always the drive's last estimates.

A reading is the true value plus the bias plus seeded Gaussian noise,
quantised to whole counts: ``floor((q + bias + noise) N / 2 pi) 2 pi / N``
for the encoder (N counts per revolution), ``floor((x + bias + noise) / r) r``
for the scale (resolution r). The noise comes before the quantisation, as on
hardware, so a reading is always a whole number of counts. A velocity is the
difference quotient of two readings over the drive period, through an
optional first-order filter. A frozen sensor holds its reading and reports
zero velocity.

A sensor without counts (or resolution), noise and bias is ideal: it reads
the true position and rate, so a run with the default sensors gives the
values the model has always reported.

Noise is counter based: sample n of a run draws the standard normal pair
:func:`normal_pair` ``(seed, n)``, a hash of the seed and the counter
(Box-Muller of two 32-bit uniforms). The kernel keeps the counter in its
state, so one call per step and one call per run give the same sequence,
and the same seed gives the same run. :func:`uniform` gives the seeded
decisions of the dropped messages (:mod:`.delivery`) from the same hash.
"""
import math

from ._jit import kernel_jit
from . import layout as L

#: Streams of :func:`uniform`: the sensor noise of the drive's samples, dropped state
#: messages, dropped commands, the noise of the readings a step reports between samples.
STREAM_NOISE, STREAM_STATE_DROP, STREAM_COMMAND_DROP, STREAM_REPORT = 1, 2, 3, 4

_M32 = 0xFFFFFFFF
_TWO_PI = 2.0 * math.pi


@kernel_jit
def _mix32(x):
    """
    Return a 32-bit avalanche hash of x (0 <= x < 2^32), an integer in [0, 2^32).

    The multipliers are below 2^31, so every product fits in a signed 64-bit
    integer and compiled and plain Python code give the same bits.
    """
    x ^= x >> 16
    x = (x * 0x21F0AAAD) & _M32
    x ^= x >> 15
    x = (x * 0x735A2D97) & _M32
    x ^= x >> 15
    return x


@kernel_jit
def _key(seed, stream):
    """Return the 32-bit key of one stream of a seed (0 <= seed < 2^31, small stream)."""
    return _mix32((_mix32(seed & _M32) + 0x9E3779B9 * stream) & _M32)


@kernel_jit
def _word(key, index):
    """Return the 32-bit word of counter ``index`` (0 <= index < 2^53) under ``key``."""
    return _mix32(_mix32((index & _M32) ^ key) ^ ((index >> 32) & _M32))


@kernel_jit
def uniform(seed, stream, index):
    """
    Return the uniform deviate in (0, 1) of counter ``index`` of a stream of a seed.

    Parameters
    ----------
    seed : int
        The seed, 0 <= seed < 2^31.
    stream : int
        The stream (``STREAM_*``).
    index : int
        The counter, 0 <= index < 2^53.

    """
    return (_word(_key(seed, stream), index) + 0.5) * (1.0 / 4294967296.0)


@kernel_jit
def normal_pair(seed, stream, index):
    """
    Return the two independent standard normal deviates of sensor sample ``index``.

    Box-Muller of the uniforms of counters 2 index and 2 index + 1 of a
    stream; the first goes to the encoder, the second to the scale.

    Parameters
    ----------
    seed : int
        The seed, 0 <= seed < 2^31.
    stream : int
        ``STREAM_NOISE`` (the drive's samples) or ``STREAM_REPORT``.
    index : int
        The sample counter, 0 <= index < 2^52.

    """
    key = _key(seed, stream)
    u1 = (_word(key, 2 * index) + 0.5) * (1.0 / 4294967296.0)
    u2 = (_word(key, 2 * index + 1) + 0.5) * (1.0 / 4294967296.0)
    r = math.sqrt(-2.0 * math.log(u1))
    return r * math.cos(_TWO_PI * u2), r * math.sin(_TWO_PI * u2)


@kernel_jit
def _encoder(P, q, z):
    """Return the encoder reading of the true motor angle q [rad] with noise deviate z."""
    r = q + P[L.P_EBIAS] + P[L.P_ENOISE] * z
    cpr = P[L.P_ECPR]
    if cpr > 0.0:
        r = math.floor(r * (cpr / _TWO_PI)) * (_TWO_PI / cpr)
    return r


@kernel_jit
def _scale(P, x, z):
    """Return the linear scale reading of the true nut position x [m] with noise deviate z."""
    r = x + P[L.P_SBIAS] + P[L.P_SNOISE] * z
    res = P[L.P_SRES]
    if res > 0.0:
        r = math.floor(r / res) * res
    return r


@kernel_jit
def readings(P, S, qm, xa):
    """
    Return the (encoder [rad], scale [m]) readings of the state now, between two samples.

    What a step reports when it does not end on a drive sample: the readings
    at its end, with noise of the report stream (``STREAM_REPORT``, counted by
    S_NREP), so the drive's own samples are not disturbed. A frozen sensor
    gives its held reading, an ideal one the truth.
    """
    z_enc = 0.0
    z_sc = 0.0
    n = int(S[L.S_NREP])
    S[L.S_NREP] = n + 1
    if P[L.P_ENOISE] > 0.0 or P[L.P_SNOISE] > 0.0:
        z_enc, z_sc = normal_pair(int(P[L.P_SEED]), STREAM_REPORT, n)
    if P[L.P_EFRZ] > 0.5:
        q = S[L.S_EQ]
    elif P[L.P_EIDEAL] > 0.5:
        q = qm
    else:
        q = _encoder(P, qm, z_enc)
    if P[L.P_SFRZ] > 0.5:
        x = S[L.S_XS]
    elif P[L.P_SIDEAL] > 0.5:
        x = xa
    else:
        x = _scale(P, xa, z_sc)
    return q, x


@kernel_jit
def _take(S, i_read, i_vel, reading, td, beta, first):
    """Store a reading in S[i_read] and its filtered difference quotient in S[i_vel]."""
    if first:
        S[i_vel] = 0.0
    else:
        S[i_vel] += beta * ((reading - S[i_read]) / td - S[i_vel])
    S[i_read] = reading


@kernel_jit
def sample(P, S, qm, wm, xa, va, td, beta, first):
    """
    Take one sample of both sensors into S (S_EQ .. S_VS) and count it (S_NSAMP).

    qm, wm: true motor angle [rad] and rate [rad/s] (q sense); xa, va: true
    position [m] and velocity [m/s] of nut A; td: drive period [s], the base
    of the difference quotients; beta: the velocity filter's gain per sample
    (1: no filter); first: the sample at reset (velocities start at 0).
    """
    n = int(S[L.S_NSAMP])
    S[L.S_NSAMP] = n + 1
    z_enc = 0.0
    z_sc = 0.0
    if P[L.P_ENOISE] > 0.0 or P[L.P_SNOISE] > 0.0:
        z_enc, z_sc = normal_pair(int(P[L.P_SEED]), STREAM_NOISE, n)
    # motor encoder
    if P[L.P_EFRZ] > 0.5 and not first:
        S[L.S_EW] = 0.0
    elif P[L.P_EIDEAL] > 0.5:
        S[L.S_EQ] = qm
        S[L.S_EW] = wm
    else:
        _take(S, L.S_EQ, L.S_EW, _encoder(P, qm, z_enc), td, beta, first)
    # linear scale
    if P[L.P_SFRZ] > 0.5 and not first:
        S[L.S_VS] = 0.0
    elif P[L.P_SIDEAL] > 0.5:
        S[L.S_XS] = xa
        S[L.S_VS] = va
    else:
        _take(S, L.S_XS, L.S_VS, _scale(P, xa, z_sc), td, beta, first)


def pack_sensors(p, v):
    """
    Fill the sensor and kernel fault slots of the parameter vector v from ScrewParams p.

    Parameters
    ----------
    p : ScrewParams
        The parameters.
    v : numpy.ndarray
        The parameter vector (layout.NP floats).

    """
    hs = p.hand_sign
    v[L.P_ECPR] = p.encoder_counts
    v[L.P_ENOISE] = p.encoder_noise
    v[L.P_EBIAS] = hs * p.encoder_bias
    v[L.P_EIDEAL] = 1.0 if (p.encoder_counts == 0 and p.encoder_noise == 0.0
                            and p.encoder_bias == 0.0) else 0.0
    v[L.P_SFIT] = 1.0 if p.linear_scale else 0.0
    v[L.P_SRES] = p.scale_resolution
    v[L.P_SNOISE] = p.scale_noise
    v[L.P_SBIAS] = p.scale_bias
    v[L.P_SIDEAL] = 1.0 if (p.scale_resolution == 0.0 and p.scale_noise == 0.0
                            and p.scale_bias == 0.0) else 0.0
    v[L.P_VFT] = p.velocity_filter_time
    v[L.P_SEED] = p.sensor_seed
    v[L.P_EFRZ] = 1.0 if p.fault_encoder_freeze else 0.0
    v[L.P_SFRZ] = 1.0 if p.fault_scale_freeze else 0.0
    v[L.P_JAM] = 1.0 if p.fault_jam else 0.0
    v[L.P_JAMX] = p.fault_jam_position
    v[L.P_TSCALE] = p.fault_motor_torque_scale
    v[L.P_FINJ] = 1.0 if p.fault_drive_fault else 0.0
