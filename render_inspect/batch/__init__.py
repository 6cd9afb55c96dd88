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
from ._cluster import (
                     MAX_WORKERS,
                     call_with_threads,
                     check_scheduler,
                     check_workers_option,
                     cluster_info,
                     dashboard_text,
                     dask_client,
                     open_client,
                     plan_workers,
                     wait_for_workers,
)
from ._imagetest import (
                     compare_deterministic,
                     flip_mean,
                     image_t_test,
                     pass_statistics,
                     sidak_threshold,
)
from ._morris import (MORRIS_STUDY, MorrisConfig, MorrisFactor, elementary_effects,
                      morris_design, morris_indices, morris_unit_design, point_key)
from ._plots import default_plots, plot_rows
from ._progress import Progress
from ._results import (
                     SUMMARY_METRICS,
                     ResultsLog,
                     csv_safe,
                     csv_text,
                     flatten,
                     folder_lock,
                     md_text,
                     summary_table,
)
from ._select import (MACHINING_TIME, SelectConfig, machining_time, missing_metrics,
                      select_lines, select_point)
from ._summary import RegressionFailed, replaced_dir, write_summary_html
from ._tiled import TiledStats, run_tiles, tile_client
from ._sweepfile import (
                     PlotConfig,
                     RunConfig,
                     Study,
                     MAX_POINTS,
                     SweepFile,
                     SweepPoint,
                     check_file_name,
                     count_points,
                     dotted_get,
                     expand_points,
                     fixed_keys,
                     point_id,
                     read_sweep,
                     sweep_keys,
                     toml_value,
)

__all__ = ["SweepFile", "Study", "RunConfig", "PlotConfig", "SweepPoint", "read_sweep",
           "expand_points", "sweep_keys", "toml_value", "point_id", "dotted_get",
           "fixed_keys", "count_points", "MAX_POINTS", "check_file_name", "csv_safe", "md_text",
           "ResultsLog", "flatten", "csv_text", "summary_table", "folder_lock", "SUMMARY_METRICS",
           "plot_rows", "default_plots", "Progress",
           "dask_client", "check_workers_option", "dashboard_text", "MAX_WORKERS",
           "plan_workers", "check_scheduler", "cluster_info", "call_with_threads", "open_client", "wait_for_workers",
           "compare_deterministic", "image_t_test", "pass_statistics", "sidak_threshold",
           "flip_mean", "RegressCase", "Tolerance", "read_case", "list_cases", "case_hash",
           "read_reference", "write_reference", "IMAGE_NAMES",
           "write_summary_html", "RegressionFailed", "replaced_dir", "run_tiles", "tile_client",
           "TiledStats", "MorrisConfig", "MorrisFactor", "morris_design", "morris_unit_design",
           "morris_indices", "elementary_effects", "point_key", "MORRIS_STUDY",
           "SelectConfig", "machining_time", "select_point", "select_lines", "missing_metrics",
           "MACHINING_TIME"]
