"""Reports: figures (maps, image panels, radial profiles, axis motion, following error)
and the
self-contained ``report.html`` of a comparison, from metrics and images."""

from __future__ import annotations

from ._figures import image_panels, line_panels, map_panels, png_bytes, radial_profile_figure
from ._following import plot_following_error, plot_following_error_map
from ._html import HtmlReport, data_uri, table_html
from ._kinematics import kinematics_png, plot_kinematics
from ._page import build_page

__all__ = ["build_page", "HtmlReport", "data_uri", "table_html", "plot_kinematics",
           "kinematics_png", "image_panels", "map_panels", "png_bytes", "radial_profile_figure",
           "line_panels", "plot_following_error", "plot_following_error_map"]
