"""Fitting the scene to a measured surface: which tool, feed, machine and material settings
produced it.

Arrays and numbers in, numbers out, like :mod:`render_inspect.metrology`: the forward model
(the cut and the virtual instrument) is handed in as a function, so this package needs no
import of the simulation itself (``render_inspect.pipeline`` chains it).

* :func:`free_parameters`: the free scene keys, their start values and their bounds from the
  scene's schema (:mod:`._params`);
* :class:`MisfitSpec`, :func:`make_target`, :func:`residual_vector`: the robust misfit with
  its spectral terms (:mod:`._features`);
* :class:`Evaluator`, :func:`solve`: the bounded least-squares fit with its evaluations in
  batches on Dask, cached by the hash of each evaluation (:mod:`._solve`, :mod:`._evaluator`,
  :mod:`._cache`), all within ``--max-evaluations`` (:mod:`._budget`);
* :func:`fit_window`, :func:`register_field`: where the measured field lies (:mod:`._placement`);
* :func:`check_before`, :func:`check_after`, :func:`profile_marks`: whether the scene
  describes the measurement at all (:mod:`._checks`);
* :func:`fit_record`: the content of ``fit.json`` (:mod:`._result`);
* :func:`plan_propagation`, :func:`combine_propagation`: the fit's uncertainty carried to a
  prediction made with the fitted values (:mod:`._propagate`), over the window
  :func:`prediction_window` gives, its numbers averaged over where the marks fall in it
  (:func:`phase_average`, :mod:`._predict_window`);
* :class:`ProfileSpec`, :func:`make_profile_target`, :func:`profile_family`: the same
  for a measured profile (:mod:`._profile`), and both arms of a diameter slice together
  (:class:`ArmsTarget`, :func:`arm_estimates`, :func:`combine_arms`: :mod:`._arms`).
"""

from ._cache import EvaluationCache, scene_hash, task_hash
from ._features import (FORMS, MisfitSpec, Prediction, Target, make_target, noise_floor,
                        predict_features, prepare_map, radial_psd, residual_vector,
                        set_noise_floor, soft_l1, waviness)
from ._params import (FreeParameter, free_parameters, get_value, parse_bounds, parse_free,
                      schema_range, set_value)
from ._checks import (MARK_KEYS, MISMATCH, PERIOD_TOLERANCE, check_after, check_before,
                      mark_tiles, profile_marks, within_reach)
from ._profile import (PROFILE_TERMS, ProfileSpec, ProfileTarget, make_profile_target,
                       predict_profile_features, profile_family, profile_residual_vector,
                       set_profile_noise_floor, set_profile_psd)
from ._arms import (ARMS_CHOICES, ArmsPrediction, ArmsTarget, arm_estimates, arm_evaluations,
                    arms_features, arms_text, combine_arms, set_arms_noise_floor)
from ._profile_psd import amplitude_scan
from ._placement import centred_origin, check_units, field_extent, fit_window, register_field
from ._result import fit_record, misfit_maps, summary_lines
from ._local import run_local
from ._budget import BudgetExhausted
from ._evaluator import Evaluation, Evaluator
from ._solve import UNRESOLVED, FitResult, solve
from ._uncertainty import identifiability, realisation_shifts, search_box

from ._weights import check_weights, parse_weights
from ._predict_window import (MIN_PERIODS, PHASES, PredictionWindow, phase_average,
                              prediction_window)
from ._propagate import (COVERAGE_FACTOR, PREDICTED_QUANTITIES, Propagation, SigmaPoint,
                         combine_propagation, plan_propagation, prediction_lines)

__all__ = ["check_weights", "parse_weights",
           "FreeParameter", "free_parameters", "parse_free", "parse_bounds", "schema_range",
           "set_value", "get_value", "MisfitSpec", "Target", "Prediction", "FORMS",
           "make_target", "noise_floor", "set_noise_floor", "predict_features", "prepare_map",
           "radial_psd", "residual_vector", "realisation_shifts", "soft_l1", "waviness",
           "EvaluationCache", "task_hash", "scene_hash", "Evaluation", "Evaluator",
           "FitResult", "solve", "run_local", "UNRESOLVED", "BudgetExhausted", "field_extent",
           "centred_origin", "fit_window", "register_field", "check_units", "fit_record",
           "misfit_maps", "summary_lines", "identifiability", "search_box", "check_before", "check_after",
           "mark_tiles", "profile_marks", "MARK_KEYS", "MISMATCH", "PERIOD_TOLERANCE",
           "PROFILE_TERMS", "ProfileSpec", "ProfileTarget", "make_profile_target",
           "predict_profile_features", "profile_family", "profile_residual_vector",
           "set_profile_noise_floor", "within_reach", "ARMS_CHOICES", "ArmsTarget",
           "arm_estimates", "arm_evaluations", "arms_text", "combine_arms", "set_arms_noise_floor",
           "ArmsPrediction", "arms_features", "amplitude_scan", "set_profile_psd",
           "COVERAGE_FACTOR", "PREDICTED_QUANTITIES", "Propagation", "SigmaPoint",
           "combine_propagation", "plan_propagation", "prediction_lines", "MIN_PERIODS",
           "PHASES", "PredictionWindow", "phase_average", "prediction_window"]
