"""Reports: every figure the package draws (maps, image panels, radial profiles, axis
motion, following error, the comparison's figures, the instrument's characterisation,
sweep plots and their Morris indices, the regression's images) and the self-contained ``report.html`` of a
comparison, from metrics and arrays.  Stages describe the figures they want as data
(:func:`draw_figure`); only this package draws."""

from __future__ import annotations

from ._comparison import (ComparedVariant, comparison_figures, comparison_summary,
                          diffuse_caption, luminance, srgb)
from ._draw import FIGURE_KINDS, draw_figure, drawn_data, figure_kinds, preload_drawing, uses_matplotlib
from ._figure_kinds import register_figure, registered_figures
from . import _edge_plot  # noqa: F401  (registers the figure kinds tool_edge, tool_wear)
from ._figures import (annotate_rgb, block_mean, display_map, image_panels, line_panels,
                       lowpass_map, map_panels, png_bytes, radial_profile_figure)
from ._locator import difference_figure, locator_figure
from ._fit import fit_figures, fit_page, fit_provenance_section, psd_figure
from ._following import plot_following_error, plot_following_error_map
from ._format import fmt_number, fmt_quantity, nice_length, scale_bar_length
from ._html import HtmlReport, data_uri, table_html
from ._keys import key_label, key_unit
from ._instrument import analysis_summary, characterise_figures, measurement_summary
from ._kinematics import (axis_motion_figure, kinematics_png, moving_axes, plot_kinematics,
                          turning_axes)
from ._morris import morris_png
from ._maps import (image_png, residual_png, residual_preview_image, residual_preview_png, rgb_png,
                    save_height_png, save_map_png)
from ._page import build_page
from ._program_page import program_figure_name, program_section
from ._provenance import provenance_section, warnings_section
from ._profile_figs import profile_figure, profile_overlay_figure
from ._quickplot import map_png, maps_png, panels_png
from ._sweep_plots import curves_png, heatmap_png, sweep_plot_png
from ..core.plugins import import_private_modules

__all__ = ["build_page", "HtmlReport", "data_uri", "table_html", "plot_kinematics",
           "kinematics_png", "image_panels", "map_panels", "png_bytes", "radial_profile_figure",
           "line_panels", "plot_following_error", "plot_following_error_map",
           "annotate_rgb", "block_mean", "display_map", "lowpass_map", "difference_figure", "fmt_number",
           "fmt_quantity", "nice_length", "scale_bar_length", "locator_figure", "axis_motion_figure", "moving_axes",
           "turning_axes", "draw_figure", "drawn_data", "preload_drawing", "uses_matplotlib", "FIGURE_KINDS", "save_map_png", "save_height_png",
           "residual_png", "residual_preview_image", "residual_preview_png", "image_png", "rgb_png", "map_png",
           "panels_png", "maps_png", "characterise_figures", "measurement_summary", "analysis_summary",
           "curves_png", "heatmap_png", "sweep_plot_png", "morris_png",
           "ComparedVariant", "comparison_figures", "comparison_summary", "diffuse_caption", "srgb",
           "luminance", "fit_figures", "fit_page", "fit_provenance_section", "psd_figure", "figure_kinds",
           "register_figure", "registered_figures", "profile_figure",
           "profile_overlay_figure", "program_section", "program_figure_name", "key_label", "key_unit",
           "provenance_section", "warnings_section"]

# figure kinds added as modules of this package register themselves on import
import_private_modules(__name__, __path__)
