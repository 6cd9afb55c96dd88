"""Choosing the S- and L-filter of a waviness map from what the part is made of.

A machined surface carries three scales: the tool marks (the feed scallop of period
``f`` for turning), the waviness the process leaves (overcut, servo errors, vibration:
on the scale of the design's own features) and the form.  The waviness map keeps the
middle one (ISO 16610-61 Gaussian filters, ISO 25178-3 S-F/S-L surfaces):

* S-filter (removes the short wavelengths): the nesting index ``lambda_s`` is the
  smallest that leaves less than ``leak_nm`` of the marks' first harmonic.  A scallop of
  circular arcs (nose radius ``Rc``, period ``f``) has ``PV = Rc - sqrt(Rc^2 - f^2/4)``
  and a first harmonic of amplitude ``a1 ~ 4 PV / pi^2`` (the Fourier series of the
  parabola it is close to); the Gaussian passes ``exp(-pi (alpha lambda_s / f)^2)`` of
  it, so ``lambda_s = f sqrt(ln(a1 / leak) / pi) / alpha`` (never below ``f``, where the
  filter passes half).  Marks finer than two pixels are not resolved by the map: no
  S-filter.
* L-filter (removes the long wavelengths): ``lambda_c = 2.5 w`` for the waviness of
  interest ``w`` (the design's feature size: sinusoid wavelength, lenslet pitch,
  element size), which passes 98.7 % of ``w``.  When ``lambda_c`` is longer than the
  window the L-filter would do nothing but bend the edges: the form is removed as a
  plane only.
* Edges: ``"cut"`` drops ``max(lambda_s, lambda_c) / 2`` on every side (where the
  weighting function reaches outside the map); when that would leave less than half the
  window's shorter side, the map is extended by its mirror image instead
  (``"mirror"``).  Either way the choice is returned and stated in the report.

What the part is made of comes from the process (its
:class:`~render_inspect.core.marks.ToolMarks`: period, nose radius, whether the marks
are a feed scallop) and from the design (its feature size), never from asking which
process or design kind it is.  The same marks set the diffuse renderer's texture
(:func:`render_marks`) and the roughness a process leaves on its own
(:func:`expected_sq_mm`).
"""

from __future__ import annotations

from typing import Any, Protocol
import numpy as np
import math

from ..core.errors import InputError, check_positive
from ..core.marks import ToolMarks
from ..core.units import MM_TO_NM, MM_TO_UM
from ._checks import kinematic_sq_mm
from ._filters import GAUSSIAN_ALPHA, gaussian_transmission, l_filter, remove_form, s_filter

__all__ = ["waviness_filters", "scallop_pv", "L_FILTER_FACTOR", "MARK_LEAK_NM", "mark_size",
           "feature_size", "waviness_choice", "render_marks", "expected_sq_mm",
           "FINEST_RENDERED_MARKS_MM", "waviness_map"]

#: lambda_c = L_FILTER_FACTOR x the waviness of interest
L_FILTER_FACTOR = 2.5
#: what the S-filter may leave of the marks' first harmonic, nm
MARK_LEAK_NM = 0.5


def scallop_pv(period: float, nose_radius: float) -> float:
    """Peak-to-valley height (mm) of a scallop of circular arcs of radius ``nose_radius``
    spaced ``period`` apart (both mm): ``Rc - sqrt(Rc^2 - period^2 / 4)``."""
    check_positive("period", period)
    check_positive("nose_radius", nose_radius)
    h = min(period / 2.0, nose_radius)
    return float(nose_radius - math.sqrt(nose_radius ** 2 - h * h))


def waviness_filters(*, pixel: float, window_mm: tuple, mark_period: float | None = None,
                     mark_pv: float | None = None, waviness: float | None = None,
                     edges: str = "cut", leak_nm: float = MARK_LEAK_NM,
                     s_filter: float | None = None, l_filter: float | None = None) -> dict:
    """S- and L-filter nesting indices and edge handling of a waviness map.

    Parameters
    ----------
    pixel : float
        Sampling distance of the map, mm.
    window_mm : (width, height)
        Size of the map, mm.
    mark_period : float, optional
        Period of the tool marks, mm (turning: the feed per revolution).
    mark_pv : float, optional
        Peak-to-valley height of the marks, mm (:func:`scallop_pv`).
    waviness : float, optional
        The waviness of interest, mm (the design's feature size).
    edges : {"cut", "mirror"}
        Preferred edge handling (``"cut"`` falls back to ``"mirror"`` on small windows).
    leak_nm : float
        What the S-filter may leave of the marks' first harmonic, nm.
    s_filter, l_filter : float, optional
        Nesting indices set by the user (mm): used as given.

    Returns
    -------
    dict
        ``s_filter_mm``, ``l_filter_mm`` (None = not applied), ``edges``, ``cut_mm`` (the
        border dropped on every side), ``mark_transmission`` (fraction of the marks'
        first harmonic passed), ``waviness_transmission`` (of ``waviness``),
        ``chosen_from_scene`` (False when the user set both) and ``reasons`` (sentences
        for the report).
    """
    check_positive("pixel", pixel)
    if edges not in ("cut", "mirror"):
        raise InputError(f"metrology.filter_edges must be 'cut' or 'mirror', got {edges!r}")
    w_mm, h_mm = (float(v) for v in window_mm)
    side = min(w_mm, h_mm)
    reasons = []
    a1_nm = None
    if s_filter is not None:
        ls = float(s_filter)
        reasons.append(f"S-filter {_um(ls)} (metrology.s_filter)")
    elif mark_period is None:
        ls = None
        reasons.append("no S-filter: the process leaves no periodic tool marks")
    elif mark_period < 2 * pixel:
        ls = None
        reasons.append(f"no S-filter: the tool marks (period {_um(mark_period)}) are finer "
                       f"than two pixels ({_um(2 * pixel)}) and not resolved by the map")
    else:
        a1_nm = 4.0 * (mark_pv or 0.0) / math.pi ** 2 * MM_TO_NM
        ratio = math.sqrt(math.log(a1_nm / leak_nm) / math.pi) / GAUSSIAN_ALPHA \
            if a1_nm > leak_nm else 1.0
        ls = max(1.0, ratio) * mark_period
        reasons.append(f"S-filter {_um(ls)} = {ls / mark_period:.2f} x the mark period "
                       f"{_um(mark_period)}: leaves {min(leak_nm, a1_nm):.2g} nm of the marks' "
                       f"first harmonic ({a1_nm:.3g} nm)")
    if l_filter is not None:
        lc = float(l_filter)
        reasons.append(f"L-filter {_mm(lc)} (metrology.l_filter)")
    elif waviness is None:
        lc = None
        reasons.append("no L-filter: the design has no feature size to keep; form removed "
                       "as a plane")
    else:
        lc = L_FILTER_FACTOR * float(waviness)
        if lc >= side:
            reasons.append(f"no L-filter: {L_FILTER_FACTOR:g} x the waviness of interest "
                           f"({_mm(waviness)}) is {_mm(lc)}, longer than the window "
                           f"({_mm(side)}); form removed as a plane")
            lc = None
        else:
            reasons.append(f"L-filter {_mm(lc)} = {L_FILTER_FACTOR:g} x the waviness of "
                           f"interest ({_mm(waviness)}), which it passes at "
                           f"{100 * (1 - float(gaussian_transmission(waviness, lc))):.1f} %")
    if ls is not None and lc is not None and not lc > ls:
        raise InputError(f"metrology.l_filter ({lc} mm) must be > metrology.s_filter ({ls} mm)")
    longest = max([v for v in (ls, lc) if v is not None], default=0.0)
    cut = 0.0
    mode = edges
    if longest > 0 and edges == "cut":
        cut = 0.5 * longest
        if side - 2 * cut < 0.5 * side:
            mode = "mirror"
            cut = 0.0
            reasons.append(f"edges: mirrored (cutting {_mm(0.5 * longest)} on every side would "
                           f"leave less than half of the {_mm(side)} window)")
        else:
            reasons.append(f"edges: {_mm(cut)} cut on every side (half the longest nesting "
                           f"index), where the filter would reach outside the map")
    elif longest > 0:
        reasons.append("edges: the map is extended by its mirror image (metrology.filter_edges)")
    out = {"s_filter_mm": ls, "l_filter_mm": lc, "edges": mode, "cut_mm": cut,
           "mark_period_mm": mark_period, "mark_first_harmonic_nm": a1_nm,
           "mark_transmission": None if (ls is None or mark_period is None)
           else float(gaussian_transmission(mark_period, ls)),
           "waviness_mm": waviness,
           "waviness_transmission": None if waviness is None else float(
               (gaussian_transmission(waviness, ls) if ls else 1.0)
               * (1.0 - (gaussian_transmission(waviness, lc) if lc else 0.0))),
           "chosen_from_scene": not (s_filter is not None and l_filter is not None),
           "reasons": reasons}
    return out


def _um(v_mm: float) -> str:
    return f"{v_mm * MM_TO_UM:.3g} um"


def _mm(v_mm: float) -> str:
    return f"{v_mm:.3g} mm" if v_mm >= 0.1 else _um(v_mm)


# ------------------------------------------------------------------ from the scene's parts
#: linear marks finer than this (mm, half the shortest visible wavelength) are not
#: resolved by light: the diffuse renderer gets no period for them
FINEST_RENDERED_MARKS_MM = 0.2e-3


def mark_size(marks: ToolMarks | None) -> tuple[float | None, float | None]:
    """(period, peak-to-valley) of the marks, mm: a feed scallop's height from the nose
    radius (:func:`scallop_pv`), other marks' as the process states it; (None, None)
    without periodic marks."""
    if marks is None or marks.period_mm is None:
        return None, None
    if marks.scallop:
        return marks.period_mm, scallop_pv(marks.period_mm, marks.nose_radius_mm)
    return marks.period_mm, marks.pv_mm


def feature_size(design: Any) -> float | None:
    """The design's own lateral scale (mm): the waviness a process leaves on it is on
    this scale.  ``design``: the design surface, which says it
    (:meth:`~render_inspect.design.Surface.lateral_scale`: a sinusoid's wavelength, a
    lenslet pitch, an element's diameter, a compound design's feature's; None without
    one)."""
    return design.lateral_scale()


class _WavinessSettings(Protocol):
    """What :func:`waviness_choice` reads of a scene's ``[metrology]`` section."""

    @property
    def s_filter(self) -> float | None: ...
    @property
    def l_filter(self) -> float | None: ...
    @property
    def filter_edges(self) -> str: ...
    @property
    def form_removal(self) -> str: ...
    @property
    def polynomial_degree(self) -> int: ...


def waviness_choice(marks: ToolMarks | None, design: Any, metrology: _WavinessSettings, *,
                    pixel: float, window_mm: tuple[float, float]) -> dict:
    """The S/L filters, edge handling and form removal of a simulated map's waviness:
    :func:`waviness_filters` from the process's marks and the design surface's lateral
    scale (:func:`feature_size`; ``design``: the surface), with
    the ``[metrology]`` section's choices (``s_filter``, ``l_filter``, ``filter_edges``,
    ``form_removal``, ``polynomial_degree``)."""
    period, pv = mark_size(marks)
    choice = waviness_filters(pixel=pixel, window_mm=window_mm, mark_period=period, mark_pv=pv,
                              waviness=feature_size(design), edges=metrology.filter_edges,
                              s_filter=metrology.s_filter, l_filter=metrology.l_filter)
    choice["form_removal"] = metrology.form_removal if metrology.form_removal != "design" else "none"
    choice["polynomial_degree"] = int(metrology.polynomial_degree)
    return choice


def render_marks(marks: ToolMarks | None) -> dict | None:
    """The tool marks as the diffuse renderer takes them
    (:func:`~render_inspect.render.render_diffuse` ``marks``): circular feed marks about
    the spindle axis with their period and nose radius, or straight marks along the cut
    whose period is dropped when light cannot resolve it."""
    if marks is None:
        return None
    if marks.pattern == "circular":
        # circular marks are turning's feed marks: they have their period
        return {"kind": "circular", "center_mm": [float(v) for v in marks.center_mm],
                "period_mm": float(marks.period_mm),  # type: ignore[arg-type]
                "nose_radius_mm": marks.nose_radius_mm}
    period = marks.period_mm
    if period is not None and period < FINEST_RENDERED_MARKS_MM:
        period = None
    return {"kind": "linear", "direction": [float(v) for v in marks.direction],
            "period_mm": period, "nose_radius_mm": marks.nose_radius_mm}


def expected_sq_mm(marks: ToolMarks | None) -> float | None:
    """The Sq a process leaves on its own (mm): the ideal turned profile
    ``f^2 / (12 sqrt(5) R)`` of a feed scallop (:func:`kinematic_sq_mm`); None for other
    marks."""
    if marks is None or not marks.scallop or marks.period_mm is None or not marks.period_mm > 0:
        return None
    return kinematic_sq_mm(float(marks.period_mm), float(marks.nose_radius_mm))


def waviness_map(residual: np.ndarray, pixel: float, choice: dict) -> np.ndarray:
    """The waviness of a residual map (mm): the form of ``choice`` removed, then its S-
    and L-filters (:func:`waviness_choice`) with its edge handling."""
    r, _ = remove_form(residual, pixel=pixel, method=choice["form_removal"],
                       degree=choice["polynomial_degree"])
    if choice["s_filter_mm"]:
        r = s_filter(r, pixel=pixel, nesting_index=choice["s_filter_mm"], edges=choice["edges"])
    if choice["l_filter_mm"]:
        r = l_filter(r, pixel=pixel, nesting_index=choice["l_filter_mm"], edges=choice["edges"])
    return r
