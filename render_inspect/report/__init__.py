"""Reports: ``render-inspect compare`` (compensated vs uncompensated, optionally vs a
measured map) with its ``metrics.json`` and self-contained ``report.html``.

Entry point: :func:`run_compare`.  Mitsuba is used only through
:mod:`render_inspect.render`, imported inside the functions.
"""

from __future__ import annotations

from ._compare import (COMPARE_MAX_CAMERA_PIXELS, COMPARE_MAX_DIFFUSE_RESOLUTION,
                       COMPARE_MAX_DIFFUSE_SPP, PROFILE_ANGLES_DEG, VARIANTS, compare_variants,
                       preview_render_configs, run_compare)
from ._html import HtmlReport, data_uri, table_html
from ._page import build_page

__all__ = ["run_compare", "compare_variants", "preview_render_configs", "build_page",
           "HtmlReport", "data_uri", "table_html", "VARIANTS", "PROFILE_ANGLES_DEG",
           "COMPARE_MAX_CAMERA_PIXELS", "COMPARE_MAX_DIFFUSE_RESOLUTION",
           "COMPARE_MAX_DIFFUSE_SPP"]
