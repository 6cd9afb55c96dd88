"""Batch work: parameter sweeps (sweep files, results on disk, what their plots show, the
Dask cluster, progress), the tiled out-of-core simulation of a height map on Dask, and
image regression (case files, references, statistics, the HTML summary).

The pipeline chains the stages (``pipeline.run_sweep``, ``pipeline.run_regress``); this
package holds what those two need besides the stages: numbers, files and the cluster.
"""

from ._cases import (
                     IMAGE_NAMES,
                     RegressCase,
                     Tolerance,
                     case_hash,
                     list_cases,
                     read_case,
                     read_reference,
                     write_reference,
)
from ._cluster import MAX_WORKERS, check_workers_option, dashboard_text, dask_client
from ._imagetest import (
                     compare_deterministic,
                     flip_mean,
                     image_t_test,
                     pass_statistics,
                     sidak_threshold,
)
from ._plots import default_plots, plot_rows
from ._progress import Progress
from ._results import (
                     SUMMARY_METRICS,
                     ResultsLog,
                     csv_text,
                     flatten,
                     folder_lock,
                     summary_table,
)
from ._summary import RegressionFailed, replaced_dir, write_summary_html
from ._tiled import TiledStats, run_tiles, tile_client
from ._sweepfile import (
                     PlotConfig,
                     RunConfig,
                     Study,
                     SweepFile,
                     SweepPoint,
                     dotted_get,
                     expand_points,
                     point_id,
                     read_sweep,
                     sweep_keys,
                     toml_value,
)

__all__ = ["SweepFile", "Study", "RunConfig", "PlotConfig", "SweepPoint", "read_sweep",
           "expand_points", "sweep_keys", "toml_value", "point_id", "dotted_get",
           "ResultsLog", "flatten", "csv_text", "summary_table", "folder_lock", "SUMMARY_METRICS",
           "plot_rows", "default_plots", "Progress",
           "dask_client", "check_workers_option", "dashboard_text", "MAX_WORKERS",
           "compare_deterministic", "image_t_test", "pass_statistics", "sidak_threshold",
           "flip_mean", "RegressCase", "Tolerance", "read_case", "list_cases", "case_hash",
           "read_reference", "write_reference", "IMAGE_NAMES",
           "write_summary_html", "RegressionFailed", "replaced_dir", "run_tiles", "tile_client",
           "TiledStats"]
