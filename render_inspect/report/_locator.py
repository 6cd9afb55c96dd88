"""The comparison report's first figure (:func:`difference_figure`: where the windows lie
on the part, the true and the measured height difference, a profile across the largest
difference) and its locator panel alone (:func:`locator_figure`), drawn with the
conventions of :mod:`._figures`.

The locator draws the design over the simulated region in grey with a colour bar in the
height unit its caller gives (the design's sag: what the part's form is where the windows
lie), the part's outline and every window of the report, x and y in mm on the part."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..core.units import MM_TO_NM, MM_TO_UM
from ._figures import (_Extent, _extend, _limits, _plt, _scale_bar, _shared_bar, _to_png,
                       display_map, lowpass_map)
from ._format import fmt_quantity

__all__ = ["difference_figure", "locator_figure", "height_background"]


def height_background(z_mm: np.ndarray, extent: _Extent, what: str = "design height") -> dict:
    """A locator's ``background`` and ``background_label``: the heights ``z_mm`` (mm) in
    um, or in nm where they span less than 1 um, with the unit on the colour bar."""
    z = np.asarray(z_mm, dtype=np.float64)
    ok = np.isfinite(z)
    span_um = float(np.ptp(z[ok])) * MM_TO_UM if ok.any() else 0.0
    scale, unit = (MM_TO_NM, "nm") if span_um < 1.0 else (MM_TO_UM, "um")
    return {"background": (z * scale, extent), "background_label": f"{what} ({unit})"}


def _draw_locator(ax, loc: dict) -> None:
    """The part, the simulated region and every window of the report, in mm, over the
    ``background`` heights (with a colour bar labelled ``background_label``)."""
    from matplotlib.patches import Circle, Rectangle

    part = loc.get("part") or {}
    bg = loc.get("background")
    if bg is not None:
        im = ax.imshow(display_map(bg[0], 300), origin="lower", extent=bg[1], cmap="Greys",
                       interpolation="nearest", alpha=0.8)
        cb = ax.figure.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
        cb.set_label(loc.get("background_label") or "height")
    if part.get("shape") == "disc":
        cx, cy = part["center"]
        ax.add_patch(Circle((cx, cy), part["radius"], fill=False, color="0.3", lw=1.2))
        ax.plot([cx], [cy], marker="+", color="0.3", ms=8)
    elif part.get("shape") == "rect":
        x0, y0, x1, y1 = part["rect"]
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, color="0.3", lw=1.2))
    handles = []
    for name, rect, color, style in loc.get("windows", []):
        x0, y0, x1, y1 = rect
        p = Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, color=color, lw=1.6, ls=style,
                      label=name)
        ax.add_patch(p)
        handles.append(p)
    lims = loc.get("limits")
    if lims is not None:
        ax.set_xlim(lims[0], lims[1])
        ax.set_ylim(lims[2], lims[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    if handles:
        ax.legend(handles=handles, fontsize=7, loc="lower left", bbox_to_anchor=(0.0, 1.0),
                  framealpha=0.9, borderaxespad=0.3)


def locator_figure(locator: dict, *, dpi: int = 100) -> bytes:
    """PNG bytes of the locator panel alone (where the windows are): the figure the
    report shows instead of the difference when the two variants are identical."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.0, 4.6), dpi=dpi, layout="constrained")
    _draw_locator(ax, locator)
    return _to_png(fig)


def difference_figure(*, names: Sequence[str], locator: dict, true_diff: np.ndarray | None,
                      true_extent: _Extent, measured_diff: np.ndarray | None,
                      measured_extent: _Extent, profile: dict, title: str = "", dpi: int = 100,
                      panel_labels: Sequence[str] = ("true (simulated)", "measured by the virtual instrument"),
                      lowpass_mm: float | None = None) -> bytes:
    """The report's first figure: what differs between the two variants.

    Four panels: where every window lies on the part (``locator``: ``part``,
    ``windows`` = [(name, (x0, y0, x1, y1), colour, line style)], ``limits``, optional
    ``background`` = (map, extent) with ``background_label`` (what and its unit, on its
    colour bar: :func:`height_background`) and ``inset`` = a second locator dict drawn
    small),
    the true height difference (machined a - machined b, nm) over the common window, the
    difference of what the virtual instrument measures (nm) over the same window with
    the same colour scale, and a profile across the largest difference (``profile``:
    ``s`` (mm), ``true`` (nm), ``measured`` (nm, may hold NaN), ``a`` and ``b`` (true
    residuals, nm), ``line`` = ((x0, y0), (x1, y1)) mm, ``axis`` label, optional
    ``true_levelled`` (nm, on ``s_measured``: the truth with the measurement's form removal)
    and ``measured_label``); ``panel_labels`` name the two maps.  ``lowpass_mm``: the two maps
    are drawn through :func:`lowpass_map` of that nesting index (tool marks the simulation
    does not resolve would alias into false stripes); the figure says so."""
    plt = _plt()
    if lowpass_mm:
        true_diff, measured_diff = (
            None if d is None else lowpass_map(d, (e[1] - e[0]) / np.shape(d)[1], lowpass_mm)
            for d, e in ((true_diff, true_extent), (measured_diff, measured_extent)))
    fig = plt.figure(figsize=(19.0, 4.8), dpi=dpi, layout="constrained")
    gs = fig.add_gridspec(1, 4, width_ratios=[1.0, 1.05, 1.05, 1.35])
    ax0 = fig.add_subplot(gs[0, 0])
    _draw_locator(ax0, locator)
    inset = locator.get("inset")
    if inset is not None:
        ia = ax0.inset_axes([0.62, 0.02, 0.36, 0.36])
        _draw_locator(ia, {**inset, "windows": inset.get("windows", [])})
        ia.set_xticks([])
        ia.set_yticks([])
        ia.set_xlabel("")
        ia.set_ylabel("")
        leg = ia.get_legend()
        if leg is not None:
            leg.remove()
        ia.set_title("whole part", fontsize=7, pad=1)
    # one colour scale, set by the true difference when there is one: a measurement's
    # slips (a fringe order at a steep flank) are clipped (arrows) instead of washing the
    # truth out
    vmin, vmax, _ = _limits([true_diff if true_diff is not None else measured_diff], True, 0.5)
    bar = _shared_bar([e for d, e in ((true_diff, true_extent), (measured_diff, measured_extent))
                       if d is not None])
    a, b = names
    line = profile.get("line")
    for k, (data, ext, what) in enumerate(((true_diff, true_extent, panel_labels[0]),
                                           (measured_diff, measured_extent, panel_labels[1]))):
        ax = fig.add_subplot(gs[0, 1 + k])
        if data is None:
            ax.text(0.5, 0.5, "not available", ha="center", va="center", transform=ax.transAxes)
            ax.set_axis_off()
            continue
        im = ax.imshow(display_map(data), origin="lower", extent=ext, cmap="RdBu_r",
                       vmin=vmin, vmax=vmax, interpolation="nearest")
        d = np.asarray(data, dtype=np.float64)
        d = d[np.isfinite(d)]
        stat = (f"rms {fmt_quantity(float(np.sqrt(np.mean(d * d))), 'nm')}, "
                f"PV {fmt_quantity(float(np.ptp(d)), 'nm')}") if d.size else "no data"
        if lowpass_mm:
            stat += f", low-passed at {fmt_quantity(lowpass_mm * MM_TO_UM, 'um')}"
        ax.set_title(f"{a} - {b}: {what}\n{stat}", fontsize=10)
        ax.set_xlabel("x (mm)")
        if k == 0:
            ax.set_ylabel("y (mm)")
        cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04, extend=_extend(data, vmin, vmax))
        cb.set_label("height difference (nm)")
        _scale_bar(ax, ext[1] - ext[0], length=bar)
        if line is not None:
            ax.plot([line[0][0], line[1][0]], [line[0][1], line[1][1]], color="k", lw=0.9,
                    ls="--")
    ax = fig.add_subplot(gs[0, 3])
    s = np.asarray(profile["s"])
    ax.plot(s, profile["true"], color="k", lw=1.6, label=f"{a} - {b} (true)")
    if profile.get("true_levelled") is not None and np.isfinite(profile["true_levelled"]).any():
        ax.plot(profile["s_measured"], profile["true_levelled"], color="0.45", lw=1.0, ls=":",
                label=f"{a} - {b} (true, same form removed)")
    if profile.get("measured") is not None and np.isfinite(profile["measured"]).any():
        ax.plot(profile["s_measured"], profile["measured"], color="C3", lw=1.2, ls="--",
                label=f"{a} - {b} ({profile.get('measured_label', 'measured')})")
    ax.axhline(0, color="0.5", lw=0.5)
    ax.set_xlabel(profile.get("axis", "position along the line (mm)"))
    ax.set_ylabel("height difference (nm)")
    ax.set_title(profile.get("title", "profile across the largest difference"), fontsize=10)
    ax.grid(alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    if profile.get("a") is not None or profile.get("b") is not None:
        # the residuals themselves can be far larger than their difference: own axis
        ax2 = ax.twinx()
        for key, name, color in (("a", a, "C0"), ("b", b, "C1")):
            if profile.get(key) is not None:
                ax2.plot(s, profile[key], color=color, lw=0.7, alpha=0.6,
                         label=f"{name}: machined - design (right axis)")
        ax2.set_ylabel("machined - design (nm)", color="0.35")
        ax2.tick_params(axis="y", colors="0.35")
        h2, l2 = ax2.get_legend_handles_labels()
        handles, labels = handles + h2, labels + l2
        ax.set_zorder(ax2.get_zorder() + 1)
        ax.patch.set_visible(False)
    ax.legend(handles, labels, fontsize=7, loc="best", framealpha=0.85)
    if title:
        fig.suptitle(title, fontsize=11)
    return _to_png(fig)
