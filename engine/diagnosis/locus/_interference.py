"""A periodic interference of the measurement chain (step 5 of the method, with the sensor library).

Channels that read, besides their signal, a sinusoid of one fixed frequency: the mains' hum of a
ground loop, a switching converter's ripple picked up by a cable. One
source, one frequency f [Hz]; each channel it reaches with its own amplitude and phase. Once f is
fixed the term is linear (a sine and a cosine column per channel), so f is searched and the
channels are selected sparsely, as the cross-talk is (:func:`~engine.diagnosis.locus._linear.sparse_extension`):

1. f is searched over ``[min_periods / T, 0.45 / Ts]`` (T the window's duration, Ts the sample
   interval): the summed periodogram of the sensor library's residual (zero-padded eightfold),
   its highest peaks refined. A slower sinusoid is a drift of a few periods, which the loci's
   inputs and the calibration hold as well.
2. A source in the measurement chain keeps its amplitude and phase over the window; a transient of
   the plant that rings or drifts near f does not. So a channel is *eligible* at f only when
   giving each of ``n_segments`` stretches of the window its own sine and cosine drops its
   residual by little more than noise would (:func:`segment_gain`). The peak kept is the one whose
   eligible channels drop the residual most.
3. An eligible channel's pair of columns is taken while its drop in the residual exceeds
   ``2 ln n + 2 ln n_ch`` (two coefficients, and the choice among the channels); the first pair
   pays for f too, ``ln n + 2 ln F`` with F the independent frequencies in the band (the
   risk-inflation price of choosing the best of F), so noise alone, whose best frequency drops the
   residual by about ``2 ln F``, takes none.

Measured on development records (``lab/validation/dev-locus-spent/interference.md``): a mains hum
on a1 and a2 keeps 0.1-1.1 % of its drop in the stretches' gain; the transients of mechanical
terms near their best frequency 43-1800 %.

A mechanical term at a fixed frequency acts through the plant: its response in each channel
changes with the clutch's state (open, closed, impacts), which one amplitude and phase per channel
cannot follow; step 2 leaves such a term to the loci's inputs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2 as chi2_dist

from engine.diagnosis.locus._linear import linear_fit, orth, project

#: Zero-padding factor of the frequency search's periodogram.
PAD: int = 8
#: Highest frequency searched, as a share of the sample rate (below the Nyquist frequency's 0.5).
NYQUIST_SHARE: float = 0.45
#: Points of the refinement around a periodogram's peak (within one padded bin on each side).
N_REFINE: int = 41
#: Peaks of the periodogram tried (the highest first).
N_PEAKS: int = 5
#: Relative tolerance of :func:`is_motion` (magnitude and phase of the ratio together).
MOTION_TOLERANCE: float = 0.3
#: Quantile of the segments' gain in white noise below which a component counts as stationary.
STATIONARY_LEVEL: float = 0.999


@dataclass(frozen=True)
class Interference:
    """The interference the residual asks for.

    Attributes
    ----------
    frequency_hz : float
        Its frequency [Hz].
    channels : tuple of int
        The channels that read it (indices into the record's channels), in the order taken.
    coef : ndarray, shape (m, 2)
        Each such channel's sine and cosine coefficients, whitened (times the channel's sigma: its
        unit); the time origin is the window's first sample.
    rss : float
        Whitened residual sum of squares of the extended fit [chi2 units].
    penalty : float
        What the term adds to the sensor library's BIC beyond ``rss`` [chi2 units].
    design_coef : ndarray
        Coefficients of the base design's columns in the extended fit.
    """

    frequency_hz: float
    channels: tuple[int, ...]
    coef: np.ndarray
    rss: float
    penalty: float
    design_coef: np.ndarray


def _pair(t: np.ndarray, f: float) -> np.ndarray:
    w = 2.0 * math.pi * f * t
    return np.stack([np.sin(w), np.cos(w)], axis=1)


def _pair_drops(e: np.ndarray, pair: np.ndarray) -> np.ndarray:
    """Drop of each channel's residual (rows of ``e``) when its sine and cosine are fitted."""
    G = pair.T @ pair
    b = e @ pair  # (n_ch, 2)
    return np.einsum("ij,ij->i", b, np.linalg.solve(G, b.T).T)


def segment_gain(e: np.ndarray, t: np.ndarray, f: float, n_segments: int) -> tuple[np.ndarray, np.ndarray]:
    """Each channel's drop at ``f``, and what giving each stretch of the window its own pair adds.

    Parameters
    ----------
    e : ndarray, shape (n_ch, n_samples)
        Whitened residual, a row per channel.
    t : ndarray, shape (n_samples,)
        Sample instants [s].
    f : float
        Frequency [Hz].
    n_segments : int
        Equal stretches of the window.

    Returns
    -------
    whole : ndarray, shape (n_ch,)
        Drop of each channel's residual when one sine and cosine at ``f`` are fitted to the whole
        window [chi2 units].
    gain : ndarray, shape (n_ch,)
        The further drop when each stretch gets its own pair [chi2 units]: chi2 with
        ``2 (n_segments - 1)`` degrees of freedom for a source of constant amplitude and phase in
        white noise; a large share of ``whole`` for a transient that rings or drifts near ``f``.
    """
    pair = _pair(t, f)
    whole = _pair_drops(e, pair)
    seg = np.zeros_like(whole)
    for idx in np.array_split(np.arange(t.size), n_segments):
        seg += _pair_drops(e[:, idx], pair[idx])
    return whole, np.clip(seg - whole, 0.0, None)


def is_motion(x_derivative: complex, x_channel: complex, f: float, scale: float) -> bool:
    """Whether two phasors at ``f`` [Hz] are a signal and its time derivative times ``scale``.

    ``x_derivative = j 2 pi f scale x_channel`` within :data:`MOTION_TOLERANCE` (relative, in
    magnitude and phase together): what a motion of the plant at ``f`` puts in, e.g., a2 and v2,
    and an interference picked up by two cables does not.
    """
    expected = 2j * math.pi * f * scale * x_channel
    return bool(abs(expected) > 0 and abs(x_derivative / expected - 1.0) <= MOTION_TOLERANCE)


def _peaks(score: np.ndarray, n: int, spacing: int) -> list[int]:
    """Indices of the ``n`` highest local maxima of ``score``, at least ``spacing`` apart."""
    order = np.argsort(score)[::-1]
    out: list[int] = []
    for i in order:
        if len(out) == n:
            break
        if all(abs(int(i) - j) >= spacing for j in out):
            out.append(int(i))
    return out


def periodic_extension(
    design: np.ndarray,
    r: np.ndarray,
    t: np.ndarray,
    n_ch: int,
    k: int,
    Q: np.ndarray,
    min_periods: float,
    n_segments: int = 4,
    max_share: float = 0.1,
    motions: Sequence[tuple[int, int, float]] = (),
) -> Interference | None:
    """The sensor library's fit extended by a periodic interference, if the residual asks for one.

    Parameters
    ----------
    design : ndarray, shape (n, m)
        The sensor library's columns as fitted (whitened, the calibrated parameters projected out).
    r : ndarray, shape (n,)
        The whitened residual, channel after channel (``n = n_ch * t.size``), the calibrated
        parameters projected out.
    t : ndarray, shape (n_samples,)
        The window's sample instants [s], evenly spaced.
    n_ch : int
        Channels of the record.
    k : int
        Rank of the calibrated parameters' columns (their BIC price, as in the base fit).
    Q : ndarray, shape (n, k)
        Orthonormal basis of the calibrated parameters' columns (projected out of the new columns).
    min_periods : float
        Fewest periods over the window of a frequency searched [-].
    n_segments : int
        Stretches of the window over which a channel's component must keep its amplitude and
        phase (:func:`segment_gain`).
    max_share : float
        A channel is stationary when giving each stretch its own pair drops its residual by at
        most this share of the whole window's drop, beyond the noise's own (the
        ``STATIONARY_LEVEL`` quantile of its chi2) [-].
    motions : sequence of (int, int, float)
        Channels that are the time derivative of another times a scale: (derivative, channel,
        scale), indices into the record's channels, the scale between their *whitened* values
        (the physical scale times the channel's sigma over the derivative's). When the term
        reaches both with the ratio of a motion (:func:`is_motion`), the plant moves at that
        frequency: no interference.

    Returns
    -------
    Interference or None
        None when no frequency pays for itself, or the window is too short to search.
    """
    n_s = t.size
    n = r.size
    if n_ch < 1 or n_s < 8 or n != n_ch * n_s:
        return None
    ts = float(t[1] - t[0])
    duration = n_s * ts
    f_lo, f_hi = min_periods / duration, NYQUIST_SHARE / ts
    n_freq = (f_hi - f_lo) * duration  # independent frequencies in the band
    if n_freq < 2.0:
        return None
    ln_n = math.log(max(n, 2))
    pair_price = 2.0 * ln_n + 2.0 * math.log(max(n_ch, 2))
    f_price = ln_n + 2.0 * math.log(n_freq)
    _, _, coef0 = linear_fit(design, r, k)
    e = (r - design @ coef0).reshape(n_ch, n_s)
    # 1. the frequency: the summed periodogram (a pair's drop is about 2 |X(f)|^2 / n_s), its
    # highest peaks refined, and the one whose stationary channels drop the residual most
    freqs = np.fft.rfftfreq(PAD * n_s, ts)
    band = (freqs >= f_lo) & (freqs <= f_hi)
    drops = 2.0 * np.abs(np.fft.rfft(e, PAD * n_s, axis=1)[:, band]) ** 2 / n_s
    score = np.clip(drops - pair_price, 0.0, None).sum(axis=0)
    t0 = t - t[0]
    limit = chi2_dist.ppf(STATIONARY_LEVEL, 2 * (n_segments - 1))
    best: tuple[float, float, list[int]] | None = None
    for i in _peaks(score, N_PEAKS, 2 * PAD):
        if score[i] <= f_price:
            break
        f0 = float(freqs[band][i])
        step = 1.0 / (PAD * duration)
        fine = np.linspace(max(f_lo, f0 - step), min(f_hi, f0 + step), N_REFINE)
        f_i = float(
            fine[int(np.argmax([np.clip(_pair_drops(e, _pair(t0, f)) - pair_price, 0.0, None).sum() for f in fine]))]
        )
        whole, gain = segment_gain(e, t0, f_i, n_segments)
        eligible = [j for j in range(n_ch) if whole[j] > pair_price and gain[j] <= max_share * whole[j] + limit]
        total = float(sum(whole[j] - pair_price for j in eligible))
        if total > f_price and (best is None or total > best[0]):
            best = (total, f_i, eligible)
    if best is None:
        return None
    _, f_best, eligible = best
    # 2. the channels, sparsely: each channel's pair, taken while it pays for itself
    pair = _pair(t0, f_best)
    columns: dict[int, np.ndarray] = {}
    for j in eligible:
        col = np.zeros((n, 2))
        col[j * n_s : (j + 1) * n_s] = pair
        columns[j] = project(Q, col)
    chosen: list[int] = []
    current = design
    while len(chosen) < len(eligible):
        B = orth(current, n)
        res = project(B, r[:, None])[:, 0]
        best_j, best_drop = -1, 0.0
        for j in eligible:
            if j in chosen:
                continue
            P = project(B, columns[j])
            G = P.T @ P
            if np.linalg.cond(G) > 1e12:
                continue
            b = P.T @ res
            drop = float(b @ np.linalg.solve(G, b))
            if drop > best_drop:
                best_j, best_drop = j, drop
        price = pair_price + (f_price if not chosen else 0.0)
        if best_j < 0 or best_drop <= price:
            break
        chosen.append(best_j)
        current = np.hstack([current, columns[best_j]])
    if not chosen:
        return None
    rss, _, coef = linear_fit(current, r, k)
    m0 = design.shape[1]
    pairs = coef[m0:].reshape(len(chosen), 2)
    phasor = {j: complex(c, -s_) for j, (s_, c) in zip(chosen, pairs, strict=True)}  # y = Re(X e^(j w t))
    for deriv, chan, scale in motions:
        if deriv in phasor and chan in phasor and is_motion(phasor[deriv], phasor[chan], f_best, scale):
            return None
    return Interference(
        frequency_hz=f_best,
        channels=tuple(chosen),
        coef=coef[m0:].reshape(len(chosen), 2),
        rss=rss,
        penalty=f_price + len(chosen) * pair_price,
        design_coef=coef[:m0],
    )
