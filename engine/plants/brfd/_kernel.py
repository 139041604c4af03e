"""Numba kernel of the BRFD plant: a Dahl-type friction element behind a play, driven by displacement.

The displacement x is imposed (the hydraulic actuator); the kernel returns the force the element
transmits. Per sample k (interval dt):

- the relative displacement ``s`` across the linkage grows by ``dx = x[k] - x[k-1]``; the play
  of width ``b`` is the dead zone ``|s| <= b / 2``: inside it nothing is transmitted;
- in contact on side ``sign(s)``, the elastic deflection ``e`` (``F_el = sigma0 e``) follows Dahl's
  law ``de/dx = 1 - sigma0 e sign(dx) / g(v)``, integrated exactly over the sample for constant
  g (an exponential approach to ``sign(dx) g / sigma0``); a deflection pushed below zero by the
  unloading leaves contact (``e = 0`` and the gap opens);
- ``g(v) = (Fc (1 + asym sign(v)) + Fs exp(-(v / v_s)^2)) max(1 - phi s, 0.1) max(1 + e x / x_t, 0.1)``
  (Coulomb level, its asymmetry and a Stribeck term, faded along the travel ``s = sum |dx|`` since
  the record's start by the held-back ``friction_fade`` phi [1/m], and varying along the stroke by
  the sealed ``tapered_drum`` e [-] over the scale x_t; both neutral at 0); v is the actuator's
  velocity (central difference of x);
- the transmitted force ``F = (sigma0 e + sigma2 v) (1 + kappa w + kappa2 w^2) (1 + a exp(-w / w_a))``
  in contact, 0 in the gap (kappa2: the sealed ``band_quadratic_wrap``, neutral 0); ``w = |x - x_rev|`` is the wind-up since the last reversal of x (a
  reversal: x retreats more than ``rev_tol`` from its running extreme): the band brake's
  self-energizing amplification kappa, and the held-back ``band_relaxation`` a (neutral 0) over the
  wind-up scale w_a.

Exact per-sample integration makes the kernel unconditionally stable for any sigma0 (no sub-steps).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# parameter vector layout
P_SIGMA0 = 0
P_FC = 1
P_SIGMA2 = 2
P_FS = 3
P_VS = 4
P_ASYM = 5
P_PLAY = 6
P_KAPPA = 7
P_REV_TOL = 8
P_FADE = 9
P_RELAX = 10
P_W_RELAX = 11
P_TAPER = 12
P_X_TAPER = 13
P_KAPPA2 = 14
N_PARAMS = 15


@njit(cache=True, nogil=True)
def transmitted_force(x: np.ndarray, dt: float, p: np.ndarray, out: np.ndarray, contact: np.ndarray) -> int:
    """Fill ``out`` [N] and ``contact`` (1 in contact, 0 in the play) for displacement ``x`` [m]; 0 on success.

    Returns 1 for a non-finite force (a parameter outside what the model can hold).
    """
    n = x.shape[0]
    sigma0 = p[P_SIGMA0]
    fc = p[P_FC]
    sigma2 = p[P_SIGMA2]
    fs = p[P_FS]
    vs = p[P_VS]
    asym = p[P_ASYM]
    h = 0.5 * p[P_PLAY]
    kappa = p[P_KAPPA]
    rev_tol = p[P_REV_TOL]
    fade = p[P_FADE]
    relax = p[P_RELAX]
    w_relax = p[P_W_RELAX]
    taper = p[P_TAPER]
    x_taper = p[P_X_TAPER]
    kappa2 = p[P_KAPPA2]
    travel = 0.0  # travel of the actuator since the start [m]
    s = 0.0  # relative displacement across linkage and play [m]
    e = 0.0  # elastic deflection of the friction element [m]
    x_rev = x[0]
    x_ext = x[0]
    x_hi = x[0]
    x_lo = x[0]
    direction = 0.0
    for k in range(n):
        if k == 0:
            v = (x[1] - x[0]) / dt if n > 1 else 0.0
        elif k == n - 1:
            v = (x[k] - x[k - 1]) / dt
        else:
            v = (x[k + 1] - x[k - 1]) / (2.0 * dt)
        dx = x[k] - x[k - 1] if k > 0 else 0.0
        travel += abs(dx)
        # reversal tracking for the wind-up (see :func:`reversals`)
        if direction == 0.0:
            if x[k] > x_hi:
                x_hi = x[k]
            if x[k] < x_lo:
                x_lo = x[k]
            if x[k] - x_lo > rev_tol:
                direction, x_rev, x_ext = 1.0, x_lo, x[k]
            elif x_hi - x[k] > rev_tol:
                direction, x_rev, x_ext = -1.0, x_hi, x[k]
        elif direction > 0.0:
            if x[k] > x_ext:
                x_ext = x[k]
            elif x_ext - x[k] > rev_tol:
                direction, x_rev, x_ext = -1.0, x_ext, x[k]
        else:
            if x[k] < x_ext:
                x_ext = x[k]
            elif x[k] - x_ext > rev_tol:
                direction, x_rev, x_ext = 1.0, x_ext, x[k]
        sv = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
        g = fc * (1.0 + asym * sv) + fs * math.exp(-((v / vs) ** 2))
        if fade != 0.0:
            g *= max(1.0 - fade * travel, 0.1)
        if taper != 0.0:
            g *= max(1.0 + taper * x[k] / x_taper, 0.1)
        if g < 1e-9 * fc:
            g = 1e-9 * fc
        if h == 0.0:  # no play: Dahl's law on the deflection, always in contact
            if dx != 0.0:
                e_ss = (g / sigma0) * (1.0 if dx > 0.0 else -1.0)
                e = e_ss + (e - e_ss) * math.exp(-sigma0 * abs(dx) / g)
            f = (sigma0 * e + sigma2 * v) * (1.0 + kappa * abs(x[k] - x_rev))
            if kappa2 != 0.0:
                f *= 1.0 + kappa2 * (x[k] - x_rev) ** 2 / (1.0 + kappa * abs(x[k] - x_rev))
            if relax != 0.0:
                f *= 1.0 + relax * math.exp(-abs(x[k] - x_rev) / w_relax)
            if not math.isfinite(f):
                return 1
            out[k] = f
            contact[k] = 1
            continue
        s_t = s + dx
        if abs(s_t) <= h:
            s = s_t
            e = 0.0
            out[k] = 0.0
            contact[k] = 0
            continue
        side = 1.0 if s_t > 0.0 else -1.0
        e_prev = e if e * side > 0.0 else 0.0
        # contact displacement on this side since the last sample: beyond the gap edge, minus what was there
        delta = side * (abs(s_t) - h) - e_prev
        if delta != 0.0:
            e_ss = (g / sigma0) * (1.0 if delta > 0.0 else -1.0)
            e = e_ss + (e_prev - e_ss) * math.exp(-sigma0 * abs(delta) / g)
        else:
            e = e_prev
        if e * side <= 0.0:  # unloaded through zero: the play opens
            e = 0.0
            s = side * h
            out[k] = 0.0
            contact[k] = 0
            continue
        s = side * h + e
        w = abs(x[k] - x_rev)
        f = (sigma0 * e + sigma2 * v) * (1.0 + kappa * w)
        if kappa2 != 0.0:
            f *= 1.0 + kappa2 * w * w / (1.0 + kappa * w)
        if relax != 0.0:
            f *= 1.0 + relax * math.exp(-w / w_relax)
        if not math.isfinite(f):
            return 1
        out[k] = f
        contact[k] = 1
    return 0


@njit(cache=True, nogil=True)
def reversals(x: np.ndarray, rev_tol: float) -> np.ndarray:
    """Indices of the reversals of ``x``: the running extremes from which x then retreats by more than ``rev_tol``."""
    out = np.empty(x.shape[0], dtype=np.int64)
    m = 0
    direction = 0.0
    i_hi = i_lo = i_ext = 0
    for k in range(x.shape[0]):
        if direction == 0.0:
            if x[k] > x[i_hi]:
                i_hi = k
            if x[k] < x[i_lo]:
                i_lo = k
            if x[k] - x[i_lo] > rev_tol:
                direction, i_ext = 1.0, k
            elif x[i_hi] - x[k] > rev_tol:
                direction, i_ext = -1.0, k
        elif direction > 0.0:
            if x[k] > x[i_ext]:
                i_ext = k
            elif x[i_ext] - x[k] > rev_tol:
                out[m] = i_ext
                m += 1
                direction, i_ext = -1.0, k
        else:
            if x[k] < x[i_ext]:
                i_ext = k
            elif x[k] - x[i_ext] > rev_tol:
                out[m] = i_ext
                m += 1
                direction, i_ext = 1.0, k
    return out[:m]
