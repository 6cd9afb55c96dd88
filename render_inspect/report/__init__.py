"""Reports: figures (maps, image panels, radial profiles, axis motion, following error)
and the
self-contained ``report.html`` of a comparison, from metrics and images."""

from __future__ import annotations

from ._figures import (annotate_rgb, block_mean, difference_figure, display_map, image_panels,
                       line_panels, locator_figure, map_panels, png_bytes,
                       radial_profile_figure)
from ._fit import fit_figures, fit_page, psd_figure
from ._following import plot_following_error, plot_following_error_map
from ._format import fmt_number, fmt_quantity, nice_length
from ._html import HtmlReport, data_uri, table_html
from ._kinematics import (axis_motion_figure, kinematics_png, moving_axes, plot_kinematics,
                          turning_axes)
from ._page import build_page

__all__ = ["build_page", "HtmlReport", "data_uri", "table_html", "plot_kinematics",
           "kinematics_png", "image_panels", "map_panels", "png_bytes", "radial_profile_figure",
           "line_panels", "plot_following_error", "plot_following_error_map",
           "annotate_rgb", "block_mean", "display_map", "difference_figure", "fmt_number",
           "fmt_quantity", "nice_length", "locator_figure", "axis_motion_figure", "moving_axes",
           "turning_axes", "fit_figures", "fit_page", "psd_figure"]
