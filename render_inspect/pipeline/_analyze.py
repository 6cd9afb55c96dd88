"""``analyze``: one height map file (measured or simulated) -> ISO 25178-2 parameters,
a height map picture and, on request, an X3P of the evaluated surface."""

from __future__ import annotations

import json
import time
from pathlib import Path

from .. import __version__
from ..core.errors import InputError
from ..core.units import MM_TO_NM, MM_TO_UM
from ..io import atomic_output_dir, check_output_dir, json_safe, read_surface, write_x3p
from ..metrology import FORMS, OUTLIER_METHODS, analyze_map, parse_filter
from ..report import save_height_png
from ._metrics import analysis_metrics, write_metrics

__all__ = ["run_analyze", "ANALYZE_FILES"]

#: Files ``analyze`` writes into its output folder.
ANALYZE_FILES = ("metrics.json", "height.png", "height.x3p")


def run_analyze(path, out, *, form: str = "plane", filter_spec: str | tuple | None = None,
                outliers: str = "none", outlier_sigma: float = 3.0, slope: str = "forward",
                x3p: bool = False, channel: str | None = None, overwrite: bool = False) -> dict:
    """Analyse one height map file and write the results.

    Parameters
    ----------
    path : str or Path
        Any file :func:`render_inspect.io.read_surface` reads (instrument formats, X3P,
        our ``heightmap.exr`` - channel ``machined`` unless ``channel`` says otherwise).
    out : str or Path
        Output folder: checked before the file is read, replaced as a whole when the
        results are complete (:func:`~render_inspect.io.atomic_output_dir`).
    form : {"none", "plane", "poly2", "sphere"}
        Form removed before the parameters (``none``: the mean only).
    filter_spec : "S,L" text or (S, L), optional
        ISO 16610-61 Gaussian nesting indices in mm; either may be empty / None.
    outliers : {"none", "sigma"}
        ``sigma`` leaves the second-difference ``outlier_sigma``-sigma outliers out.
    slope : {"forward", "central"}
        Derivative estimator of Sdq and Sdr.
    x3p : bool
        Also write ``height.x3p``: the evaluated surface (form removed, filtered; metres in
        the file as ISO 25178-72 requires).
    overwrite : bool
        Replace ``out`` even if render_inspect did not write it.

    Returns
    -------
    dict
        The content of ``metrics.json``: :func:`render_inspect.metrology.analyze_map`'s
        metrics plus ``input``, ``files``, ``software_version``, ``timing_s``.
    """
    t0 = time.perf_counter()
    check_output_dir(out, overwrite=overwrite, command="analyze")
    if form not in FORMS:
        raise InputError(f"--form must be one of {', '.join(FORMS)}, got {form!r}")
    if outliers not in OUTLIER_METHODS:
        raise InputError(f"--outliers must be one of {', '.join(OUTLIER_METHODS)}, got {outliers!r}")
    s_mm, l_mm = (parse_filter(filter_spec) if not isinstance(filter_spec, tuple)
                  else filter_spec)
    m = read_surface(path, channel=channel)
    t_read = time.perf_counter() - t0
    a = analyze_map(m, form=form, s_filter_mm=s_mm, l_filter_mm=l_mm, outliers=outliers,
                    outlier_sigma=outlier_sigma, slope=slope)
    files = {"metrics.json": "these metrics",
             "height.png": "evaluated surface: heights in nm (colour bar), x and y in mm, "
                           "scale bar"}
    if x3p:
        files["height.x3p"] = ("evaluated surface (outliers left out if asked, form removed, "
                               "filtered): ISO 25178-72, metres in the file")
    metrics = analysis_metrics(a.metrics, path=path, files=files, timing={})
    ar = metrics["areal"]
    parts = [f"form {form}"]
    if s_mm:
        parts.append(f"S {s_mm:g} mm")
    if l_mm:
        parts.append(f"L {l_mm:g} mm")
    if outliers != "none":
        parts.append(f"{metrics['outliers']['count']} outliers left out")
    title = (f"{Path(path).name}: {', '.join(parts)}\nSq {ar['Sq_nm']:.4g} nm, Sa "
             f"{ar['Sa_nm']:.4g} nm, Sz {ar['Sz_nm']:.4g} nm; pixel "
             f"{m.pixel[0] * MM_TO_UM:.4g} x {m.pixel[1] * MM_TO_UM:.4g} um")
    with atomic_output_dir(out, overwrite=overwrite, command="analyze") as tmp:
        tmp = Path(tmp)
        save_height_png(tmp / "height.png", a.height * MM_TO_NM, extent=m.extent, title=title,
                        label="height (nm)")
        if x3p:
            comment = json.dumps({"render_inspect": __version__, "command": "analyze",
                                  "source": str(Path(path).name), "form": form,
                                  "filter_mm": [s_mm, l_mm], "outliers": outliers,
                                  "units": "x, y, z in metres (ISO 25178-72)"})
            write_x3p(tmp / "height.x3p", a.height, pixel=m.pixel, origin=m.origin,
                      comment=comment)
        metrics["timing_s"] = {"read": t_read, "total": time.perf_counter() - t0}
        write_metrics(tmp, metrics)
    return json_safe(metrics)
