"""Metrology, arrays in and numbers out: measuring interferometer frames (no truth),
evaluating against a truth, ISO 25178 / 21920 parameters, ISO 16610-61 Gaussian filters, form removal,
outliers and 6-DOF registration (seed 002), microstructure-array analysis (lenslet
centres, dislocations, per-lenslet form errors), and comparison of measured maps with a
scene's design and simulation.  Plain numpy/scipy; lengths in mm."""

from ._compare import (
                       Comparison,
                       characterise_map,
                       check_same_pixel,
                       compare_measured,
                       coverage,
                       resample_map,
                       sample_map,
)
from ._filter_choice import MARK_LEAK_NM, scallop_pv, waviness_filters
from ._filters import (
                       EDGE_MODES,
                       GAUSSIAN_ALPHA,
                       gaussian_filter,
                       gaussian_sigma,
                       gaussian_transmission,
                       l_filter,
                       remove_form,
                       s_filter,
                       valid_mask,
)
from ._msa import (
                       LENSLET_KEYS,
                       base_form_error,
                       characterise_msa,
                       lenslet_centers,
                       lenslet_table,
                       separate_msa,
)
from ._params import (
                       areal_parameters,
                       extract_section,
                       profile_parameters,
                       section_parameters,
)
from ._phase import (
                       PhaseResult,
                       evaluate_measurement,
                       height_error,
                       height_from_phase,
                       measure_frames,
                       phase_quality,
                       retrieve_csi,
                       retrieve_psi,
                       unwrap_phase,
                       wrapped_phase,
)
from ._registration import (
                       RIGID_KEYS,
                       GridSurface,
                       MovedSurface,
                       detect_outliers,
                       register_icp,
                       register_lsq,
                       rigid_resample,
                       rotation_matrix,
                       template_surface,
)

__all__ = [
    "areal_parameters", "profile_parameters", "extract_section", "section_parameters",
    "GAUSSIAN_ALPHA", "gaussian_sigma", "gaussian_filter", "s_filter", "l_filter",
    "remove_form", "valid_mask", "EDGE_MODES", "gaussian_transmission",
    "waviness_filters", "scallop_pv", "MARK_LEAK_NM",
    "RIGID_KEYS", "rotation_matrix", "rigid_resample", "MovedSurface", "detect_outliers",
    "GridSurface", "template_surface", "register_lsq", "register_icp",
    "LENSLET_KEYS", "lenslet_centers", "separate_msa", "lenslet_table", "base_form_error",
    "characterise_msa",
    "characterise_map", "coverage", "check_same_pixel", "resample_map", "sample_map",
    "Comparison", "compare_measured",
    "PhaseResult", "wrapped_phase", "unwrap_phase", "phase_quality", "height_from_phase",
    "retrieve_psi", "retrieve_csi", "height_error", "measure_frames",
    "evaluate_measurement",
]
