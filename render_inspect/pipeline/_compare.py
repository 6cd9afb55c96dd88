"""``compare``: two variants of a scene through the whole chain, and what differs.

The pair is the one that means something for the scene's process kind (its ``variants``
hook: compensation on/off for turning, servo lag on/off for tool-servo turning,
vibration on/off for sculpturing, RCSE against the conventional path), or any scene key
with two values (``--vary key=a,b``).  For each variant (same camera, same seed):
simulate the machined surface, render the virtual interferometer and the diffuse-light
views, retrieve the height from the frames (what the instrument reports) and
characterise everything.  The windows are shared: the interferometer's field, the micro
diffuse view and the first figure's maps all cover one common window, placed where the
two variants differ most.  Files: both variant folders, the figures, ``metrics.json``
and a self-contained ``report.html`` whose first figure is the difference.
"""

from __future__ import annotations

import json
import logging
import math
import re
import time
import tomllib
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import ndimage

from .. import __version__
from ..core.errors import InputError
from ..core.progress import task
from ..design import make_surface
from ..instruments import interferometer_geometry, render_interferogram
from ..io import (
    atomic_output_dir,
    check_output_dir,
    atomic_write_bytes,
    atomic_write_text,
    json_safe,
    read_surface,
    save_map_png,
    write_heightmap_exr,
    write_json,
    write_toolpath_npz,
)
from ..metrology import (
    areal_parameters,
    characterise_map,
    compare_measured,
    extract_section,
    kinematic_sq_mm,
    l_filter,
    remove_form,
    s_filter,
    scallop_pv,
    waviness_filters,
)
from ..processes import Variant, VariantPair, process_of
from ..render import mitsuba_variant
from ..report import _figures as F
from ..report import axis_motion_figure, build_page, fmt_quantity, locator_figure, nice_length
from ..scene import apply_overrides, scene_from_dict
from ._measure import measure_and_evaluate, measurement_outputs
from ._render import (
    diffuse_caption,
    check_render_limits,
    interferogram_summary,
    part_outline,
    render_diffuse_views,
    write_diffuse_outputs,
    write_interferogram_outputs,
)
from ._simulate import simulate

__all__ = ["run_compare", "check_measured", "expected_sq_mm", "compare_variants", "compare_pair",
           "compare_summary", "variant_scene", "parse_vary", "preview_render_configs",
           "common_window", "VARIANTS", "PROFILE_ANGLES_DEG",
           "COMPARE_MAX_CAMERA_PIXELS", "COMPARE_MAX_DIFFUSE_RESOLUTION",
           "COMPARE_MAX_DIFFUSE_SPP"]

log = logging.getLogger("render_inspect")

#: The two columns of a turning comparison (the names the compensation pair uses).
VARIANTS = ("compensated", "uncompensated")
#: Section angles of the radial profiles (seed 000 Fig. 16 shows that the overcut
#: waviness depends on the angle).
PROFILE_ANGLES_DEG = (0.0, 30.0, 60.0, 90.0)
#: Render sizes compare uses unless the scene sets them: camera pixels across the common
#: window, diffuse image size and samples per pixel.
COMPARE_MAX_CAMERA_PIXELS = 256
COMPARE_MAX_DIFFUSE_RESOLUTION = 512
COMPARE_MAX_DIFFUSE_SPP = 32
MM_TO_NM = 1e6
_NAME_OK = re.compile(r"^[A-Za-z0-9_.-]+$")


# ----------------------------------------------------------------------------- variants
def parse_vary(text: str) -> tuple[str, tuple]:
    """``"key=a,b"`` -> ``(key, (a, b))`` with TOML values (``process.compensation=z,none``,
    ``tool.nose_radius=0.5,0.25``, ``simulation.region=[0,0,1,1],[0,0,2,2]``).

    Raises
    ------
    InputError
        Not of the form key=a,b with exactly two values.
    """
    if "=" not in text:
        raise InputError(f"--vary expects section.key=a,b (two values), received {text!r}")
    key, rest = text.split("=", 1)
    key = key.strip()
    if not key or not all(key.split(".")):
        raise InputError(f"--vary key must be a dotted path like process.compensation, received {key!r}")
    parts, depth, cur, quote = [], 0, "", None
    for ch in rest:
        if quote:
            cur += ch
            if ch == quote:
                quote = None
            continue
        if ch in "'\"":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    parts.append(cur)
    parts = [p.strip() for p in parts]
    if len(parts) != 2 or not all(parts):
        raise InputError(f"--vary {key} needs exactly two values separated by a comma, "
                         f"received {rest!r}")
    values = []
    for p in parts:
        try:
            values.append(tomllib.loads(f"v = {p}")["v"])
        except tomllib.TOMLDecodeError:
            values.append(p)  # a bare word is a string, as with --set
    return key, tuple(values)


def _slug(text: str) -> str:
    s = re.sub(r"[^A-Za-z0-9_.-]+", "_", str(text)).strip("_")
    return s[:60] or "value"


def compare_pair(scene, vary: str | None = None) -> VariantPair:
    """The pair ``compare`` shows: the process kind's own (``variants`` hook), or the two
    values of one key (``vary = "key=a,b"``)."""
    if vary is None:
        kind = process_of(scene)
        if kind.variants is None:
            raise InputError(f"process.kind = {scene.process.kind!r} defines no comparison; "
                             f"use --vary key=a,b")
        return kind.variants(scene)
    key, (va, vb) = parse_vary(vary)
    leaf = key.split(".")[-1]
    na, nb = _slug(f"{leaf}_{va}"), _slug(f"{leaf}_{vb}")
    if na == nb:
        na, nb = na + "_a", nb + "_b"
    return VariantPair(Variant(na, f"{key} = {va}", {key: va}),
                       Variant(nb, f"{key} = {vb}", {key: vb}), key=key,
                       about=f"The scene with {key} = {va} against {key} = {vb}.")


def variant_scene(scene, variant: Variant):
    """``scene`` with the variant's values set (dotted keys; ``None`` clears a key)."""
    if not variant.values:
        return scene
    data = scene.to_dict()
    plain = []
    for key, value in variant.values.items():
        if value is None:
            node = data
            parts = key.split(".")
            for p in parts[:-1]:
                node = node.setdefault(p, {})
            node[parts[-1]] = None
        else:
            plain.append((key, value))
    data = _set_values(data, plain)
    return scene_from_dict(data, source=f"(variant {variant.name})")


def _set_values(data: dict, pairs) -> dict:
    overrides = []
    for key, value in pairs:
        if isinstance(value, str):
            overrides.append(f"{key}={_toml_str(value)}")
        elif isinstance(value, bool):
            overrides.append(f"{key}={'true' if value else 'false'}")
        elif isinstance(value, (int, float)):
            overrides.append(f"{key}={value!r}")
        else:
            overrides.append(f"{key}={json.dumps(value)}")
    return apply_overrides(data, overrides)


def _toml_str(s: str) -> str:
    return "'" + s.replace("'", "") + "'"


def compare_variants(scene, vary: str | None = None) -> tuple:
    """The two scenes ``compare`` puts side by side (:func:`compare_pair`); everything
    but the varied keys (camera, seed, region) is the same."""
    pair = compare_pair(scene, vary)
    return tuple(variant_scene(scene, v) for v in pair.variants)


# -------------------------------------------------------------------------- windows
def common_window(diff, *, pixel: float, origin, size_mm: float, fixed=None) -> dict:
    """The window every close-up of the report shows: ``fixed`` (mm) if given, else a
    square of ``size_mm`` placed where the two variants differ most (the largest mean
    ``|diff|`` over the window, inside the map), or the map's centre when they do not
    differ.

    Parameters
    ----------
    diff : (ny, nx) array
        Height difference of the two variants (any unit; NaN = not covered).
    pixel, origin
        Grid of ``diff``, mm.
    size_mm : float
        Side of the window.

    Returns
    -------
    dict with ``window`` (x0, y0, x1, y1), mm, and ``peak`` (x, y of the largest
    smoothed ``|diff|`` inside it), mm.
    """
    d = np.abs(np.nan_to_num(np.asarray(diff, dtype=np.float64)))
    ny, nx = d.shape
    x_lo, y_lo = origin[0], origin[1]
    x_hi, y_hi = x_lo + pixel * (nx - 1), y_lo + pixel * (ny - 1)
    if fixed is not None:
        x0, y0, x1, y1 = (float(v) for v in fixed)
    else:
        side = min(float(size_mm), x_hi - x_lo, y_hi - y_lo)
        n = max(1, int(round(side / pixel)))
        if d.max() > 0:
            mean = ndimage.uniform_filter(d, size=n, mode="constant")
            # keep the window inside the map
            h = n // 2
            inner = np.zeros_like(mean, dtype=bool)
            inner[h:ny - (n - h) + 1, h:nx - (n - h) + 1] = True
            if not inner.any():
                inner[:] = True
            i, j = np.unravel_index(np.argmax(np.where(inner, mean, -1)), mean.shape)
            cx, cy = x_lo + j * pixel, y_lo + i * pixel
        else:
            cx, cy = (x_lo + x_hi) / 2, (y_lo + y_hi) / 2
        x0 = min(max(cx - side / 2, x_lo), x_hi - side)
        y0 = min(max(cy - side / 2, y_lo), y_hi - side)
        x1, y1 = x0 + side, y0 + side
    j0 = max(0, int(math.floor((x0 - x_lo) / pixel)))
    j1 = min(nx, int(math.ceil((x1 - x_lo) / pixel)) + 1)
    i0 = max(0, int(math.floor((y0 - y_lo) / pixel)))
    i1 = min(ny, int(math.ceil((y1 - y_lo) / pixel)) + 1)
    sub = d[i0:i1, j0:j1]
    if sub.size and sub.max() > 0:
        sm = ndimage.gaussian_filter(sub, sigma=max(1.0, min(sub.shape) / 16), mode="nearest")
        i, j = np.unravel_index(np.argmax(sm), sm.shape)
        peak = (x_lo + (j0 + j) * pixel, y_lo + (i0 + i) * pixel)
    else:
        peak = ((x0 + x1) / 2, (y0 + y1) / 2)
    return {"window": (float(x0), float(y0), float(x1), float(y1)),
            "peak": (float(peak[0]), float(peak[1]))}


def preview_render_configs(scene, heightmap, *, window=None):
    """Interferometer and diffuse settings for compare: the scene's, over the common
    ``window`` (mm) when given, with the sizes the scene does not set capped
    (:data:`COMPARE_MAX_CAMERA_PIXELS`, :data:`COMPARE_MAX_DIFFUSE_RESOLUTION`,
    :data:`COMPARE_MAX_DIFFUSE_SPP`).  Without a window the interferometer keeps its
    objective's pixel and gets a smaller field of view (centred) unless the scene sets
    ``field_of_view`` (then the pixel is coarsened instead).

    Returns (icfg, dcfg, notes) where notes lists what was capped."""
    icfg = scene.render.interferometer
    dcfg = scene.render.diffuse
    notes = []
    user = icfg.model_fields_set
    if window is not None and "field_of_view" not in user:
        icfg = icfg.model_copy(update={"field_of_view": tuple(window)})
    if "pixel" not in user:
        g = interferometer_geometry(heightmap, icfg)
        n = max(g["nx"], g["ny"])
        if n > COMPARE_MAX_CAMERA_PIXELS:
            x0, y0, x1, y1 = g["window"]
            if "field_of_view" not in user and window is None:
                # keep the objective's pixel (its lateral resolution), crop the field
                half = COMPARE_MAX_CAMERA_PIXELS * g["pixel"] / 2
                cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
                fov = (max(x0, cx - half), max(y0, cy - half), min(x1, cx + half),
                       min(y1, cy + half))
                icfg = icfg.model_copy(update={"field_of_view": fov})
                notes.append(f"interferometer field of view cropped to {COMPARE_MAX_CAMERA_PIXELS} "
                             f"camera pixels of {g['pixel'] * 1e3:.3g} um around the centre "
                             f"({(fov[2] - fov[0]):.3g} x {(fov[3] - fov[1]):.3g} mm; set "
                             f"render.interferometer.field_of_view or pixel to choose)")
            else:
                pix = max(x1 - x0, y1 - y0) / COMPARE_MAX_CAMERA_PIXELS
                icfg = icfg.model_copy(update={"pixel": pix})
                notes.append(f"interferometer pixel {g['pixel'] * 1e3:.3g} um -> {pix * 1e3:.3g} "
                             f"um ({COMPARE_MAX_CAMERA_PIXELS} camera pixels across the field; "
                             f"set render.interferometer.pixel to choose)")
    upd = {}
    dset = dcfg.model_fields_set
    if "resolution" not in dset and dcfg.resolution > COMPARE_MAX_DIFFUSE_RESOLUTION:
        upd["resolution"] = COMPARE_MAX_DIFFUSE_RESOLUTION
    if "spp" not in dset and dcfg.spp > COMPARE_MAX_DIFFUSE_SPP:
        upd["spp"] = COMPARE_MAX_DIFFUSE_SPP
    if window is not None and "window" not in dset:
        upd["window"] = tuple(window)
    if upd:
        dcfg = dcfg.model_copy(update=upd)
        capped = {k: v for k, v in upd.items() if k != "window"}
        if capped:
            notes.append("diffuse " + ", ".join(f"{k} -> {v}" for k, v in capped.items())
                         + " (set render.diffuse.resolution / spp to choose)")
    return icfg, dcfg, notes


# ---------------------------------------------------------------------------- variant
@dataclass
class _Variant:
    name: str
    label: str
    scene: object
    heightmap: object = None
    toolpath: object = None
    ig: object = None
    phase: object = None
    sim: object = None
    diffuse: dict = field(default_factory=dict)  # view -> (rgb, meta)
    timing: dict = field(default_factory=dict)
    filtered: np.ndarray | None = None
    maps: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)


def _scene_filters(scene, hm) -> dict:
    """The S/L filters and edge handling of the waviness maps, chosen from the scene
    (:func:`~render_inspect.metrology.waviness_filters`)."""
    p = scene.process
    m = scene.metrology
    marks = None
    pv = None
    if hasattr(p, "feed_per_rev"):
        marks = p.feed_per_rev
        pv = scallop_pv(marks, scene.tool.nose_radius)
    elif p.kind == "sculpt":
        vib = scene.artifacts.vibration
        if vib.frequency_hz > 0 and vib.amplitude > 0:
            marks = (p.feed_mm_per_min / 60.0) / vib.frequency_hz
            pv = 2 * vib.amplitude
    x0, x1, y0, y1 = hm.extent
    choice = waviness_filters(pixel=hm.pixel, window_mm=(x1 - x0, y1 - y0), mark_period=marks,
                              mark_pv=pv, waviness=_feature_size(scene.design),
                              edges=m.filter_edges, s_filter=m.s_filter, l_filter=m.l_filter)
    choice["form_removal"] = m.form_removal if m.form_removal != "design" else "none"
    choice["polynomial_degree"] = int(m.polynomial_degree)
    return choice


def _feature_size(design) -> float | None:
    """The design's own lateral scale (mm): the waviness a process leaves on it is on
    this scale (sinusoid wavelength, lenslet pitch, element diameter)."""
    sizes = []
    for a in ("wavelength_x", "wavelength_y", "pitch_x", "pitch_y"):
        v = getattr(design, a, None)
        if v:
            sizes.append(float(v))
    er = getattr(design, "element_radius", None)
    if er:
        sizes.append(2 * float(er))
    feat = getattr(design, "feature", None)
    if not sizes and feat is not None:
        return _feature_size(feat)
    return max(sizes) if sizes else None


def _filtered_map(residual, pixel, f):
    r, _ = remove_form(residual, pixel=pixel, method=f["form_removal"],
                       degree=f["polynomial_degree"])
    if f["s_filter_mm"]:
        r = s_filter(r, pixel=pixel, nesting_index=f["s_filter_mm"], edges=f["edges"])
    if f["l_filter_mm"]:
        r = l_filter(r, pixel=pixel, nesting_index=f["l_filter_mm"], edges=f["edges"])
    return r


def _simulate_variant(v: _Variant, out: Path) -> None:
    """Simulate one variant; write heightmap.exr, toolpath.npz, residual.png."""
    d = out / v.name
    d.mkdir(parents=True, exist_ok=True)
    sim = v.sim = simulate(v.scene)
    hm = v.heightmap = sim.heightmap
    v.toolpath = sim.toolpath
    write_heightmap_exr(d / "heightmap.exr", hm)
    if sim.toolpath is not None:
        write_toolpath_npz(d / "toolpath.npz", sim.toolpath)
    save_map_png(d / "residual.png", F.display_map(hm.residual * MM_TO_NM), extent=hm.extent,
                 title=f"{v.label}: machined - design", label="residual (nm)", cmap="RdBu_r",
                 symmetric=True)


def _render_variant(v: _Variant, out: Path, *, icfg, dcfg, seed: int, design_surface,
                    filters: dict, t) -> None:
    """Render, measure and characterise one simulated variant; write its folder."""
    timing = v.timing
    d = out / v.name
    hm = v.heightmap
    sim = v.sim
    t0 = time.perf_counter()
    t.update(f"{v.name}: interferogram")
    ig = v.ig = render_interferogram(hm, icfg, surface="machined", seed=seed)
    timing["interferogram"] = time.perf_counter() - t0
    write_interferogram_outputs(d, ig, scene=v.scene.to_dict())
    t.advance()
    t0 = time.perf_counter()
    t.update(f"{v.name}: phase retrieval")
    mcfg = v.scene.metrology
    # measure from the frames alone (what the instrument reports: height.exr), then
    # evaluate that measurement against the truth kept beside the frames
    reported, v.phase, measured = measure_and_evaluate(d / "interferogram.exr",
                                                       algorithm=mcfg.phase_algorithm,
                                                       csi_refine=mcfg.csi_refine,
                                                       min_modulation=mcfg.min_modulation)
    measured["instrument"] = measurement_outputs(d, ig, reported, source="interferogram.exr")
    timing["phase_retrieval"] = time.perf_counter() - t0
    t.advance()
    err = np.where(v.phase.valid, v.phase.height - ig.height_true, np.nan) * MM_TO_NM
    save_map_png(d / "measurement_error.png", err, extent=ig.extent,
                 title=f"{v.label}: measured - true height", label="error (nm)", cmap="RdBu_r",
                 symmetric=True)
    xx, yy = np.meshgrid(ig.x, ig.y)
    design_ig = np.broadcast_to(design_surface.height(xx, yy), xx.shape)
    meas_res = np.where(reported.valid, reported.height - design_ig, np.nan)
    true_res = np.where(v.phase.valid, ig.height_true - design_ig, np.nan)
    v.maps.update(measured_residual=meas_res, true_residual=true_res, error=err,
                  measured_height=np.where(v.phase.valid, v.phase.height, np.nan))
    measured.update({f"instrument_residual_{k}": x for k, x in _areal_nm(meas_res, ig.pixel).items()})
    measured.update({f"true_residual_{k}": x for k, x in _areal_nm(true_res, ig.pixel).items()})

    views = {}
    for view in ("micro", "macro"):
        t0 = time.perf_counter()
        t.update(f"{v.name}: diffuse {view} view")
        views[view] = render_diffuse_views(v.scene, hm, dcfg, seed=seed, views=(view,))[view]
        timing[f"diffuse_{view}"] = time.perf_counter() - t0
        rgb, meta = views[view]
        v.diffuse[view] = (rgb, meta)
        write_diffuse_outputs(d, rgb, meta, name=f"diffuse_{view}")
        t.advance()

    v.filtered = _filtered_map(hm.residual, hm.pixel, filters)
    save_map_png(d / "filtered.png", F.display_map(v.filtered * MM_TO_NM), extent=hm.extent,
                 title=f"{v.label}: filtered residual (waviness)", label="height (nm)",
                 cmap="RdBu_r", symmetric=True)
    filt = characterise_map(hm.residual, pixel=hm.pixel, origin=hm.origin,
                            form_removal=filters["form_removal"],
                            polynomial_degree=filters["polynomial_degree"],
                            s_filter_mm=filters["s_filter_mm"], l_filter_mm=filters["l_filter_mm"],
                            filter_edges=filters["edges"])
    filt["chosen_from_scene"] = filters["chosen_from_scene"]

    m = dict(sim.metrics)
    m.update({"variant": {"name": v.name, "label": v.label},
              "measured": measured, "filtered": filt,
              "interferometer": interferogram_summary(ig),
              "diffuse": {view: _diffuse_summary(meta) for view, (_, meta) in v.diffuse.items()},
              "mitsuba_variant": ig.variant})
    m["timing_s"] = {**sim.timing_s, **timing}
    write_json(d / "metrics.json", m)
    v.metrics.update(m)


def _diffuse_summary(meta: dict) -> dict:
    sc = meta.get("scale") or {}
    out = {k: meta[k] for k in ("view", "spp", "seed", "vertical_exaggeration", "window_mm",
                                 "mitsuba_variant")}
    out.update(resolution=[meta["camera"]["width"], meta["camera"]["height"]],
               light=meta["light"]["type"], lamp=meta.get("lamp"),
               material=meta["material"]["type"],
               iridescence=bool(meta["material"].get("grating")),
               mm_per_px=sc.get("mm_per_px") or sc.get("mm_per_px_at_target"))
    for k in ("orders", "first_order_efficiency_550nm", "sigma_u", "sigma_v"):
        if k in meta["material"]:
            out[k] = meta["material"][k]
    return out


def _areal_nm(z, pixel) -> dict:
    ok = np.isfinite(z)
    if ok.sum() < 2:
        return {"Sa_nm": None, "Sq_nm": None, "Sz_nm": None}
    p = areal_parameters(z, pixel=pixel)
    return {f"{k}_nm": p[k] * MM_TO_NM for k in ("Sa", "Sq", "Sp", "Sv", "Sz")}


def expected_sq_mm(scene) -> float | None:
    """The Sq the scene's process should leave on its own (mm): the ideal turned profile
    ``f^2 / (12 sqrt(5) R)`` for feed ``f`` per revolution and nose radius ``R``; None for
    processes without a feed per revolution."""
    feed = getattr(scene.process, "feed_per_rev", None)
    radius = getattr(scene.tool, "nose_radius", None)
    if feed is None or radius is None or not feed > 0:
        return None
    return kinematic_sq_mm(float(feed), float(radius))


def check_measured(path, scene, design_surface, *, force: bool = False):
    """Read a measured file and check, before any simulation, that it is a map of this
    design: registered overlap with ``simulation.region`` at least ``metrology.min_overlap``
    of the smaller area, registration residual not far above the process's roughness
    (:func:`render_inspect.metrology.registration_checks`).

    Returns ``(MeasuredMap, Comparison)``; raises :class:`InputError` (one line, the
    reasons) when the checks refuse and ``force`` is False."""
    m = read_surface(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # coverage warnings: repeated in the comparison
        comp = compare_measured(m, design_surface, metrology=scene.metrology,
                                region=tuple(scene.simulation.region),
                                seed=int(scene.simulation.seed),
                                expected_sq_mm=expected_sq_mm(scene), force=force)
    return m, comp


# --------------------------------------------------------------------------- compare
def run_compare(scene, out, *, measured=None, vary: str | None = None,
                force: bool = False, overwrite: bool = False) -> dict:
    """Two variants of a scene (and optionally a measured map): files and report.

    Parameters
    ----------
    scene : Scene
        The validated scene.
    out : str or Path
        Output folder, written atomically (:func:`render_inspect.io.atomic_output_dir`).
    measured : str or Path, optional
        A measured height map (any format :func:`render_inspect.io.read_surface` reads),
        registered to the design and shown as a third column.  It is read and checked
        (:func:`check_measured`) before anything is simulated.
    vary : str, optional
        ``"key=a,b"``: compare the scene with ``key = a`` against ``key = b`` instead of
        the process kind's own pair (:func:`compare_pair`).
    force : bool
        Compare the measured map even when the checks refuse it (the reasons are kept in
        ``measured_file.checks`` and shown in the report).
    overwrite : bool
        Replace ``out`` even if render_inspect did not write it.

    Returns
    -------
    dict
        The content of ``metrics.json``.

    Files in ``out``: one folder per variant (``compensated/`` and ``uncompensated/`` for
    the turning pair; named after the variants otherwise) with ``heightmap.exr``,
    ``toolpath.npz`` (turning), ``interferogram.exr`` with ``height_measured``,
    ``height.exr`` (what the instrument reports), the diffuse images and PNGs, the variant's ``metrics.json``; the figures (the first,
    ``difference.png``), ``metrics.json`` and ``report.html``.
    """
    check_output_dir(out, overwrite=overwrite, command="compare", scene=scene)
    if measured is not None and not Path(measured).is_file():
        raise InputError(f"--measured file not found: {str(measured)!r}")
    _check_phase_settings(scene)
    t_all = time.perf_counter()
    seed = int(scene.simulation.seed)
    design_surface = make_surface(scene.design)
    pair = compare_pair(scene, vary)
    variants = [_Variant(v.name, v.label, variant_scene(scene, v)) for v in pair.variants]
    for v in variants:
        if not _NAME_OK.match(v.name):
            raise InputError(f"variant name {v.name!r} must use letters, digits, '_', '-', '.'")
    meas_map = None
    if measured is not None:  # read and check the file before any simulation
        meas_map, _ = check_measured(measured, scene, design_surface, force=force)
    log.info("compare %s: %s (%s) vs %s (%s)", scene.name, variants[0].name, variants[0].label,
             variants[1].name, variants[1].label)
    check_render_limits(scene, kind="all")
    with atomic_output_dir(out, overwrite=overwrite, command="compare", scene=scene) as tmp, \
            task("compare", total=13) as t:
        tmp = Path(tmp)
        for v in variants:
            t.update(f"{v.name}: simulate")
            _simulate_variant(v, tmp)
            t.advance(2)
        a, b = variants
        diff = (a.heightmap.machined - b.heightmap.machined) * MM_TO_NM
        identical = bool(np.array_equal(a.heightmap.machined, b.heightmap.machined, equal_nan=True))
        hm = a.heightmap
        icfg0 = scene.render.interferometer
        fixed = icfg0.field_of_view if "field_of_view" in icfg0.model_fields_set else None
        g0 = interferometer_geometry(hm, icfg0)
        size = COMPARE_MAX_CAMERA_PIXELS * g0["pixel"] if "pixel" not in icfg0.model_fields_set \
            else max(g0["window"][2] - g0["window"][0], g0["window"][3] - g0["window"][1])
        cw = common_window(diff, pixel=hm.pixel, origin=hm.origin, size_mm=size, fixed=fixed)
        icfg, dcfg, notes = preview_render_configs(scene, hm, window=cw["window"])
        feed = getattr(scene.process, "feed_per_rev", None)
        if feed is not None and feed < 4 * hm.pixel:
            notes.append(f"the simulation samples the {feed * 1e3:.3g} um feed marks with "
                         f"{feed / hm.pixel:.2g} pixels per period (simulation.pixel = "
                         f"{hm.pixel * 1e3:.3g} um): below 4 they are not resolved and alias in "
                         f"the maps and the micro view; set simulation.pixel <= "
                         f"{feed / 4 * 1e3:.3g} um to resolve them")
        filters = _scene_filters(scene, hm)
        for v in variants:
            _render_variant(v, tmp, icfg=icfg, dcfg=dcfg, seed=seed,
                            design_surface=design_surface, filters=filters, t=t)
        meas = None
        if measured is not None:
            t.update("measured file")
            meas = _measured_column(meas_map, scene, design_surface, a.heightmap, seed)
        t.update("figures and report")
        part = part_outline(scene)
        figs, diff_metrics = _figures(a, b, meas, pair=pair, window=cw, part=part,
                                      identical=identical, filters=filters)
        for name, png in figs.items():
            atomic_write_bytes(tmp / f"{name}.png", png)
        ok = np.isfinite(diff)
        rc = a.metrics["residual"], b.metrics["residual"]
        metrics = {
            "variants": [{"name": v.name, "label": v.label, "values": pv.values}
                         for v, pv in zip(variants, pair.variants)],
            "pair": {"key": pair.key, "about": pair.about, "identical": identical},
            a.name: {k: x for k, x in a.metrics.items() if not k.startswith("_")},
            b.name: {k: x for k, x in b.metrics.items() if not k.startswith("_")},
            "difference": {
                "machined_rms_nm": float(np.sqrt(np.mean(diff[ok] ** 2))) if ok.any() else None,
                "machined_pv_nm": float(np.ptp(diff[ok])) if ok.any() else None,
                "min_nm_change": rc[0]["min_nm"] - rc[1]["min_nm"],
                "Sq_nm_change": rc[0]["Sq_nm"] - rc[1]["Sq_nm"],
                "filtered_Sq_nm_change": _sub(a.metrics["filtered"].get("Sq_nm"),
                                              b.metrics["filtered"].get("Sq_nm")),
                **diff_metrics},
            "filters": {k: x for k, x in filters.items()},
            "windows": {"simulation_mm": [float(x) for x in scene.simulation.region],
                        "common_mm": list(cw["window"]),
                        "interferometer_mm": list(a.ig.meta.get("window_mm", cw["window"])),
                        "diffuse_micro_mm": list(a.diffuse["micro"][1]["window_mm"]),
                        "diffuse_macro_mm": list(a.diffuse["macro"][1]["window_mm"]),
                        "largest_difference_mm": list(cw["peak"]), "part": part},
            "software_version": __version__, "seed": seed,
            "mitsuba_variant": mitsuba_variant(),
            "scene": scene.to_dict(),
            "render_settings": {"interferometer": _as_rendered_interferometer(a.ig, icfg),
                                "diffuse": {view: _diffuse_summary(meta)
                                            for view, (_, meta) in a.diffuse.items()},
                                "notes": notes,
                                "profile_angles_deg": list(PROFILE_ANGLES_DEG)},
        }
        if "lenslets" in metrics[a.name]:
            metrics["lenslets"] = metrics[a.name]["lenslets"]
        if meas is not None:
            metrics["measured_file"] = meas["metrics"]
        metrics["timing_s"] = {"total": time.perf_counter() - t_all}
        metrics["report"] = str((Path(out) / "report.html").resolve())
        write_json(tmp / "metrics.json", metrics)
        page = build_page(scene, metrics, figs, notes=notes)
        atomic_write_text(tmp / "report.html", page)
        t.advance()
    return json_safe(metrics)


def compare_summary(metrics: dict) -> tuple[list, list]:
    """The headline numbers of a comparison for a one-screen summary: rows
    (quantity, variant a, variant b) and lines (quantity, text) about the difference."""
    va, vb = (v["name"] for v in metrics["variants"])
    a, b = metrics[va], metrics[vb]
    d = metrics["difference"]
    w = d.get("window", {})
    rows = [("variant", a["variant"]["label"], b["variant"]["label"]),
            ("residual Sq", fmt_quantity(a["residual"]["Sq_nm"], "nm"),
             fmt_quantity(b["residual"]["Sq_nm"], "nm")),
            ("residual min (< 0: overcut)", fmt_quantity(a["residual"]["min_nm"], "nm"),
             fmt_quantity(b["residual"]["min_nm"], "nm")),
            ("waviness Sq (filtered)", fmt_quantity(a["filtered"].get("Sq_nm"), "nm"),
             fmt_quantity(b["filtered"].get("Sq_nm"), "nm")),
            ("instrument height error rms", fmt_quantity(a["measured"].get("rms_nm"), "nm"),
             fmt_quantity(b["measured"].get("rms_nm"), "nm"))]
    lines = [(f"{va} - {vb}, simulated region",
              f"rms {fmt_quantity(d.get('machined_rms_nm'), 'nm')}, "
              f"PV {fmt_quantity(d.get('machined_pv_nm'), 'nm')}"),
             (f"{va} - {vb}, common window",
              f"true rms {fmt_quantity((w.get('true') or {}).get('rms_nm'), 'nm')}, "
              f"measured rms {fmt_quantity((w.get('measured') or {}).get('rms_nm'), 'nm')}")]
    return rows, lines


def _sub(x, y):
    return None if x is None or y is None else x - y


def _as_rendered_interferometer(ig, icfg) -> dict:
    """The interferometer settings as rendered: the scene's keys with the preset values
    resolved (wavelength, NA, pixel, field of view)."""
    d = icfg.model_dump(mode="json")
    d.update(wavelength_nm=ig.wavelength_nm, numerical_aperture=ig.numerical_aperture,
             pixel=ig.pixel, field_of_view=list(ig.meta.get("window_mm", [])),
             bandwidth_nm=ig.bandwidth_nm, camera_pixels=list(ig.shape))
    if d.get("reference_height") is None:
        d["reference_height"] = ig.z_ref
    if ig.mode == "psi":
        d.pop("scan_step_nm", None)
        d.pop("bandwidth_nm", None)
    else:
        d.pop("steps", None)
        d.pop("step_rad", None)
    return d


def _check_phase_settings(scene) -> None:
    """Refuse, before any work, a PSI algorithm that cannot use the frames rendered."""
    ic, alg = scene.render.interferometer, scene.metrology.phase_algorithm
    need = {"4step": 4, "5step": 5}.get(alg)
    if ic.mode == "psi" and need is not None:
        if ic.steps != need:
            raise InputError(f"metrology.phase_algorithm = {alg!r} needs render.interferometer.steps "
                             f"= {need}, got {ic.steps}; set steps = {need} or phase_algorithm = "
                             f"'auto' / 'lsq'")
        if abs(ic.step_rad - np.pi / 2) > 1e-6:
            raise InputError(f"metrology.phase_algorithm = {alg!r} needs render.interferometer."
                             f"step_rad = pi/2 (1.5707963...), got {ic.step_rad}; use 'lsq' for "
                             f"other steps")


def _measured_column(m, scene, design_surface, sim_hm, seed) -> dict:
    simulated = sim_hm if np.allclose(m.pixel, sim_hm.pixel, rtol=1e-6) else None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        comp = compare_measured(m, design_surface, metrology=scene.metrology,
                                simulated=simulated, region=tuple(scene.simulation.region),
                                seed=seed, expected_sq_mm=expected_sq_mm(scene), force=True)
    metrics = dict(comp.metrics)
    metrics["compared_with_simulation"] = simulated is not None
    notes = [str(w.message) for w in caught]
    if simulated is None:
        notes.append(f"the measured pixel ({m.pixel[0] * 1e3:.4g} x {m.pixel[1] * 1e3:.4g} um) "
                     f"differs from the simulation's ({sim_hm.pixel * 1e3:.4g} um): the "
                     f"measurement is compared with the design only")
    checks = metrics.get("checks") or {}
    metrics["warnings"] = notes + list(checks.get("warnings", [])) + [
        f"compared with --force although: {r}" for r in checks.get("refusals", [])]
    return {"metrics": metrics, "maps": comp.maps, "pixel": comp.pixel, "origin": comp.origin,
            "extent": m.extent}


# ---------------------------------------------------------------------------- figures
def _crop(z, hm, window):
    """``z`` (on ``hm``'s grid) inside ``window``, and its pixel-edge extent."""
    x0, y0, x1, y1 = window
    p = hm.pixel
    ox, oy = hm.origin
    j0 = max(0, int(math.ceil((x0 - ox) / p - 1e-9)))
    j1 = min(z.shape[1], int(math.floor((x1 - ox) / p + 1e-9)) + 1)
    i0 = max(0, int(math.ceil((y0 - oy) / p - 1e-9)))
    i1 = min(z.shape[0], int(math.floor((y1 - oy) / p + 1e-9)) + 1)
    ext = (ox + (j0 - 0.5) * p, ox + (j1 - 0.5) * p, oy + (i0 - 0.5) * p, oy + (i1 - 0.5) * p)
    return z[i0:i1, j0:j1], ext


def _line_profile(z, *, pixel, origin, p0, p1, step):
    """Bilinear samples of ``z`` along the segment p0 -> p1 (mm): (s, values)."""
    length = math.hypot(p1[0] - p0[0], p1[1] - p0[1])
    n = max(2, int(length / step) + 1)
    s = np.linspace(0.0, length, n)
    x = p0[0] + (p1[0] - p0[0]) * s / length
    y = p0[1] + (p1[1] - p0[1]) * s / length
    col = (x - origin[0]) / pixel
    row = (y - origin[1]) / pixel
    vals = ndimage.map_coordinates(np.nan_to_num(z, nan=np.nan), [row, col], order=1,
                                   mode="constant", cval=np.nan)
    valid = ndimage.map_coordinates(np.isfinite(z).astype(float), [row, col], order=1,
                                    mode="constant", cval=0.0)
    vals = np.where(valid > 0.999, vals, np.nan)
    return s, vals


def _stats(d) -> dict:
    d = np.asarray(d, dtype=np.float64)
    d = d[np.isfinite(d)]
    if not d.size:
        return {"rms_nm": None, "pv_nm": None, "mean_nm": None}
    return {"rms_nm": float(np.sqrt(np.mean(d * d))), "pv_nm": float(np.ptp(d)),
            "mean_nm": float(d.mean())}


def _figures(a: _Variant, b: _Variant, meas, *, pair, window, part, identical, filters):
    """All top-level PNGs (name -> bytes) and the difference numbers of the first figure."""
    figs = {}
    hm = a.heightmap
    ig = a.ig
    win = window["window"]
    names = (a.name, b.name)
    labels = (a.label, b.label)
    # --- the difference over the common window
    true_full = (a.heightmap.machined - b.heightmap.machined) * MM_TO_NM
    true_win, true_ext = _crop(true_full, hm, ig.meta.get("window_mm", win))
    ma, mb = a.maps["measured_height"], b.maps["measured_height"]
    meas_diff = (ma - mb) * MM_TO_NM
    ig_ext = ig.extent
    px, py = window["peak"]
    x0, y0, x1, y1 = ig.meta.get("window_mm", win)
    px = min(max(px, x0 + 0.1 * (x1 - x0)), x1 - 0.1 * (x1 - x0))
    py = min(max(py, y0 + 0.1 * (y1 - y0)), y1 - 0.1 * (y1 - y0))
    # the profile runs along the direction in which the difference changes most
    with np.errstate(invalid="ignore"):
        gy, gx = np.gradient(np.nan_to_num(true_win)) if min(true_win.shape) > 2 else (0, 0)
    along_x = float(np.mean(np.abs(gx))) >= float(np.mean(np.abs(gy)))
    line = ((x0, py), (x1, py)) if along_x else ((px, y0), (px, y1))
    s, prof = _line_profile(true_full, pixel=hm.pixel, origin=hm.origin, p0=line[0], p1=line[1],
                            step=hm.pixel)
    _, pa = _line_profile(a.heightmap.residual * MM_TO_NM, pixel=hm.pixel, origin=hm.origin,
                          p0=line[0], p1=line[1], step=hm.pixel)
    _, pb = _line_profile(b.heightmap.residual * MM_TO_NM, pixel=hm.pixel, origin=hm.origin,
                          p0=line[0], p1=line[1], step=hm.pixel)
    sm, pm = _line_profile(meas_diff, pixel=ig.pixel, origin=ig.origin, p0=line[0], p1=line[1],
                           step=ig.pixel)
    diff_metrics = {"window": {"window_mm": [x0, y0, x1, y1], "largest_difference_mm": [px, py],
                               "true": _stats(true_win), "measured": _stats(meas_diff),
                               "profile_mm": [list(line[0]), list(line[1])]}}
    locator = _locator(a, part, window, ig)
    if not identical:
        figs["difference"] = F.difference_figure(
            names=names, locator=locator, true_diff=true_win, true_extent=true_ext,
            measured_diff=meas_diff, measured_extent=ig_ext,
            profile={"s": s + (x0 if along_x else y0), "true": prof, "a": pa, "b": pb,
                     "s_measured": sm + (x0 if along_x else y0), "measured": pm, "line": line,
                     "axis": f"x (mm) at y = {py:.4g} mm" if along_x
                     else f"y (mm) at x = {px:.4g} mm",
                     "title": "profile across the largest difference"},
            title=f"{labels[0]} ({names[0]}) - {labels[1]} ({names[1]})")
    else:
        figs["windows"] = locator_figure(locator)
    # --- residual maps (full simulated region), one scale
    res_panels = [(f"{n}: machined - design", v.heightmap.residual * MM_TO_NM)
                  for n, v in zip(names, (a, b))]
    exts = [hm.extent, hm.extent]
    if meas is not None:
        res_panels.append(("measured file - design (registered)",
                           meas["maps"]["residual"] * MM_TO_NM))
        exts.append(meas["extent"])
    figs["residual_side_by_side"] = F.map_panels(res_panels, extent=exts, label="residual (nm)",
                                                 cmap="RdBu_r", symmetric=True)
    figs["residual_difference"] = F.map_panels(
        [(f"machined: {names[0]} - {names[1]}", true_full)], extent=hm.extent,
        label="height difference (nm)", cmap="RdBu_r", symmetric=True,
        lines=[(line[0], line[1])])
    # --- waviness (filtered) maps, one scale, and their difference
    fa, fb = a.filtered * MM_TO_NM, b.filtered * MM_TO_NM
    figs["filtered_side_by_side"] = F.map_panels(
        [(f"{names[0]}: waviness", fa), (f"{names[1]}: waviness", fb),
         (f"{names[0]} - {names[1]}", fa - fb)],
        extent=hm.extent, label="filtered height (nm)", cmap="RdBu_r", symmetric=True)
    # --- interferometer
    figs["interferogram_side_by_side"] = F.image_panels(
        [(f"{n}: intensity (zero-shift frame)", v.ig.intensity) for n, v in zip(names, (a, b))],
        extent=ig_ext, gray_label="intensity (0..1)",
        suptitle=f"Interferograms ({ig.mode.upper()}, {ig.objective}, NA "
                 f"{ig.numerical_aperture:g}, {ig.wavelength_nm:g} nm, "
                 f"{ig.pixel * 1e3:.3g} um pixels)")
    figs["interferogram_difference"] = F.map_panels(
        [(f"{names[0]} - {names[1]}", a.ig.intensity.astype(float) - b.ig.intensity)],
        extent=ig_ext, label="intensity difference", cmap="RdBu_r", symmetric=True)
    figs["measured_residual_side_by_side"] = F.map_panels(
        [(f"{n}: measured - design", v.maps["measured_residual"] * MM_TO_NM)
         for n, v in zip(names, (a, b))],
        extent=ig_ext, label="residual seen by the instrument (nm)", cmap="RdBu_r",
        symmetric=True)
    figs["measurement_error_side_by_side"] = F.map_panels(
        [(f"{n}: measured - true", v.maps["error"]) for n, v in zip(names, (a, b))],
        extent=ig_ext, label="height error (nm)", cmap="RdBu_r", symmetric=True)
    # --- diffuse light
    (rc, mc), (ru, _) = a.diffuse["micro"], b.diffuse["micro"]
    x0m, y0m, x1m, y1m = mc["window_mm"]
    ext = (x0m, x1m, y0m, y1m)
    figs["diffuse_micro_side_by_side"] = F.image_panels(
        [(f"{n}: diffuse micro view", _srgb(r)[::-1]) for n, r in zip(names, (rc, ru))],
        extent=ext, notes=[", ".join(diffuse_caption(mc))] * 2,
        suptitle=f"Diffuse light ({mc['light']['type']}), straight down, heights exaggerated "
                 f"{mc['vertical_exaggeration']:g}x")
    figs["diffuse_difference"] = F.map_panels(
        [(f"{names[0]} - {names[1]} (luminance)", (_luminance(rc) - _luminance(ru))[::-1])],
        extent=ext, label="linear luminance difference", cmap="RdBu_r", symmetric=True)
    (rm, mm_), (rmb, _) = a.diffuse["macro"], b.diffuse["macro"]
    sc = mm_["scale"]["mm_per_px_at_target"]
    bar = nice_length(0.2 * rm.shape[1] * sc)
    figs["diffuse_macro_side_by_side"] = F.image_panels(
        [(f"{n}: the whole part", _srgb(r)) for n, r in zip(names, (rm, rmb))],
        extent=[(0, r.shape[1], 0, r.shape[0]) for r in (rm, rmb)], axis_labels=False,
        scale_mm=(bar, bar / sc), notes=[", ".join(diffuse_caption(mm_))] * 2,
        suptitle=f"The part under the {mm_['light']['type']}"
                 + (" and a lamp" if mm_.get("lamp") else "")
                 + f", heights exaggerated {mm_['vertical_exaggeration']:g}x"
                 + (" (colours: diffraction by the feed marks)"
                    if mm_["material"].get("grating") else ""))
    # --- sections
    turning = hasattr(a.scene.process, "feed_per_rev")
    center = _profile_center(hm) if turning else ((hm.extent[0] + hm.extent[1]) / 2,
                                                  (hm.extent[2] + hm.extent[3]) / 2)
    secs = {}
    for n, v in zip(names, (a, b)):
        h = v.heightmap
        secs[n] = _sections(h.machined, h.design, pixel=h.pixel, origin=h.origin, center=center,
                            angles_deg=PROFILE_ANGLES_DEG, filtered=v.filtered,
                            through=not turning)
    if meas is not None:
        secs["measured file"] = _sections(meas["maps"]["measured"], meas["maps"]["design"],
                                          pixel=meas["pixel"], origin=meas["origin"],
                                          center=center, angles_deg=PROFILE_ANGLES_DEG,
                                          through=not turning)
    figs["sections"] = F.radial_profile_figure(secs, radial=turning)
    # --- machine axes
    kin = _kinematics_png(a, b)
    if kin is not None:
        figs["kinematics"] = kin
    return figs, diff_metrics


def _locator(a: _Variant, part: dict, window: dict, ig) -> dict:
    hm = a.heightmap
    r = [float(v) for v in a.scene.simulation.region]
    x0, x1, y0, y1 = hm.extent
    windows = [("simulated region = macro residual patch", (x0, y0, x1, y1), "0.2", "-"),
               ("interferometer field = common window", tuple(ig.meta.get("window_mm",
                                                                          window["window"])),
                "C3", "-"),
               ("diffuse micro view", tuple(a.diffuse["micro"][1]["window_mm"]), "C0", "--")]
    pad = 0.04 * max(x1 - x0, y1 - y0)
    loc = {"part": part if part.get("shape") == "rect" else {}, "windows": windows,
           "limits": (x0 - pad, x1 + pad, y0 - pad, y1 + pad),
           "background": (a.heightmap.design, hm.extent)}
    if part.get("shape") == "disc":
        R = part["radius"]
        loc["inset"] = {"part": part, "windows": [("region", tuple(r), "C3", "-")],
                        "limits": (-1.05 * R, 1.05 * R, -1.05 * R, 1.05 * R)}
    return loc


def _kinematics_png(a: _Variant, b: _Variant):
    """The machine axes that move in both variants' programs (turning), or the RCSE
    comparison's X motion; None for programs without a spindle (sculpturing)."""
    cols = []
    for v in (a, b):
        sim = v.sim
        if sim.toolpath is None:
            return None
        spec = sim.cut.plots.get("rcse_kinematics.png")
        if spec is not None and v is a:
            return axis_motion_figure([("RCSE (CCPs on the spiral)", spec["path"], {}),
                                       ("conventional (grid-interpolated)", spec["reference"], {})],
                                      axes=("X",),
                                      title="X motion: RCSE vs conventional (seed 004 Figs. 8-9)")
        # the commanded program: a machine's followed path carries its servo noise,
        # whose derivatives would hide the motion (its following error has own figures)
        cols.append((f"{v.name}", sim.toolpath, sim.plan.data))
    return axis_motion_figure(cols, title="Axis motion of the programs (the axes that move)")


def _sections(z, design, *, pixel, origin, center, angles_deg, filtered=None, through=False):
    def sec(m, ang):
        return _one_section(m, pixel=pixel, origin=origin, center=center, angle=ang,
                            through=through)[1]

    out = []
    for ang in angles_deg:
        s, zm = _one_section(z, pixel=pixel, origin=origin, center=center, angle=ang,
                             through=through)
        if np.isfinite(zm).sum() >= 2:
            out.append({"angle_deg": float(ang), "s": s, "machined": zm,
                        "design": None if design is None else sec(design, ang),
                        "filtered": None if filtered is None else sec(filtered, ang)})
    return out


def _one_section(z, *, pixel, origin, center, angle, through):
    if not through:
        return extract_section(z, pixel=pixel, origin=origin, kind="radial", center=center,
                               angle=np.radians(angle))
    ny, nx = np.shape(z)
    half = 0.5 * min(nx, ny) * pixel
    c, s_ = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    p0 = (center[0] - half * c, center[1] - half * s_)
    p1 = (center[0] + half * c, center[1] + half * s_)
    s, v = _line_profile(np.asarray(z, float), pixel=pixel, origin=origin, p0=p0, p1=p1,
                         step=pixel)
    return s - half, v


def _profile_center(hm):
    """The spindle axis (0, 0) when it lies in the map, else the map's centre."""
    x0, x1, y0, y1 = hm.extent
    if x0 <= 0 <= x1 and y0 <= 0 <= y1:
        return (0.0, 0.0)
    return ((x0 + x1) / 2, (y0 + y1) / 2)


def _srgb(rgb):
    a = np.clip(np.nan_to_num(rgb), 0.0, 1.0)
    return np.where(a <= 0.0031308, 12.92 * a, 1.055 * np.power(a, 1 / 2.4) - 0.055)


def _luminance(rgb):
    return rgb[..., 0] * 0.2126 + rgb[..., 1] * 0.7152 + rgb[..., 2] * 0.0722
