"""Where a gap outside the catalogue lies, and what the missing term looks like.

When no catalogue effect explains a record (verdict "unexplained"), the
residual of the calibration is explained instead by an *unknown input* d(t) at
one locus of the plant (model 1.1's :class:`~engine.simulation.Disturbance`):
a relative supply-voltage deviation, an additive electromagnetic torque, a
torque on the motor shaft, an angle offset of the backlash zone or (model 1.8) a torque
across the clutch (both inputs of the clutch: ``DISTURBANCE_PART``), a torque on the drive
wheel, or a torque on the load. The method is unknown-input
estimation around the calibrated trajectory, one locus at a time:

1. **Responses** (one batch). d(t) is piecewise linear, with knots every
   ``knot_spacing`` (one of them on the calibrated event); the hats of the
   knots over the test window and ``history`` before it are free, plus two
   unpenalised *extras*: a constant from switch-on and a step at the switch-off.
   For every locus, hat and extra, the calibrated case is simulated with a small
   probe of it; the difference from the calibrated simulation, whitened by the
   calibration's per-channel ``sigma``, is one column of the locus's response
   matrix A (record channels only). The calibrated parameters' own columns (K,
   J1, c, c1, ...) are projected out, so a term that a small change of the
   operating point explains is not credited to any locus.
2. **Linearised fit per locus.** The whitened residual r is fitted by ``A x``
   with a roughness penalty ``lambda (|D x|^2 + eps |x|^2)`` (D first differences:
   a stretch the record does not determine, e.g. a zone offset while the clutch is
   open, is interpolated rather than set to zero); lambda minimises
   ``BIC = RSS + (dof + k) ln(n)``, dof the effective degrees of freedom.
3. **Scan of simple inputs.** A constant or a step of several sizes at every
   locus, with the calibrated parameters re-fitted (linearised, then two damped
   Gauss-Newton steps): a global start where a term is too strong to linearise
   (a zone offset of a few tenths of a millimetre moves every impact). The same from each
   of the calibration's global starts, and a dense scan of a zone offset from each start
   along the widths that keep one side of the zone in place (``_zone_trials``). The parts
   with a rotating mass (motor shaft, drive wheel, load) also get a term that follows the
   state, a Coulomb friction against the part's own speed (:data:`COULOMB_FIELDS`): scanned,
   and fitted with the calibrated parameters by a global search (``friction_fits``); a
   friction that stops a part is out of reach of any schedule d(t) linearised around a
   trajectory where it moves.
4. **Refinement.** From the better of the two starts, damped Gauss-Newton
   iterations re-linearise each locus around its current estimate (one
   iteration for every locus, more for the best ``refine_loci``); every step is
   kept only if its *simulated* chi2 falls. The loci are ranked by the
   simulated chi2 plus ``(dof + extras + k) ln(n)``.
5. **Sensors.** An arbitrary additive sensor error would explain any residual,
   so the measurement chain gets a parametric library instead: per-channel
   offset and gain, one delay and one first-order low-pass (their response
   columns, unpenalised, linearised), and, taken sparsely, a cross-talk from
   any channel into any other (channel i reads ``g_ij`` times channel j besides
   its own signal): forward selection of at most two such columns, each taken
   only when it lowers the residual by more than ``ln n + 2 ln p`` (p candidate
   columns: the risk-inflation criterion, so noise alone picks none); and a periodic
   interference, channels reading a sinusoid of one fixed frequency besides their signal,
   taken only on channels where it keeps its amplitude and phase over the window
   (``_interference``).
6. **Evidence.** Posterior weights ``exp(-BIC / 2)``, with the BIC differences
   divided by the best fit's dispersion (chi2 per degree of freedom, at least
   1: a best fit far above the noise means the model is still wrong somewhere),
   give the confidence; loci within ``tie_delta`` of the best are *ties*.
7. **Term.** The best locus's d(t) on the record's grid: amplitude (RMS, peak),
   dominant frequency, and what it follows: ``constant``, ``time`` (a sinusoid
   of fixed frequency, or a transient from the event), ``angle`` (periodic in the
   motor angle, the integral of omega1, so its frequency is proportional to the
   speed) or ``speed`` (a sign and a proportional part of the motor or the load
   speed), each fitted by weighted least squares, the weight of every instant
   the resolution of d there, with and without damping isolated spikes.

The package, one module per idea: ``_report`` (settings and results), ``_cases`` (the calibrated
case with an input, a friction or its parameters moved), ``_responses`` (step 1, and the record as
the fits see it), ``_linear`` (the fits of step 2), ``_starts`` (step 3), ``_refine`` (step 4),
``_term`` (steps 5 and 7), ``_interference`` (the sensors' periodic interference), ``_estimate`` (:func:`estimate_locus`: the steps in order, and step 6).

Assumptions, limits and measured accuracy: ``docs/diagnosis.md`` ("Locus of a
gap outside the catalogue").
"""

from __future__ import annotations

from engine.diagnosis.locus._estimate import FIRST_GUESS_CONFIDENCE as FIRST_GUESS_CONFIDENCE
from engine.diagnosis.locus._estimate import SENSORS as SENSORS
from engine.diagnosis.locus._estimate import estimate_locus
from engine.diagnosis.locus._report import LocusError, LocusReport, LocusScore, LocusSettings, Term
from engine.diagnosis.locus._responses import N_EXTRAS as N_EXTRAS
from engine.diagnosis.locus._responses import PROBE as PROBE
from engine.diagnosis.locus._starts import SCAN_SCALE as SCAN_SCALE

__all__ = ["LocusError", "LocusReport", "LocusScore", "LocusSettings", "Term", "estimate_locus"]
