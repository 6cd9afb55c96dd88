"""Metrology, arrays in and numbers out: measuring interferometer frames (no truth),
evaluating against a truth, ISO 25178 / 21920 parameters (slopes as the reference
libraries take them; Sal / Str from the autocorrelation), one-map analysis, checks
before a comparison, ISO 16610-61 Gaussian filters, form removal, outliers and 6-DOF
registration (after Kong et al. 2020) with its uncertainty, microstructure-array analysis
(lenslet centres, dislocations, per-lenslet form errors), and comparison of measured maps
with a scene's design and simulation.  Plain numpy/scipy; lengths in mm; pixels one number
or (pixel_x, pixel_y).  The papers and standards each model follows are cited in its
module's References (docs/references.md lists them all)."""

from ._analysis import (FORMS, OUTLIER_METHODS, Analysis, analyze_map, analyze_memory,
                        analyze_memory_per_point, check_filter, filter_range,
                        parse_filter)
from ._windowed import (WINDOWED_FORMS, analyze_bands, band_bytes_per_point, form_on_grid,
                        windowed_refusal)
from ._chance import (NULL_GRID, NULL_POINTS, NULL_SURROGATES, SURROGATE_ITERATIONS,
                      SURROGATE_TOLERANCE, explained_share, phase_surrogate, plane_free_surrogates,
                      registration_against_chance, unreliable_registration_warning)
from ._checks import (DEFAULT_MAX_RESIDUAL_RATIO, DEFAULT_MIN_OVERLAP, DEFAULT_RESIDUAL_FLOOR_MM,
                      correlation_area, kinematic_sq_mm, registered_overlap, registration_checks)
from ._compare import (Comparison, characterise_map, check_same_pixel, compare_measured,
                       coverage, resample_map, sample_map)
from ._filter_choice import (FINEST_RENDERED_MARKS_MM, MARK_LEAK_NM, expected_sq_mm, feature_size,
                             mark_size, render_marks, scallop_pv, waviness_choice,
                             waviness_filters, waviness_map)
from ._lenslet_facts import lenslet_facts, lenslet_metrics, msa_metrics
from ._filters import (EDGE_MODES, GAUSSIAN_ALPHA, fit_sphere, gaussian_filter, gaussian_sigma,
                       gaussian_transmission, l_filter, pixel_xy, remove_form, s_filter,
                       valid_mask)
from ._msa import (LENSLET_KEYS, base_form_error, characterise_msa, lenslet_centers,
                   lenslet_table, separate_msa)
from ._profiles import (areal_nm, common_window, crop_window, difference_profiles,
                        difference_stats, line_profile, profile_center, sections,
                        surface_slope)
from ._params import (SLOPE_ESTIMATORS, areal_parameters, forward_slope_sums, autocorrelation, extract_section,
                      profile_parameters, section_parameters, slope_parameters,
                      spatial_parameters)
from ._instrument import (BatwingLobes, batwing, dropout_slope, edge_width, noise_by_subtraction,
                          pupil_overlap, sinusoid_amplitude, slope_table)
from ._levelling import FORM_TERMS, level_map, measured_difference
from ._measure import ALGORITHMS, measure_frames
from ._noise import (FALSE_ALARM, csi_height_noise, csi_noise_threshold, noise_sigmas,
                     psi_height_noise, psi_noise)
from ._fringe_order import (AMBIGUOUS_ORDER, FAILED_FRACTION, difference_order_check,
                            fringe_order_check, phase_residues)
from ._resolution import (RESOLVED_RATIO, difference_noise, measurement_seeds,
                          repeat_statistics, resolution)
from ._phase import (PhaseResult, evaluate_measurement, height_error, height_from_phase,
                     retrieve_csi, retrieve_psi, wrapped_phase)
from ._registration import (RIGID_KEYS, GridSurface, MovedSurface, detect_outliers,
                            register_icp, register_lsq, registration_covariance, rigid_resample,
                            rotation_matrix, template_surface)
from ._unwrap import phase_quality, unwrap_phase
from ._iso21920 import (LAMBDA_C_SERIES, default_cutoffs, evaluate_profile,
                        gaussian_profile_weights, material_ratio_curve, parse_profile_filter,
                        profile_gaussian_filter, profile_texture, rmr, roughness_profile)
from ._periods import dominant_periods, map_periods, mirror_centre, profile_periods
from ._profile_analysis import PROFILE_FORMS, PROFILE_KEYS, analyze_profile, profile_metrics

__all__ = [
    "analyze_memory", "analyze_memory_per_point", "WINDOWED_FORMS", "analyze_bands",
    "band_bytes_per_point", "form_on_grid", "windowed_refusal", "forward_slope_sums",
    "areal_parameters", "slope_parameters", "spatial_parameters", "autocorrelation",
    "SLOPE_ESTIMATORS", "profile_parameters", "extract_section", "section_parameters",
    "GAUSSIAN_ALPHA", "gaussian_sigma", "gaussian_filter", "s_filter", "l_filter",
    "remove_form", "fit_sphere", "valid_mask", "pixel_xy", "EDGE_MODES",
    "gaussian_transmission", "waviness_filters", "scallop_pv", "MARK_LEAK_NM",
    "RIGID_KEYS", "rotation_matrix", "rigid_resample", "MovedSurface", "detect_outliers",
    "GridSurface", "template_surface", "register_lsq", "register_icp",
    "registration_covariance",
    "FORMS", "OUTLIER_METHODS", "Analysis", "analyze_map", "parse_filter", "check_filter",
    "filter_range", "analyze_memory", "analyze_memory_per_point",
    "registered_overlap", "correlation_area", "registration_checks", "kinematic_sq_mm",
    "DEFAULT_MIN_OVERLAP", "DEFAULT_MAX_RESIDUAL_RATIO", "DEFAULT_RESIDUAL_FLOOR_MM",
    "NULL_SURROGATES", "NULL_POINTS", "NULL_GRID", "SURROGATE_TOLERANCE", "SURROGATE_ITERATIONS",
    "phase_surrogate", "plane_free_surrogates", "explained_share",
    "registration_against_chance", "unreliable_registration_warning",
    "LENSLET_KEYS", "lenslet_centers", "separate_msa", "lenslet_table", "base_form_error",
    "characterise_msa",
    "characterise_map", "coverage", "check_same_pixel", "resample_map", "sample_map",
    "Comparison", "compare_measured",
    "PhaseResult", "wrapped_phase", "unwrap_phase", "phase_quality", "height_from_phase",
    "retrieve_psi", "retrieve_csi", "height_error", "measure_frames", "ALGORITHMS",
    "evaluate_measurement", "FORM_TERMS", "level_map", "measured_difference",
    "FALSE_ALARM", "psi_noise", "csi_noise_threshold", "noise_sigmas",
    "psi_height_noise", "csi_height_noise", "AMBIGUOUS_ORDER", "FAILED_FRACTION",
    "difference_order_check", "fringe_order_check", "phase_residues", "RESOLVED_RATIO",
    "difference_noise", "measurement_seeds", "repeat_statistics", "resolution",
    "sinusoid_amplitude", "pupil_overlap", "edge_width", "batwing", "BatwingLobes", "slope_table",
    "dropout_slope", "noise_by_subtraction",
    "mark_size", "feature_size", "waviness_choice", "render_marks", "expected_sq_mm",
    "FINEST_RENDERED_MARKS_MM", "waviness_map", "lenslet_facts", "lenslet_metrics", "msa_metrics",
    "common_window", "crop_window", "line_profile", "difference_stats", "sections",
    "profile_center", "areal_nm", "difference_profiles", "surface_slope",
    "LAMBDA_C_SERIES", "default_cutoffs", "evaluate_profile", "gaussian_profile_weights",
    "material_ratio_curve", "parse_profile_filter", "profile_gaussian_filter",
    "profile_texture", "rmr", "roughness_profile",
    "dominant_periods", "map_periods", "mirror_centre", "profile_periods",
    "PROFILE_FORMS", "PROFILE_KEYS", "analyze_profile", "profile_metrics",
]
