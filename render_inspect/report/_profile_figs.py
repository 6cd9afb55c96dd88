"""Figures of a measured profile: the primary profile with its mean line, the roughness
profile over the evaluation length, the power spectrum with the feed period and its
harmonics, the material ratio curve; and the overlay of measured, simulated-measured and
true profiles along one line."""

from __future__ import annotations

from collections.abc import Sequence
import textwrap
from typing import Any

import numpy as np

from ..core.units import MM_TO_NM, MM_TO_UM
from ._figures import _plt, _to_png
from ._format import fmt_number, fmt_quantity

__all__ = ["period_text", "profile_figure", "profile_overlay_figure", "profile_summary"]


def _um(period_mm: float | None) -> str:
    return "none" if not period_mm else f"{period_mm * MM_TO_UM:.4g} um"


def period_text(dom: dict | None) -> str:
    """A dominant period (``metrics.json``'s ``periods.dominant``) for a summary: the
    period and the share of the variance it holds, or none, with why where the spectrum
    says (it rises to an end of the range searched)."""
    dom = dom or {}
    p, note = dom.get("period_mm"), dom.get("note")
    if not p:
        return "none" + (f": {note}" if note else "")
    frac = dom.get("fraction_of_variance")
    text = fmt_quantity(p * MM_TO_UM, "um")
    if frac is not None:
        text += f" ({100 * frac:.3g} % of the variance)"
    return text + (f"; {note}" if note else "")


def profile_summary(metrics: dict) -> list[tuple[str, str]]:
    """The headline numbers of a profile's ``metrics.json`` (``analyze``): (quantity, text)
    rows."""
    p = metrics.get("profile", {})
    f = metrics.get("filter", {})
    per = metrics.get("periods") or {}
    ta = per.get("through_axis")
    out = metrics.get("outliers", {})
    n, n_ok = metrics.get("n_points"), metrics.get("n_measured")
    bad = (f"{n - n_ok:,} invalid ({100 * (n - n_ok) / n:.1f} %)"
           if isinstance(n, int) and isinstance(n_ok, int) and n else "invalid points n/a")
    # (what an areal map's "map" row says: points, sampling, extent, invalid points; four
    # significant figures, the spacing as the file gives it)
    rows = [("profile", f"{n} points, spacing {metrics.get('spacing_mm', 0) * MM_TO_UM:.4g} um, "
                        f"length {metrics.get('length_mm', 0):.4g} mm; {bad}"),
            ("filter", f"lambda_s {f.get('lambda_s_mm') or 0:g} mm, lambda_c "
                       f"{f.get('lambda_c_mm'):g} mm ({f.get('chosen_by')})"),
            ("Ra, Rq", f"{fmt_quantity(p.get('Ra_nm'), 'nm')}, {fmt_quantity(p.get('Rq_nm'), 'nm')}"),
            ("Rp, Rv, Rz, Rt", ", ".join(fmt_quantity(p.get(k), "nm")
                                        for k in ("Rp_nm", "Rv_nm", "Rz_nm", "Rt_nm"))),
            ("Rsk, Rku, Rdq", f"{fmt_number(p.get('Rsk'))}, {fmt_number(p.get('Rku'))}, "
                              f"{fmt_number(p.get('Rdq'))}"),
            ("RSm", fmt_quantity((p.get("RSm_mm") or 0) * MM_TO_UM, "um") if p.get("RSm_mm")
             else "n/a"),
            ("dominant period", period_text(per.get("dominant")))]
    if ta:
        rows.append(("through the axis", f"centre {ta['centre_mm']:.4g} mm; period left "
                     f"{_um((ta.get('left') or {}).get('period_mm'))}, right "
                     f"{_um((ta.get('right') or {}).get('period_mm'))}"))
    elif (per.get("mirror") or {}).get("why_not_through_axis"):
        rows.append(("through the axis", "no: " + per["mirror"]["why_not_through_axis"]))
    rows.append(("spikes", f"{out.get('count')} " + ("left out" if out.get("left_out") else "kept")))
    return rows


def profile_figure(arrays: dict, metrics: dict, *, title: str = "", dpi: int = 90) -> bytes:
    """Four panels of one analysed profile
    (:func:`~render_inspect.metrology.analyze_profile`'s ``arrays`` and ``metrics``)."""
    plt = _plt()
    x = np.asarray(arrays["x"])
    p = np.asarray(arrays["primary"]) * MM_TO_NM
    w = np.asarray(arrays["waviness"]) * MM_TO_NM
    r = np.asarray(arrays["roughness"]) * MM_TO_NM
    ev = np.asarray(arrays["evaluate"], dtype=bool)
    f = metrics["filter"]
    pm = metrics["profile"]
    fig, axes = plt.subplots(2, 2, figsize=(11, 6.6), dpi=dpi,
                             gridspec_kw={"width_ratios": [2.2, 1]})
    ax = axes[0, 0]
    ax.plot(x, p, lw=0.8, color="0.2", label="primary (form removed, lambda_s)")
    ax.plot(x, w, lw=1.4, color="tab:orange", label=f"mean line (lambda_c {f['lambda_c_mm']:g} mm)")
    spikes = np.asarray(arrays.get("spikes", np.zeros(x.size, bool)), dtype=bool)
    if spikes.any():
        ax.plot(x[spikes], p[spikes], "x", color="tab:red", ms=5,
                label=f"spikes ({int(spikes.sum())})")
    ta = (metrics.get("periods") or {}).get("through_axis")
    if ta:
        ax.axvline(ta["centre_mm"], color="tab:purple", lw=1, ls="--",
                   label=f"mirror centre {ta['centre_mm']:.4g} mm")
    ax.set_ylabel("height (nm)")
    ax.set_xlabel("position (mm)")
    ax.legend(fontsize=7, loc="best")
    ax.grid(alpha=0.3)
    ax.set_title("primary profile", fontsize=10)
    ax = axes[1, 0]
    ax.plot(x, np.where(ev, r, np.nan), lw=0.8, color="tab:blue")
    ax.plot(x, np.where(ev, np.nan, r), lw=0.6, color="0.7")
    ax.axhline(0, color="0.3", lw=0.6)
    ax.set_xlabel("position (mm)")
    ax.set_ylabel("roughness (nm)")
    ax.grid(alpha=0.3)
    ax.set_title(f"roughness profile: Ra {pm['Ra_nm']:.4g} nm, Rz {pm['Rz_nm']:.4g} nm, "
                 f"Rt {pm['Rt_nm']:.4g} nm over {metrics['evaluation_length_mm']:.4g} mm "
                 f"(grey: ends left out)", fontsize=9)
    ax = axes[0, 1]
    ok = np.isfinite(p)
    pf = np.interp(np.arange(p.size), np.flatnonzero(ok), p[ok])
    spec = np.abs(np.fft.rfft((pf - pf.mean()) * np.hanning(pf.size))) ** 2
    fr = np.fft.rfftfreq(pf.size, d=metrics["spacing_mm"])
    ax.loglog(1.0 / fr[1:], spec[1:] / spec[1:].max(), lw=0.8)
    dom = metrics["periods"]["dominant"]
    if dom.get("period_mm"):
        ax.axvline(dom["period_mm"], color="tab:red", lw=1,
                   label=f"period {dom['period_mm'] * MM_TO_UM:.4g} um")
        for h in dom["harmonics"][:4]:
            ax.axvline(h["period_mm"], color="tab:red", lw=0.6, ls=":")
        ax.legend(fontsize=7)
    if dom.get("note"):
        ax.text(0.02, 0.02, textwrap.fill(("no period: " if not dom.get("period_mm") else "")
                                          + dom["note"], width=48),
                transform=ax.transAxes, fontsize=6.5, va="bottom", ha="left", color="0.25")
    ax.set_xlabel("period (mm)")
    ax.set_ylabel("power (relative)")
    ax.grid(alpha=0.3, which="both")
    ax.set_title("power spectrum (dotted: harmonics)", fontsize=10)
    ax = axes[1, 1]
    mr = metrics["material_ratio"]
    ax.plot(mr["ratio_percent"], mr["depth_nm"], lw=1.2)
    ax.invert_yaxis()
    ax.set_xlabel("material ratio Rmr (%)")
    ax.set_ylabel("depth below the highest peak (nm)")
    ax.grid(alpha=0.3)
    ax.set_title("material ratio curve", fontsize=10)
    if title:
        fit_suptitle(fig, title, fontsize=10)
    return _to_png(fig, tight_layout=True)


def fit_suptitle(fig: Any, title: str, *, fontsize: float = 10, margin: float = 0.96) -> Any:
    """``fig.suptitle(title)`` wrapped at word boundaries onto as many lines as it takes
    to fit ``margin`` of the figure's width (as drawn); returns the title's Text."""
    text = fig.suptitle(title, fontsize=fontsize)
    renderer = fig.canvas.get_renderer()
    room = margin * fig.bbox.width
    width = text.get_window_extent(renderer).width
    chars = len(title)
    while width > room and chars > 20:
        chars = max(20, int(chars * room / width) - 1)
        text.set_text(textwrap.fill(title, width=chars, break_long_words=False))
        width = text.get_window_extent(renderer).width
    return text


def profile_overlay_figure(series: Sequence[dict], *, title: str = "", dpi: int = 90) -> bytes:
    """Profiles along one line overlaid: ``series`` = list of dict(``s`` (mm), ``z`` (mm),
    ``label``)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(11, 3.8), dpi=dpi)
    styles = [{"lw": 1.0, "color": "0.15"}, {"lw": 1.4, "color": "tab:blue", "alpha": 0.9},
              {"lw": 0.8, "color": "tab:orange", "ls": "--", "alpha": 0.9}]
    for srs, st in zip(series, styles * 3):
        ax.plot(np.asarray(srs["s"]), np.asarray(srs["z"]) * MM_TO_NM, label=srs["label"], **st)
    ax.set_xlabel("position along the line (mm)")
    ax.set_ylabel("height (nm)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title, fontsize=10)
    return _to_png(fig, tight_layout=True)
