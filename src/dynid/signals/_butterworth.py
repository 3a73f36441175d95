"""The digital Butterworth low-pass as second-order sections, and its sections' steady states: scipy.signal's
`butter(order, cutoff, fs=fs, output="sos")` and `sosfilt_zi`, written out for this one filter so that no
identification imports scipy.signal (48 MB resident with the scipy.stats it loads: issue 25's memory target).

The design, as scipy's: the analogue prototype's poles -exp(i pi m / 2N), m = -N+1, -N+3, ..., N-1, scaled to the
cut-off pre-warped for the bilinear transform (4 tan(pi Wn / 2), Wn = cutoff / (fs / 2), at scipy's normalised
fs = 2); the bilinear transform z = (4 + s) / (4 - s), which puts the N zeros at -1; the gain wo^N / prod(4 - s)
(unit gain at DC); the poles paired into sections as scipy's `zpk2sos(pairing="nearest")` pairs them (an odd order
gets a pole and a zero at 0; the pole closest to the unit circle goes into the last section, with the zero nearest
to it; the gain goes into the first section), so that the sections, their order and their first-order section
are scipy's, to round-off.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray


def butter_lowpass_sos(order: int, cutoff: float, fs: float) -> NDArray[np.float64]:
    """(ceil(order / 2), 6) sections [b0 b1 b2 1 a1 a2] of the order-`order` digital Butterworth low-pass at
    `cutoff` Hz for `fs` Hz, as `scipy.signal.butter(order, cutoff, fs=fs, output="sos")`. Arguments assumed
    checked: order >= 1, 0 < cutoff < fs / 2."""
    m = np.arange(-order + 1, order, 2, dtype=np.float64)
    analog = -np.exp(1j * np.pi * m / (2 * order))  # the prototype's poles, the middle one exactly -1 (odd order)
    wo = 4.0 * math.tan(math.pi * (cutoff / (fs / 2.0)) / 2.0)  # pre-warped at scipy's normalised fs = 2
    s = wo * analog
    poles = (4.0 + s) / (4.0 - s)
    gain = wo**order * float(np.real(1.0 / np.prod(4.0 - s)))
    zeros = [-1.0] * order
    # one of each conjugate pair (their exp are exact conjugates: sin is odd, cos even) and the real poles
    pairs = [complex(p) for p in poles[m > 0]]
    real = [float(p.real) for p in poles[m == 0]]
    if order % 2:  # scipy's "nearest" pairing: an odd order gets a pole and a zero at the origin
        real.append(0.0)
        zeros.append(0.0)
    sos = np.zeros(((order + 1) // 2, 6))
    for si in range(sos.shape[0] - 1, -1, -1):  # the pole closest to the unit circle last
        p1 = min(pairs + real, key=lambda p: abs(1.0 - abs(p)))
        if isinstance(p1, complex):
            pairs.remove(p1)
            a1, a2 = -2.0 * p1.real, p1.real * p1.real + p1.imag * p1.imag
        else:
            real.remove(p1)
            p2 = min(real, key=lambda p: abs(1.0 - abs(p)))  # never empty: real poles come in twos here
            real.remove(p2)
            a1, a2 = -p1 - p2, p1 * p2
        # the two zeros nearest to the section's pole (the zeros are real: -1, and 0 for an odd order)
        z1 = min(zeros, key=lambda z: abs(z - p1))
        zeros.remove(z1)
        z2 = min(zeros, key=lambda z: abs(z - p1))
        zeros.remove(z2)
        sos[si] = (1.0, -z1 - z2, z1 * z2, 1.0, a1, a2)
    sos[0, :3] *= gain
    return sos


def sosfilt_zi(sos: NDArray[np.float64]) -> NDArray[np.float64]:
    """(sections, 2) initial states of the direct form II transposed for a unit step's steady state, each
    section's scaled by the DC gain of the sections before it: `scipy.signal.sosfilt_zi(sos)`. A section's state
    solves (I - A) z = b[1:] - a[1:] b0 (A its companion matrix transposed), by LAPACK as scipy's `lfilter_zi`
    does: the same operations, so the same bits (a closed form differs by ulps times the system's condition,
    ~1e3 at a low cut-off, which nonlinear fits downstream, the tyre curves', amplify to 1e-7)."""
    sos = np.asarray(sos, dtype=np.float64)
    zi = np.empty((sos.shape[0], 2))
    scale = 1.0
    for k in range(sos.shape[0]):
        b, a = sos[k, :3], sos[k, 3:]
        if a[0] != 1.0:
            b, a = b / a[0], a / a[0]
        system = np.eye(2) - np.array([[-a[1], -a[2]], [1.0, 0.0]]).T  # I - companion(a).T
        zi[k] = scale * np.linalg.solve(system, b[1:] - a[1:] * b[0])
        scale *= np.sum(sos[k, :3]) / np.sum(sos[k, 3:])
    return zi
