"""``analyze`` of a profile (a stylus trace, an interferometer's 2-D slice): ISO 21920-2
parameters over the ISO 16610-21 filtered roughness profile, the dominant periods, a
figure, metrics.json."""

from __future__ import annotations

import time
from pathlib import Path

from ..core.units import MM_TO_UM
from .. import __version__
from ..io import atomic_output_dir, check_output_dir, json_safe, read_profile
from ..metrology import analyze_profile, parse_profile_filter
from ..report import profile_figure
from ._metrics import write_metrics

__all__ = ["run_analyze_profile", "PROFILE_FILES"]

#: files ``analyze`` writes for a profile
PROFILE_FILES = ("metrics.json", "profile.png")


def run_analyze_profile(path: str | Path, out: str | Path, *, units: str | None = None,
                        form: str = "plane", filter_spec: str | tuple | None = None,
                        outliers: str = "none", outlier_sigma: float = 3.0,
                        overwrite: bool = False) -> dict:
    """Analyse one profile file and write ``metrics.json`` and ``profile.png``.

    Parameters
    ----------
    path : str or Path
        A profile :func:`~render_inspect.io.read_profile` reads.
    units : str, optional
        ``um``, ``mm``, ``nm`` or ``POSITION,HEIGHT`` for a text file that does not state
        its units.
    form : {"none", "plane", "poly2"}
        Form removed (``plane``: a least-squares line).
    filter_spec : "S,L" text or (S, L), optional
        Gaussian cut-offs lambda_s and lambda_c in mm (ISO 16610-21); either may be
        empty for ISO 21920-3's default.
    outliers : {"none", "sigma"}
        Spikes counted either way, left out with ``sigma``.

    Returns
    -------
    dict
        The content of ``metrics.json``.
    """
    t0 = time.perf_counter()
    path = Path(path)
    check_output_dir(out, overwrite=overwrite, command="analyze", inputs=(path,))
    s_mm, l_mm = parse_profile_filter(filter_spec)
    m = read_profile(path, units=units)
    t_read = time.perf_counter() - t0
    a = analyze_profile(m.x, m.z, spacing=m.spacing, form=form, lambda_s=s_mm, lambda_c=l_mm,
                        outliers=outliers, outlier_sigma=outlier_sigma)
    metrics = dict(a["metrics"])
    # what was read, under the keys analyze gives a map (docs/formats.md)
    metrics["input"] = {"path": str(path), "reader": m.meta.get("reader"),
                        "format": m.meta.get("format"), "format_name": m.meta.get("format_name"),
                        "units_in_file": m.meta.get("units_in_file"),
                        "units_from": m.meta.get("units_from"),
                        "units_in_file_from": m.meta.get("units_in_file_from"),
                        "instrument": m.meta.get("instrument") or None,
                        "instrument_fields": m.meta.get("instrument_fields") or {},
                        "date": m.meta.get("date") or None, "label": m.meta.get("label"),
                        "n_invalid": int(m.z.size - m.n_measured),
                        "n_not_measured": int(m.z.size - m.n_measured)}
    metrics["valid_fraction"] = m.n_measured / m.z.size
    metrics["files"] = {"metrics.json": "these metrics",
                        "profile.png": "primary profile and mean line, roughness profile, power "
                                       "spectrum with the feed period, material ratio curve"}
    metrics["software_version"] = __version__
    metrics["command"] = "analyze"
    pm = metrics["profile"]
    title = (f"{path.name}: {m.n_measured} of {m.z.size} points measured, spacing "
             f"{m.spacing * MM_TO_UM:.4g} um; Ra {pm['Ra_nm']:.4g} nm, Rq {pm['Rq_nm']:.4g} nm, "
             f"Rz {pm['Rz_nm']:.4g} nm (lambda_s {metrics['filter']['lambda_s_mm'] or 0:g}, "
             f"lambda_c {metrics['filter']['lambda_c_mm']:g} mm, "
             f"{metrics['filter']['chosen_by']})")
    with atomic_output_dir(out, overwrite=overwrite, command="analyze", inputs=(path,)) as tmp:
        tmp = Path(tmp)
        (tmp / "profile.png").write_bytes(profile_figure(a["arrays"], metrics, title=title))
        metrics["timing_s"] = {"read": t_read, "total": time.perf_counter() - t0}
        write_metrics(tmp, metrics)
    return json_safe(metrics)
