"""Numba kernels of the milling force model (see :mod:`cnctwin.mechanics.milling`).

Arrays in SI units. ``k`` is ``[Ktc, Krc, Kac, Kte, Kre, Kae]`` (Pa, Pa, Pa, N/m, N/m, N/m).
The elemental forces and their projection on the tool frame follow Lee & Altintas (1996) and
Altintas (2012, ch. 2); Royandi 2026 Eq. 8-11 is the cylindrical case (kappa = pi/2).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_TWO_PI = 2.0 * math.pi


@njit(cache=True)
def waveform(
    steps: int,
    radius: np.ndarray,
    kappa: np.ndarray,
    width: np.ndarray,
    lag: np.ndarray,
    offsets: np.ndarray,
    entry: np.ndarray,
    exit_: np.ndarray,
    pitch: float,
    tooth_dr: np.ndarray,
    feed: float,
    k: np.ndarray,
    edge_scale: float,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Add the forces at ``steps`` uniform spindle angles to ``out`` (rows Fx, Fy, Fz, torque).

    Tooth j of slice s sits at ``phi = theta + j pitch - lag[s]``. Its chip thickness is
    ``h = sin(kappa) min_m (m feed sin(phi) + dr_j - dr_(j+m))`` over the m-th previous
    teeth (runout, Kline & DeVor 1983), and it cuts where h > 0 inside a contact interval
    (intervals of a slice must not overlap). Only the spindle angles whose phi falls inside
    an interval clipped to 0..pi are visited.
    """
    teeth = tooth_dr.size
    runout = False
    for j in range(teeth):
        if tooth_dr[j] != 0.0:
            runout = True
    step = _TWO_PI / steps
    theta = np.arange(steps) * step
    sin_t = np.sin(theta)
    cos_t = np.cos(theta)
    ktc, krc, kac = k[0], k[1], k[2]
    kte, kre, kae = k[3] * edge_scale, k[4] * edge_scale, k[5] * edge_scale
    for s in range(radius.size):
        sk = math.sin(kappa[s])
        ck = math.cos(kappa[s])
        b = width[s]
        r = radius[s]
        for j in range(teeth):
            shift = j * pitch - lag[s]
            cs = math.cos(shift)
            ss = math.sin(shift)
            for q in range(offsets[s], offsets[s + 1]):
                lo = max(entry[q], 0.0)
                hi = min(exit_[q], math.pi)
                if hi <= lo:
                    continue
                first = math.ceil((lo - shift) / step)
                last = math.floor((hi - shift) / step) + 1
                base = (first // steps) * steps
                first -= base
                last -= base
                # The visited angles, unwrapped: first .. last - 1, then 0 .. last - steps - 1.
                _accumulate(
                    first,
                    min(last, steps),
                    sin_t,
                    cos_t,
                    cs,
                    ss,
                    runout,
                    j,
                    tooth_dr,
                    feed,
                    sk,
                    ck,
                    b,
                    r,
                    ktc,
                    krc,
                    kac,
                    kte,
                    kre,
                    kae,
                    out,
                )
                if last > steps:
                    _accumulate(
                        0,
                        last - steps,
                        sin_t,
                        cos_t,
                        cs,
                        ss,
                        runout,
                        j,
                        tooth_dr,
                        feed,
                        sk,
                        ck,
                        b,
                        r,
                        ktc,
                        krc,
                        kac,
                        kte,
                        kre,
                        kae,
                        out,
                    )


@njit(cache=True, fastmath=True)
def _accumulate(
    first: int,
    stop: int,
    sin_t: np.ndarray,
    cos_t: np.ndarray,
    cs: float,
    ss: float,
    runout: bool,
    j: int,
    tooth_dr: np.ndarray,
    feed: float,
    sk: float,
    ck: float,
    b: float,
    r: float,
    ktc: float,
    krc: float,
    kac: float,
    kte: float,
    kre: float,
    kae: float,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Add the forces of one tooth of one slice at angle indices ``first .. stop - 1``."""
    teeth = tooth_dr.size
    tiny = 1e-12 * feed
    for i in range(first, stop):
        sp = sin_t[i] * cs + cos_t[i] * ss
        cp = cos_t[i] * cs - sin_t[i] * ss
        if runout:
            h = teeth * feed * sp
            for m in range(1, teeth):
                h = min(h, m * feed * sp + tooth_dr[j] - tooth_dr[(j + m) % teeth])
        else:
            h = feed * sp
        h *= sk
        # Cut where h > 0; the tolerance keeps phi = pi (sin = 1e-16) out as phi = 0 is.
        edge = 1.0 if h > tiny else 0.0  # branch-free, so that the loop can vectorize
        h = max(h, 0.0) * edge
        dft = (ktc * h + kte * edge) * b
        dfr = (krc * h + kre * edge) * b
        dfa = (kac * h + kae * edge) * b
        rad = dfr * sk + dfa * ck
        out[0, i] += -dft * cp - rad * sp
        out[1, i] += dft * sp - rad * cp
        out[2, i] += dfr * ck - dfa * sk
        out[3, i] += dft * r


@njit(cache=True)
def mean(
    radius: np.ndarray,
    kappa: np.ndarray,
    width: np.ndarray,
    offsets: np.ndarray,
    entry: np.ndarray,
    exit_: np.ndarray,
    teeth: int,
    feed: float,
    k: np.ndarray,
    edge_scale: float,
) -> tuple[float, float, float, float]:  # pragma: no cover - compiled
    """Per-revolution mean (Fx, Fy, Fz, torque) by exact integration over phi, slice by slice.

    Over a revolution every tooth of a slice sweeps each contact interval once, whatever its
    helix lag, so the mean is ``N / (2 pi)`` times the integral of the elemental forces over
    the intervals (clipped to 0..pi), which has a closed form (Altintas 2012, ch. 2).
    """
    ktc, krc, kac = k[0], k[1], k[2]
    kte, kre, kae = k[3] * edge_scale, k[4] * edge_scale, k[5] * edge_scale
    fx = 0.0
    fy = 0.0
    fz = 0.0
    tq = 0.0
    for s in range(radius.size):
        sk = math.sin(kappa[s])
        ck = math.cos(kappa[s])
        c = feed * sk * width[s]
        e = width[s]
        for q in range(offsets[s], offsets[s + 1]):
            a = max(entry[q], 0.0)
            bb = min(exit_[q], math.pi)
            if bb <= a:
                continue
            s1 = math.cos(a) - math.cos(bb)
            c1 = math.sin(bb) - math.sin(a)
            s2 = 0.5 * (bb - a) - 0.25 * (math.sin(2.0 * bb) - math.sin(2.0 * a))
            sc = 0.5 * (math.sin(bb) ** 2 - math.sin(a) ** 2)
            span = bb - a
            t_cos = ktc * c * sc + kte * e * c1
            t_sin = ktc * c * s2 + kte * e * s1
            r_sin = krc * c * s2 + kre * e * s1
            r_cos = krc * c * sc + kre * e * c1
            a_sin = kac * c * s2 + kae * e * s1
            a_cos = kac * c * sc + kae * e * c1
            fx += -t_cos - sk * r_sin - ck * a_sin
            fy += t_sin - sk * r_cos - ck * a_cos
            fz += ck * (krc * c * s1 + kre * e * span) - sk * (kac * c * s1 + kae * e * span)
            tq += radius[s] * (ktc * c * s1 + kte * e * span)
    scale = teeth / _TWO_PI
    return fx * scale, fy * scale, fz * scale, tq * scale
