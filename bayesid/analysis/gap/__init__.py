"""Sim-to-real gap diagnosis: where the model misses, which unmodelled effect causes it, and
how far the gap shrinks once that effect is in the model.

:func:`diagnose` receives only tracks, the vehicle (nominal coefficients) and the names of the
free coefficients. It

1. fits the base model on the training tracks (simulation error over protocol windows that
   restart from the measured state -- multiple shooting;
   :func:`bayesid.estimation.windows.fit_weighted`);
2. **where**: residuals per channel, per operating region (drift angle, yaw rate, rudder angle,
   speed), per manoeuvre phase, their spectrum, the missing forces X, Y, N from inverse
   dynamics, Ljung-Box whiteness and cross-correlation with the inputs and their rates, and for
   a ship each run's propulsion point against the model's (:func:`.where.approach_check`: held-out
   runs from another basin, model or propeller, which no fitted coefficient carries)
   (:mod:`.where`);
3. **which**: refits the model with each catalogue effect in turn (the effect's parameters and
   all free coefficients) and ranks the candidates by held-out RMS position error, with the
   BIC difference on the training tracks and a sparse regression (pysindy STLSQ ensemble) of
   the missing forces on effect signatures as independent support (:mod:`.support`). A
   candidate whose effect has a catalogue ``neutral`` value contains the model it extends; if
   its fits end worse than that model, it is refitted from that model's optimum with the effect
   neutral (so ΔBIC <= k ln n; :mod:`.candidates`);
4. **how far**: the protocol's scores before and after the top effect, on the training and the
   held-out tracks: RMS and maximum position error, heading RMS, and the Gaussian log-likelihood
   of all scored channels at the fits' channel sds (:func:`bayesid.estimation.windows.scores`).

The package is split by question: :mod:`.where`, :mod:`.candidates`, :mod:`.verdict` (the rules
below), :mod:`.support`, the typed records the steps pass on and the JSON writes (:mod:`.records`:
noise floor, candidate rows, remainder, contributions, the logged-thrust and approach checks, the first round
beside discovery, base-fit check, discovered-term rows, the design's runs with the run test's
outlook, their pairs of alternatives keyed ``(a, b)`` and written ``"A vs B"``; each read back from
its JSON by ``from_dict``), and the orchestration :mod:`.diagnose`, which returns a
:class:`~.diagnose.Diagnosis`; the report layer (:func:`bayesid.report.write_diagnosis`) writes it,
reading the records by attribute. What travels between the steps travels as named records too,
not packed in tuples: the verdict's :class:`~.verdict.Thresholds` and
:class:`~.verdict.RunSeparation`, the rounds' :class:`~.diagnose.CandidateFits`,
:class:`~.diagnose.Judge` and :class:`~.diagnose.Rounds`, discovery's
:class:`~.discovery.selection.Selection` and :class:`~.discovery.confirmation.Refits`.
Every model of a diagnosis is a :class:`bayesid.estimation.windows.WindowProblem` (its contexts
built by :func:`bayesid.estimation.windows.contexts` from the diagnosis's
:class:`~.candidates.Setup`): the steps fit it (``problem.fit``) and read each fitted model
from one :class:`bayesid.estimation.windows.Evaluation` per track set (scores, per-window
errors, the simulated states *where* reads); none calls the shooting layer itself. The base
model's two Evaluations (:class:`~.candidates.BaseStage`) serve its scores, *where*, and the
candidates' seeds.

Window start states follow the protocol's start rule (:data:`bayesid.protocol.START_RULES`):
restarted from the measured state when u, v, r are logged, else fitted with the model being
scored (:mod:`bayesid.estimation.shooting`: a 10 s lead-in before each held-out window; the window starts
of the training fits as nuisance parameters). One rule serves every model compared and the floor.

Verdict rules (stated in the report):

* the gap is *significant* when the held-out RMS position error exceeds ``none_ratio`` (1.5)
  times the **noise floor**: the error a model of the right form would show at the measured
  noise level, its coefficients known as well as the training runs tell them, estimated by
  simulating a model (the fitted base model and the nominal one; the smaller result counts) on
  the held-out inputs, adding noise of the sd estimated from the data
  (:func:`bayesid.protocol.estimate_noise`, without the lower bound that the fit weights use),
  and scoring that with the same start rule and coefficients drawn from the base fit's inverse
  Fisher information (:func:`~bayesid.analysis.gap.verdict.coefficient_draws`; with
  ``DiagnoseOptions(floor="noise")`` the model's own coefficients: a perfect model's error);
* an effect is *the cause* when, added with all coefficients re-identified, the held-out error
  falls into the floor band (at most ``none_ratio`` x the floor), it removes at least
  ``explain_fraction`` (0.5) of the excess over the floor, ``(rms_ref - rms_effect) /
  (rms_ref - floor)``, and its ΔBIC on the training tracks is at most ``-10`` (very strong evidence,
  Kass & Raftery 1995);
* an effect is a *contributor* when it improves the held-out windows without closing the gap:
  one-sided Wilcoxon signed-rank test of the paired per-window RMS position errors,
  ``p < partial_p`` (0.01; or at least ``explain_fraction`` of the excess removed, where too
  few windows leave the test without power), ΔBIC at most -10 and positive shrinkage. Its
  *share* is the part of the base model's excess it removes;
* greedy rounds (``max_effects``, default 2): the best-ranked cause is added and ends the
  search; else the best-ranked contributor is added and the next round refits every other
  candidate on top of it;
* verdict: ``"none"`` when the gap is not significant (candidates are still fitted and ranked,
  for the report, but none is attributed: on a gap barely above the floor a flexible candidate
  removes half of a small excess by fitting noise); else the effects added joined by ``+``,
  with ``+unexplained`` appended when the remainder is still significant (above the band), or
  ``"unexplained"`` alone when nothing helps -- a contributor is named as one, never as the
  cause. ``gap_after`` is the model with every effect added; ``remainder`` is what is left
  (fraction of the base excess, significant or not); ``contributors`` lists every effect that
  passed the contributor test (added or not) with its share, p-value, ΔBIC and parameters.
"""

from .candidates import Stage
from .diagnose import DiagnoseOptions, Diagnosis, diagnose
from .support import signature_regression
from .verdict import Thresholds, noise_floor, paired_window_test
from .where import approach_check, ljung_box, where, window_xy

__all__ = [
    "DiagnoseOptions",
    "Diagnosis",
    "Stage",
    "Thresholds",
    "diagnose",
    "ljung_box",
    "noise_floor",
    "paired_window_test",
    "signature_regression",
    "where",
    "approach_check",
    "window_xy",
]
