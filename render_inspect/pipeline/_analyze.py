"""``analyze``: one height map file (measured or simulated) -> ISO 25178-2 parameters,
a height map picture and, on request, an X3P of the evaluated surface.

The memory the analysis needs (:func:`~render_inspect.metrology.analyze_memory`) is
checked before the file is read.  A height-map store (``heightmap.zarr``) too large for
the memory budget is analysed window by window (:func:`~render_inspect.metrology.analyze_bands`:
its rows read in bands through ``dask.array``), with the exact values of the whole map;
Sal and Str then come from the finest pyramid level that fits, and options that need the
whole map at once are refused up front with the reason."""

from __future__ import annotations

import json
import logging
import math
import time
from pathlib import Path
from typing import cast

import numpy as np

from .. import __version__
from ..core.errors import InputError, MemoryBudgetError
from ..core.limits import check_memory, format_bytes, memory_budget
from ..core.progress import task
from ..core.units import GIB_TO_BYTES, MM_TO_NM, MM_TO_UM
from ..io import (ZarrHeightMap, atomic_output_dir, check_output_dir, is_profile_file, json_safe,
                  read_surface, write_x3p)
from ..metrology import (FORMS, OUTLIER_METHODS, analyze_bands, analyze_map, analyze_memory,
                         analyze_memory_per_point, band_bytes_per_point, map_periods,
                         parse_filter, windowed_refusal)
from ..report import save_height_png
from ._analyze_profile import run_analyze_profile
from ._metrics import analysis_metrics, write_metrics

__all__ = ["run_analyze", "ANALYZE_FILES", "analyze_budget"]

log = logging.getLogger("render_inspect")

#: Files ``analyze`` writes into its output folder.
ANALYZE_FILES = ("metrics.json", "height.png", "height.x3p")
#: share of the budget the bands of a windowed analysis may hold (the rest: the level
#: that gives Sal and Str, the picture, what zarr decodes at once)
_BAND_SHARE = 0.4
#: what a band holds at most when the budget allows more (larger bands do no less work,
#: they only hold more; a band spans whole rows of the store's chunks when one fits)
WINDOW_BYTES = GIB_TO_BYTES
#: what the coarse view that gives Sal and Str (and the periods) may need at most
SPATIAL_BYTES = GIB_TO_BYTES
#: a store whose whole-map analysis needs more than this is analysed window by window even
#: when the memory budget would hold it whole (the whole-map analysis grows to about 9 GiB
#: at 64 M samples; window by window a store of any size stays near 2 GiB), unless its
#: options need the whole map (:func:`~render_inspect.metrology.windowed_refusal`)
STORE_WHOLE_MAP_BYTES = 3 * GIB_TO_BYTES
#: the advice about a scene key that the memory budget's text gives other commands
_SCENE_ADVICE = ("; set simulation.max_memory_gb to choose", " or set simulation.max_memory_gb lower")


def _without_scene_advice(text: str) -> str:
    for a in _SCENE_ADVICE:
        text = text.replace(a, "")
    return text


def analyze_budget() -> tuple[int, str]:
    """``analyze``'s memory budget: the automatic one (a share of the memory available,
    capped by ``ulimit -v``), said without the scene key other commands set it with."""
    limit, source = memory_budget(None)
    return limit, _without_scene_advice(source)


def _is_store(path: Path) -> bool:
    return path.suffix.lower() == ".zarr" and path.is_dir()


def _title(path, m_pixel, ar, metrics, *, form, s_mm, l_mm, outliers, note="") -> str:
    parts = [f"form {form}"]
    if s_mm:
        parts.append(f"S {s_mm:g} mm")
    if l_mm:
        parts.append(f"L {l_mm:g} mm")
    if outliers != "none":
        parts.append(f"{metrics['outliers']['count']} outliers left out")
    return (f"{Path(path).name}: {', '.join(parts)}{note}\nSq {ar['Sq_nm']:.4g} nm, Sa "
            f"{ar['Sa_nm']:.4g} nm, Sz {ar['Sz_nm']:.4g} nm; pixel "
            f"{m_pixel[0] * MM_TO_UM:.4g} x {m_pixel[1] * MM_TO_UM:.4g} um")


def run_analyze(path: str | Path, out: str | Path, *, form: str = "plane",
                filter_spec: str | tuple | None = None,
                outliers: str = "none", outlier_sigma: float = 3.0, slope: str = "forward",
                x3p: bool = False, channel: str | None = None, overwrite: bool = False,
                budget: tuple[int, str] | None = None, units: str | None = None) -> dict:
    """Analyse one height map file and write the results.

    Parameters
    ----------
    path : str or Path
        Any file :func:`render_inspect.io.read_surface` reads (instrument formats, X3P,
        our ``heightmap.exr`` and ``heightmap.zarr`` - channel ``machined`` unless
        ``channel`` says otherwise).
    out : str or Path
        Output folder: checked before the file is read (it may not hold the input, which
        would be deleted with it), replaced as a whole when the results are complete
        (:func:`~render_inspect.io.atomic_output_dir`).
    form : {"none", "plane", "poly2", "sphere"}
        Form removed before the parameters (``none``: the mean only).
    filter_spec : "S,L" text or (S, L), optional
        ISO 16610-61 Gaussian nesting indices in mm; either may be empty / None.
    outliers : {"none", "sigma"}
        ``sigma`` leaves the ``outlier_sigma``-sigma spikes out.
    slope : {"forward", "central"}
        Derivative estimator of Sdq and Sdr.
    x3p : bool
        Also write ``height.x3p``: the evaluated surface (form removed, filtered; metres in
        the file as ISO 25178-72 requires).
    overwrite : bool
        Replace ``out`` even if render_inspect did not write it.
    budget : (bytes, source), optional
        The memory budget (default :func:`analyze_budget`).  A map whose analysis does not
        fit is refused before it is read, unless it is a store analysed window by window.
    units : str, optional
        For a profile text file that does not state its units (``um``, ``mm``, ``nm`` or
        ``POSITION,HEIGHT``).  A profile (:func:`~render_inspect.io.is_profile_file`) is
        analysed by :func:`run_analyze_profile` (ISO 21920-2 parameters, profile.png).

    Returns
    -------
    dict
        The content of ``metrics.json``: :func:`render_inspect.metrology.analyze_map`'s
        metrics plus ``input``, ``files``, ``software_version``, ``timing_s`` (and
        ``windowed`` for a store analysed window by window).  ``metrics["warnings"]`` are
        also logged.
    """
    t0 = time.perf_counter()
    path = Path(path)
    if is_profile_file(path):
        if x3p:
            raise InputError(f"--x3p writes an evaluated areal map; {path.name} is a profile")
        return run_analyze_profile(path, out, units=units, form=form, filter_spec=filter_spec,
                                   outliers=outliers, outlier_sigma=outlier_sigma,
                                   overwrite=overwrite)
    if units is not None and path.exists():
        # (a file that is not there is named as such by the reader below)
        raise InputError(f"--units is for profile text files that do not state their units; "
                         f"{path.name} is an instrument file, which states its own")
    check_output_dir(out, overwrite=overwrite, command="analyze", inputs=(path,))
    if form not in FORMS:
        raise InputError(f"--form must be one of {', '.join(FORMS)}, got {form!r}")
    if outliers not in OUTLIER_METHODS:
        raise InputError(f"--outliers must be one of {', '.join(OUTLIER_METHODS)}, got {outliers!r}")
    s_mm, l_mm = (parse_filter(filter_spec) if not isinstance(filter_spec, tuple)
                  else filter_spec)
    budget = budget if budget is not None else analyze_budget()
    opts = {"form": form, "s_filter_mm": s_mm, "l_filter_mm": l_mm, "outliers": outliers,
            "slope": slope}
    if _is_store(path):
        store = ZarrHeightMap(path, what="height map store")
        need = analyze_memory(store.shape, holes=True, **opts)
        whole_only = windowed_refusal(form=form, s_filter_mm=s_mm, l_filter_mm=l_mm,
                                      outliers=outliers, x3p=x3p)
        if need > budget[0] or (need > STORE_WHOLE_MAP_BYTES and whole_only is None):
            return _analyze_windowed(store, path, out, need=need, budget=budget, channel=channel,
                                     x3p=x3p, overwrite=overwrite, t0=t0, **opts)
    try:
        m = read_surface(path, channel=channel, bytes_per_value=analyze_memory_per_point(
            holes=True, **opts), purpose="analyse")
    except MemoryBudgetError as err:
        raise MemoryBudgetError(_without_scene_advice(str(err))) from None
    t_read = time.perf_counter() - t0
    a = analyze_map(m, outlier_sigma=outlier_sigma, budget=budget, **opts)
    files = {"metrics.json": "these metrics",
             "height.png": "evaluated surface: heights in nm (colour bar), x and y in mm, "
                           "scale bar"}
    if x3p:
        files["height.x3p"] = ("evaluated surface (outliers left out if asked, form removed, "
                               "filtered): ISO 25178-72, metres in the file")
    metrics = analysis_metrics(a.metrics, path=path, files=files, timing={})
    metrics["periods"] = _map_periods(a.height, m.pixel, form)
    _log_warnings(metrics)
    title = _title(path, m.pixel, metrics["areal"], metrics, form=form, s_mm=s_mm, l_mm=l_mm,
                   outliers=outliers)
    with atomic_output_dir(out, overwrite=overwrite, command="analyze", inputs=(path,)) as tmp:
        tmp = Path(tmp)
        # (analyze_map keeps the evaluated height)
        save_height_png(tmp / "height.png", cast(np.ndarray, a.height) * MM_TO_NM, extent=m.extent,
                        title=title, label="height (nm)")
        if x3p:
            comment = json.dumps({"render_inspect": __version__, "command": "analyze",
                                  "source": str(path.name), "form": form,
                                  "filter_mm": [s_mm, l_mm], "outliers": outliers,
                                  "units": "x, y, z in metres (ISO 25178-72)"})
            write_x3p(tmp / "height.x3p", cast(np.ndarray, a.height), pixel=m.pixel, origin=m.origin,
                      comment=comment)
        metrics["timing_s"] = {"read": t_read, "total": time.perf_counter() - t0}
        write_metrics(tmp, metrics)
    return json_safe(metrics)


def _map_periods(z, pixel, form) -> dict | None:
    """The dominant period of an analysed map and its harmonics (square pixels only); a
    spectrum that rises to the longest period searched after a plane is removed asks for
    ``--form poly2``."""
    if not math.isclose(pixel[0], pixel[1], rel_tol=1e-6):
        return None
    p = map_periods(z, pixel=pixel[0])
    dom = {"period_mm": p.get("period_mm"), "fraction_of_variance": p.get("fraction"),
           "harmonics": p.get("harmonics", [])}
    if p.get("note"):
        dom["note"] = p["note"]
        if (p.get("rises_to") == "longest" or "longer than the longest" in p["note"]) \
                and form in ("none", "plane"):
            dom["note"] += "; try --form poly2"
    out = {"dominant": dom,
           "method": "radially averaged Hann-windowed 2-D periodogram, the strongest peak (a "
                     "local maximum) between 4 pixels and a quarter of the map's side; "
                     "harmonics 10x above the median"}
    if p.get("search_mm"):
        out["search_mm"] = dict(p["search_mm"])
    return out


def _log_warnings(metrics: dict) -> None:
    for w in metrics.get("warnings") or ():
        log.warning("warning: %s", w)


def _spatial_level(store: ZarrHeightMap, room: float, **opts):
    """The finest pyramid level whose analysis fits ``room`` bytes: (level, factor)."""
    for k in range(1, len(store.levels) + 1):
        shape = store.levels[k - 1]["shape"]
        if analyze_memory(shape, holes=True, **opts) <= room:
            return k, 1 << k
    return None


def _analyze_windowed(store: ZarrHeightMap, path: Path, out, *, need: float, budget, channel,
                      x3p: bool, overwrite: bool, t0: float, form, s_filter_mm, l_filter_mm,
                      outliers, slope) -> dict:
    """A store too large for the budget, window by window (see the module notes)."""
    limit, source = budget
    ny, nx = store.shape
    what = f"analysing {path.name} ({ny} x {nx} points)"
    why = windowed_refusal(form=form, s_filter_mm=s_filter_mm, l_filter_mm=l_filter_mm,
                           outliers=outliers, x3p=x3p)
    if why:
        raise MemoryBudgetError(
            f"{what} with {why} needs the whole map in memory, about {format_bytes(need)}, more "
            f"than the memory budget of {format_bytes(limit)} ({source}); without these options "
            f"a store is analysed window by window (--form none, plane or poly2, no --filter, "
            f"--outliers or --x3p), or analyse a part of the map (a smaller store)")
    channel = channel or "machined"
    per_row = nx * band_bytes_per_point(form)
    overhead = 2 * store.chunk_bytes * max(1, -(-nx // store.chunk_shape[1]))
    cy = store.chunk_shape[0]
    rows = int((_BAND_SHARE * limit - overhead) // per_row)
    rows = min(rows, max(int(WINDOW_BYTES // per_row), 2), ny)
    if rows >= cy:
        rows -= rows % cy  # whole chunks: each is decoded once
    elif rows >= 2:
        # a row of chunks is more than a band may hold (a wide map): bands of about an
        # equal share of a row of chunks (its chunks are decoded once per band)
        rows = max(cy // -(-cy // rows), 2)
    check_memory(max(rows, 2) * per_row + overhead, budget=budget,
                 what=f"{what} window by window (bands of {max(rows, 2)} rows of {nx} points)",
                 hint="the map's rows are too long for the budget")
    opts = {"form": form, "s_filter_mm": None, "l_filter_mm": None, "outliers": "none",
            "slope": slope}
    lv = _spatial_level(store, min((1.0 - _BAND_SHARE) * limit - overhead, SPATIAL_BYTES), **opts)
    log.info("%s window by window: %d bands of %d rows (the whole map would need about %s, "
             "more than %s)", what, math.ceil(ny / rows), rows, format_bytes(need),
             f"the budget of {format_bytes(limit)}" if need > limit else
             f"the {format_bytes(STORE_WHOLE_MAP_BYTES)} a store is analysed whole within")
    spatial = None
    if lv is not None:
        k, f = lv
        zc = store.read(channel, level=k)
        spatial = (zc, f, f"pyramid level {k} of the store (area means of {f} x {f} pixels, "
                          f"{zc.shape[0]} x {zc.shape[1]} points)")
    t_read = time.perf_counter() - t0
    n_bands = math.ceil(ny / rows)
    with task(f"analyse {ny * nx:,} points in {n_bands} bands (2 passes)",
              total=2 * n_bands) as step:
        done = [0]

        def progress(d, total):
            step.advance(d - done[0])
            done[0] = d

        a = analyze_bands(lambda r0, r1: store.rows(channel, r0, r1), store.shape,
                          pixel=store.pixel, origin=store.origin, form=form, slope=slope,
                          band_rows=rows, spatial=spatial, progress=progress,
                          source={"reader": "zarr", "format": "zarr", "channel": channel,
                                  "format_name": "height-map store (.zarr)",
                                  "instrument": "none: a height map simulated by render_inspect",
                                  "units_in_file": {"lateral": "mm", "vertical": "mm"},
                                  "units_in_file_from": "the store: mm"})
    files = {"metrics.json": "these metrics",
             "height.png": ("evaluated surface seen at the pyramid level of Sal and Str (area "
                            "means): heights in nm, x and y in mm" if spatial is not None else
                            "not written: the store has no pyramid level that fits")}
    metrics = analysis_metrics(a.metrics, path=path, files=files, timing={})
    metrics["windowed"]["memory_whole_map_bytes"] = int(need)
    metrics["windowed"]["budget_bytes"] = int(limit)
    metrics["windowed"]["whole_map_limit_bytes"] = int(min(limit, STORE_WHOLE_MAP_BYTES))
    if a.height is not None:
        f = cast(tuple, spatial)[1]  # (a height is kept only from the spatial level)
        metrics["periods"] = _map_periods(a.height, (store.pixel * f, store.pixel * f), form)
        if metrics["periods"] is not None:
            metrics["periods"]["seen_at_mm"] = store.pixel * f
    _log_warnings(metrics)
    with atomic_output_dir(out, overwrite=overwrite, command="analyze", inputs=(path,)) as tmp:
        tmp = Path(tmp)
        if a.height is not None:
            f = cast(tuple, spatial)[1]
            p = store.pixel
            ox, oy = store.origin
            extent = (ox - p / 2, ox + p * (nx - 0.5), oy - p / 2, oy + p * (ny - 0.5))
            title = _title(path, (p, p), metrics["areal"], metrics, form=form, s_mm=None,
                           l_mm=None, outliers="none",
                           note=f" (window by window; picture at {p * f * MM_TO_UM:.4g} um)")
            save_height_png(tmp / "height.png", a.height * MM_TO_NM, extent=extent, title=title,
                            label="height (nm)")
        else:
            metrics["files"].pop("height.png")
        metrics["timing_s"] = {"read_levels": t_read, "total": time.perf_counter() - t0}
        write_metrics(tmp, metrics)
    return json_safe(metrics)
