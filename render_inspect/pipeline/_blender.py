"""The pipeline as the Blender add-on drives it.

Simulate, Render, Compare and Export of the add-on are one function each here; the
add-on only reads its panel, calls them (in a worker process, or in Blender's own process
in background mode) and shows the result.  Functions that put data into Blender
(:func:`surfaces_into_blender`, :func:`load_render_images`) go through the Cycles adapter
(:mod:`render_inspect.render`), the only place that imports ``bpy``.

Every long function takes ``progress`` (``progress(fraction, message)``, fraction in
0..1) and writes its output folder atomically (:func:`~render_inspect.io.atomic_output_dir`):
stopped half-way, it leaves nothing behind.  Results are plain JSON-able dicts, so they
cross a process boundary unchanged.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
import importlib.util
import json
from pathlib import Path
from typing import Any

from ..core.errors import InputError, check_positive
from ..instruments import height_instrument
from ..io import (
    atomic_output_dir,
    read_heightmap_exr,
    write_heightmap_exr,
    write_marker,
    write_x3p,
)
from ..core.units import MM_TO_UM
from ..mesh import export_mesh, heightmap_mesh
from ..render import (
    PROP_EXAGGERATION,
    PROP_HEIGHTMAP,
    PROP_OFFSET,
    PROP_SURFACE,
    PROP_VARIANT,
    auto_exaggeration,
    blend_objects,
    default_output_dir,
    load_image,
    remove_image,
    remove_object,
    render_object,
    surface_material,
    surface_object,
)
from ..scene import compare_pair, load_scene, scene_from_dict, shipped_scenes, variant_scene
from ._compare_profile import run_compare_command
from ._render import write_interferogram_outputs
from ._blender_warnings import note, scene_warnings, variant_warnings, warnings_into
from ._simulate import simulate, write_simulation

__all__ = ["simulate_into_blender", "simulate_variants", "surfaces_into_blender",
           "blender_surfaces", "surface_info", "remove_blender_surfaces", "render_variant",
           "load_render_images", "compare_scene", "export_variant", "blender_output_dir",
           "blender_presets", "VARIANT_PROPERTY", "EXPORT_FORMATS", "PANEL_METRICS", "SIDE_BY_SIDE_GAP",
           "RENDER_IMAGES",
           "RENDER_SOURCE"]

#: The custom property naming the variant of a mesh :func:`surfaces_into_blender` made.
VARIANT_PROPERTY = PROP_VARIANT
#: What :func:`export_variant` writes.
EXPORT_FORMATS = ("EXR", "PLY", "GLB", "X3P")
#: Gap between the two meshes of :func:`surfaces_into_blender`, in part widths.
SIDE_BY_SIDE_GAP = 0.15
#: Name of the temporary mesh :func:`render_variant` renders when the surface is not in
#: this Blender (a worker process).
RENDER_SOURCE = "render_inspect_render_source"
#: The images :func:`load_render_images` makes, ``render_inspect_<variant>_<kind>``.
RENDER_IMAGES = ("cycles", "interferogram")
#: Metrics :func:`compare_scene` returns for a panel: (label, path in a variant's
#: metrics, unit).
PANEL_METRICS = (
    ("Residual Sq", ("residual", "Sq_nm"), "nm"),
    ("Residual Sz", ("residual", "Sz_nm"), "nm"),
    ("Deepest overcut", ("residual", "min_nm"), "nm"),
    ("Measured Sq", ("measured", "instrument_residual_Sq_nm"), "nm"),
)


#: Parameters of a measured profile :func:`compare_scene` shows: (label, key in a
#: profile's ``profile`` metrics, unit, factor from the metric's unit to ``unit``).
_PROFILE_METRICS = (
    ("Ra", "Ra_nm", "nm", 1.0),
    ("Rq", "Rq_nm", "nm", 1.0),
    ("Rt", "Rt_nm", "nm", 1.0),
    ("RSm", "RSm_mm", "um", MM_TO_UM),
)
#: The columns of a measured profile's comparison: (key in ``profiles``, label).
_PROFILE_COLUMNS = (("measured", "measured"), ("simulated_measured", "simulated measurement"),
                   ("true", "simulated cut"))


def _quiet(fraction: float, message: str) -> None:
    """The default ``progress``: says nothing."""


def blender_presets() -> dict[str, Path]:
    """The scenes shipped with render_inspect: name -> file."""
    return shipped_scenes()


def blender_output_dir(scene_name: str) -> Path:
    """Where the add-on writes when no output folder is set: ``render_inspect_out/<scene>``
    next to the saved .blend file, else in the system's temporary folder."""
    return default_output_dir(scene_name)


def simulate_variants(scene_path: str | Path, *, overrides: Iterable[str] = (), out: str | Path,
                      surface: str = "machined",
                      exaggeration: float | None = None,
                      progress: Callable[[float, str], None] | None = None) -> dict:
    """Simulate the two variants ``render-inspect compare`` puts side by side (the
    process's own pair, :func:`compare_pair`: ``compensated`` and ``uncompensated`` for
    turning, ``servo_lag`` / ``ideal_servo``, ``vibration_on`` / ``vibration_off``,
    ``rcse`` / ``conventional``) into ``out/<variant>/`` (``heightmap.exr``,
    ``metrics.json``, ``toolpath.npz``, ``residual.png``, ...), written in one atomic step.

    Parameters
    ----------
    scene_path : str or Path
        A scene file (TOML) or the name of a shipped scene.
    overrides : sequence of str
        ``section.key=value`` overrides.
    out : str or Path
        Output folder.
    surface : {"machined", "design", "residual"}
        The layer the meshes will show (for the automatic exaggeration).
    exaggeration : float or None
        Vertical exaggeration of the meshes; None: the scene's
        ``render.diffuse.exaggeration``, else :func:`~render_inspect.render.auto_exaggeration`
        of the first variant's surface (the same for both, so they compare).
    progress : callable or None

    Returns
    -------
    dict
        ``scene_name``, ``out``, ``surface``, ``exaggeration``, ``pair`` (``key``,
        ``about``) and ``variants``, in the pair's order: {variant: {``heightmap`` (path),
        ``label``, ``values`` (the scene keys the variant sets), ``compensation`` (the
        tool-radius compensation the process applies; ``"none"`` for sculpturing),
        ``residual`` (metrics),
        ``shape``, ``pixel_mm``}}; ``warnings``: what ``render-inspect simulate`` warns
        of, one line each (values that look like unit mistakes, a measured tool edge used
        beyond its measured angles, a program's findings), prefixed with the variant
        where it is that variant's.
    """
    warns: list[str] = []
    with warnings_into(warns):
        result = _simulate_variants(scene_path, overrides, out, surface, exaggeration,
                                    progress or _quiet, warns)
    result["warnings"] = warns
    return result


def _simulate_variants(scene_path: str | Path, overrides: Iterable[str], out: str | Path,
                       surface: str, exaggeration: float | None,
                       progress: Callable[[float, str], None], warns: list[str]) -> dict:
    if surface not in ("machined", "design", "residual"):
        raise InputError(f"surface must be machined, design or residual, got {surface!r}")
    if exaggeration is not None:
        check_positive("exaggeration", exaggeration)
    progress(0.02, "loading the scene")
    scene = load_scene(scene_path, list(overrides))
    scene_warnings(scene, warns)
    out = Path(out)
    pair = compare_pair(scene)
    result: dict[str, Any] = {"scene_name": scene.name, "out": str(out.resolve()),
                              "surface": surface,
                              "pair": {"key": pair.key, "about": pair.about}, "variants": {}}
    first: Any = None  # (the first variant's HeightMap)
    # the variant folders are replaced; what else the add-on wrote there (compare/,
    # export/) is kept
    with atomic_output_dir(out, merge=True, command="blender simulate",
                           option="output folder") as tmp:
        for i, v in enumerate(pair.variants):
            name = v.name
            sc = variant_scene(scene, v)
            progress(0.05 + 0.45 * i, f"simulating the {name} surface")
            sim = simulate(sc)
            first = first or sim.heightmap
            (Path(tmp) / name).mkdir()
            metrics = write_simulation(sim, Path(tmp) / name)
            variant_warnings(name, metrics, warns)
            # a folder of its own: the renders of this variant are added to it later
            write_marker(Path(tmp) / name, command="simulate", scene=sc)
            result["variants"][name] = {
                "heightmap": str((out / name / "heightmap.exr").resolve()),
                "label": v.label, "values": dict(v.values),
                "compensation": sim.traits.compensation,
                "residual": {k: v for k, v in metrics["residual"].items()
                             if isinstance(v, (int, float))},
                "shape": list(sim.heightmap.shape), "pixel_mm": float(sim.heightmap.pixel)}
        progress(0.97, "writing")
    if exaggeration is None:
        exaggeration = scene.render.diffuse.exaggeration
    if exaggeration is None:
        exaggeration = auto_exaggeration(first, surface)
    result["exaggeration"] = float(exaggeration)
    progress(1.0, "done")
    return result


def surfaces_into_blender(result: dict, *, collection: Any = None) -> dict:
    """The meshes of a :func:`simulate_variants` result, side by side in Blender.

    Earlier ones are removed first, and with them the images of their renders
    (``render_inspect_<variant>_cycles`` / ``_interferogram``: their files were in the
    variants' folders, which a new simulation replaces).  Each is named ``render_inspect_<variant>_x<exaggeration>``
    and carries the custom properties ``render_inspect_variant``,
    ``render_inspect_exaggeration``, ``render_inspect_heightmap_path``,
    ``render_inspect_offset_mm`` (its shift along x: the second variant, e.g. the
    uncompensated one, sits ``1 + SIDE_BY_SIDE_GAP`` part widths to the right; vertices
    keep the part's coordinates) and those of :func:`~render_inspect.render.surface_object`.

    Returns
    -------
    dict
        {variant: bpy.types.Object}
    """
    ex = float(result["exaggeration"])
    names = list(result["variants"])  # in the pair's order
    maps = {v: read_heightmap_exr(result["variants"][v]["heightmap"]) for v in names}
    # the renders of the meshes replaced (their files went with the variants' folders)
    for variant in set(blender_surfaces()) | set(names):
        for kind in RENDER_IMAGES:
            remove_image(f"render_inspect_{variant}_{kind}")
    remove_blender_surfaces()
    made, shift = {}, 0.0
    try:
        for variant in names:
            hm = maps[variant]
            obj = surface_object(hm, surface=result["surface"], exaggeration=ex,
                                 name=f"render_inspect_{variant}_x{ex:g}", collection=collection)
            made[variant] = obj
            obj[PROP_VARIANT] = variant
            obj[PROP_HEIGHTMAP] = result["variants"][variant]["heightmap"]
            obj[PROP_OFFSET] = shift
            obj.location.x = shift
            obj.data.materials.append(surface_material())
            x_lo, x_hi, _, _ = hm.extent
            shift += (x_hi - x_lo) * (1.0 + SIDE_BY_SIDE_GAP)
    except Exception:
        remove_blender_surfaces()  # nothing half-made
        raise
    return made


def blender_surfaces(objects: Iterable[Any] | None = None) -> dict:
    """{variant: object} of the meshes :func:`surfaces_into_blender` made, among
    ``objects`` (default: every object of the Blender file)."""
    if objects is None:
        objects = blend_objects()
    return {o[PROP_VARIANT]: o for o in objects if PROP_VARIANT in o}


def remove_blender_surfaces() -> None:
    for obj in list(blender_surfaces().values()):
        remove_object(obj.name)


def surface_info(obj: Any) -> dict:
    """What :func:`render_variant` and :func:`export_variant` need of a mesh made by
    :func:`surfaces_into_blender`: ``variant``, ``heightmap``, ``surface``,
    ``exaggeration``."""
    if obj is None or PROP_VARIANT not in obj:
        raise InputError("no render_inspect surface: run Simulate first")
    return {"variant": str(obj[PROP_VARIANT]), "heightmap": str(obj[PROP_HEIGHTMAP]),
            "surface": str(obj[PROP_SURFACE]), "exaggeration": float(obj[PROP_EXAGGERATION])}


def render_variant(heightmap: str | Path, *, variant: str, surface: str = "machined",
                   exaggeration: float, view: str = "macro", resolution: int = 256,
                   samples: int = 64, seed: int = 0, out: str | Path, interferogram: bool = True,
                   progress: Callable[[float, str], None] | None = None) -> dict:
    """Cycles render of one simulated surface under its scene's diffuse light, and the
    interferogram of its scene's instrument (``[render.interferometer]``; needs Mitsuba).

    Renders the mesh on screen when this Blender has it (background mode), else builds
    the same mesh from ``heightmap`` (a worker process).  Writes ``cycles.exr`` /
    ``cycles.png`` and ``interferogram.exr``, ``interferogram_fringes.png`` into ``out``.

    Returns
    -------
    dict
        ``variant``, ``cycles_png``, ``cycles_exr``, ``cycles_time_s``, and with the
        interferogram ``interferogram_png``, ``interferogram_exr``, ``interferogram``
        (its summary); ``notes`` (what was left out and why); ``warnings`` (what the
        interferometer warns of, one line each).
    """
    progress = progress or _quiet
    progress(0.02, "loading the height map")
    path = str(Path(heightmap).resolve())
    hm = read_heightmap_exr(path)
    ex = float(exaggeration)
    obj = next((o for o in blend_objects()
                if o.get(PROP_HEIGHTMAP) == path and o.get(PROP_SURFACE) == surface
                and o.get(PROP_EXAGGERATION) == ex), None)
    made = obj is None
    if made:
        obj = surface_object(hm, surface=surface, exaggeration=ex, name=RENDER_SOURCE)
    progress(0.05, "Cycles: building the scene")
    try:
        res = render_object(obj, view=view, out=out, resolution=int(resolution),
                            spp=int(samples), seed=int(seed),
                            progress=lambda k, n: progress(0.05 + 0.6 * k / n,
                                                           f"Cycles sample {k}/{n}"))
    finally:
        if made:
            remove_object(RENDER_SOURCE)
    result: dict[str, Any] = {"variant": variant, "cycles_png": str(res["png"]),
                              "cycles_exr": str(res["exr"]),
                              "cycles_time_s": float(res["time_s"]), "notes": [],
                              "warnings": []}
    with warnings_into(result["warnings"]):
        _interferogram_into(result, hm, path, surface, out, interferogram, progress)
    progress(1.0, "done")
    return result


def _interferogram_into(result: dict, hm: Any, path: str, surface: str, out: str | Path,
                        interferogram: bool, progress: Callable[[float, str], None]) -> None:
    """:func:`render_variant`'s interferogram, its files and summary into ``result``."""
    if interferogram:
        if importlib.util.find_spec("mitsuba") is None:
            result["notes"].append("no interferogram: Mitsuba is not available on this platform")
        else:
            progress(0.7, "interferometer: ray tracing the surface (Mitsuba)")
            if not hm.scene:
                raise InputError(f"{path}: the height map records no scene; simulate again")
            sc = scene_from_dict(hm.scene)  # the variant's scene, as simulated
            entry = height_instrument()
            # (the height instrument has a render hook: height_instrument() picks one that does)
            ig = entry.render(hm, getattr(sc.render, entry.name),  # type: ignore[misc]
                              surface="design" if surface == "design" else "machined",
                              seed=int(sc.simulation.seed))
            with atomic_output_dir(out, merge=True, command="interferometer", scene=sc,
                                   option="output folder") as tmp:
                summary = write_interferogram_outputs(Path(tmp), ig, scene=sc.to_dict())
            o = Path(out).resolve()
            result.update(interferogram_png=str(o / "interferogram_fringes.png"),
                          interferogram_exr=str(o / "interferogram.exr"),
                          interferogram={k: v for k, v in summary.items()
                                         if isinstance(v, (int, float, str))})


def load_render_images(result: dict) -> list[str]:
    """Load the PNGs of a :func:`render_variant` result into Blender as images
    ``render_inspect_<variant>_cycles`` and ``render_inspect_<variant>_interferogram``;
    return their names."""
    names = []
    for suffix in RENDER_IMAGES:
        key = f"{suffix}_png"
        if key in result:
            names.append(load_image(result[key], f"render_inspect_{result['variant']}_{suffix}").name)
    return names


def _metric(d: Any, path: Iterable[str]) -> int | float | None:
    for k in path:
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d if isinstance(d, (int, float)) else None


def compare_scene(scene_path: str | Path, *, overrides: Iterable[str] = (), out: str | Path,
                  measured: str | Path | None = None, units: str | None = None,
                  line: str | None = None,
                  progress: Callable[[float, str], None] | None = None) -> dict:
    """``render-inspect compare`` (:func:`run_compare_command`) into ``out``, with the
    metrics a panel shows.

    Parameters
    ----------
    scene_path : str or Path
        A scene file (TOML) or the name of a shipped scene.
    overrides : sequence of str
        ``section.key=value`` overrides.
    out : str or Path
        Output folder.
    measured : str, Path or None
        ``--measured``: a measured height map (a third column beside the two variants) or
        a measured profile (compared along a line with the simulated measurement and the
        simulated cut instead of the two variants).
    units, line : str or None
        ``--units`` and ``--line`` of a measured profile.
    progress : callable or None

    Returns
    -------
    dict
        ``report`` (report.html), ``metrics_json``, ``kind`` (``"variants"`` or
        ``"profile"``), ``variants`` (the column names: the two variants in order,
        ``compensated``, ``uncompensated`` for turning, the process's own pair otherwise;
        for a measured profile ``measured``, ``simulated_measured``, ``true``),
        ``labels``, ``rows`` ({``label``, ``unit``, ``values`` (one per column) and the
        values under the column names too}: :data:`PANEL_METRICS`, or
        Ra, Rq, Rt and RSm for a measured profile), ``difference_rms_nm``, and
        for a measured profile ``virtual_measurement`` (its check's status) and
        ``registration`` (``shift_um``, ``correlation``, ``reliable``, ``against``);
        ``warnings``: what ``render-inspect compare`` warns of, one line each (a measured
        tool edge used beyond its angles, a virtual measurement that does not follow
        the cut, a registration that is not reliable, a measured map's checks).
    """
    progress = progress or _quiet
    warns: list[str] = []
    with warnings_into(warns):
        progress(0.02, "loading the scene")
        scene = load_scene(scene_path, list(overrides))
        scene_warnings(scene, warns)
        progress(0.05, "simulating, rendering and measuring" + (
            f" against {Path(measured).name}" if measured else " both variants"))
        metrics = run_compare_command(scene, out, measured=measured, units=units or None,
                                      line=line or None)
    o = Path(out).resolve()
    res: dict[str, Any] = {"report": str(o / "report.html"),
                           "metrics_json": str(o / "metrics.json"), "warnings": warns}
    for text in metrics.get("warnings") or []:
        note(warns, text)
    for text in (metrics.get("measured_file") or {}).get("warnings") or []:
        note(warns, text, "measured file: ")
    rows = []
    if metrics.get("kind") == "profile":
        names = [k for k, _ in _PROFILE_COLUMNS]
        for label, key, unit, factor in _PROFILE_METRICS:
            vals = [_metric(metrics["profiles"].get(k, {}), ("profile", key)) for k in names]
            vals = [None if v is None else v * factor for v in vals]
            if any(v is not None for v in vals):
                rows.append({"label": label, "unit": unit, "values": vals,
                             **dict(zip(names, vals))})
        reg = metrics.get("registration") or {}
        res.update(kind="profile", variants=names, labels=[lab for _, lab in _PROFILE_COLUMNS],
                   rows=rows, difference_rms_nm=None,
                   virtual_measurement=(metrics.get("virtual_measurement") or {}).get("status"),
                   registration={"shift_um": None if reg.get("shift_mm") is None
                                 else reg["shift_mm"] * MM_TO_UM,
                                 **{k: reg.get(k) for k in ("correlation", "reliable", "against")}})
    else:
        names = [v["name"] for v in metrics["variants"]]
        for label, path, unit in PANEL_METRICS:
            vals = [_metric(metrics.get(v, {}), path) for v in names]
            if any(v is not None for v in vals):
                rows.append({"label": label, "unit": unit, "values": vals,
                             **dict(zip(names, vals))})
        res.update(kind="variants", variants=names,
                   labels=[v["label"] for v in metrics["variants"]], rows=rows,
                   difference_rms_nm=metrics.get("difference", {}).get("machined_rms_nm"))
    progress(1.0, "done")
    return res


def export_variant(heightmap: str | Path, *, variant: str, surface: str = "machined",
                   exaggeration: float, formats: Iterable[str] = EXPORT_FORMATS, out: str | Path,
                   progress: Callable[[float, str], None] | None = None) -> dict:
    """One simulated surface as files, into ``out``: ``heightmap.exr`` (design, machined,
    residual, mm), ``<variant>_<surface>.ply`` (mesh, mm, +Z up),
    ``<variant>_<surface>.glb`` (glTF: m, +Y up; exaggeration in the extras) and
    ``<variant>_machined.x3p`` (the machined surface, ISO 25178-72).

    Returns
    -------
    dict
        ``out`` and ``files`` (names written).
    """
    progress = progress or _quiet
    asked = list(formats) if isinstance(formats, (list, tuple, set)) else [formats]
    unknown = [f for f in asked if not isinstance(f, str) or f not in EXPORT_FORMATS]
    formats = [f for f in EXPORT_FORMATS if f in asked]
    if unknown or not formats:  # (messages: name what was received)
        raise InputError(f"export formats: choose one or more of {list(EXPORT_FORMATS)}; "
                         f"received {asked!r}")
    if "X3P" in formats and importlib.util.find_spec("x3pio") is None:
        raise InputError("export formats: X3P needs the x3pio package, which is not "
                         "available here; choose EXR, PLY or GLB")
    progress(0.02, "loading the height map")
    hm = read_heightmap_exr(heightmap)
    out = Path(out)
    files = []
    with atomic_output_dir(out, command="export", scene=hm.scene, option="output folder") as tmp:
        tmp = Path(tmp)
        if "EXR" in formats:
            progress(0.1, "EXR")
            write_heightmap_exr(tmp / "heightmap.exr", hm)
            files.append("heightmap.exr")
        meshes = [f for f in ("PLY", "GLB") if f in formats]
        if meshes:
            progress(0.3, "mesh")
            gm = heightmap_mesh(hm, channel=surface, exaggeration=float(exaggeration))
            for f in meshes:
                name = f"{variant}_{surface}.{f.lower()}"
                export_mesh(gm, tmp / name)
                files.append(name)
        if "X3P" in formats:
            progress(0.8, "X3P")
            name = f"{variant}_machined.x3p"
            write_x3p(tmp / name, hm.machined, pixel=hm.pixel, origin=hm.origin,
                      comment=json.dumps(hm.scene or {}, sort_keys=True))
            files.append(name)
    progress(1.0, "done")
    return {"out": str(out.resolve()), "files": files}


def simulate_into_blender(scene_path: str | Path, *, overrides: Iterable[str] = (),
                          out: str | Path | None = None, surface: str = "machined",
                          exaggeration: float | None = None, collection: Any = None) -> dict:
    """Load a scene file, simulate the machined surface and load it as a mesh object.

    Parameters
    ----------
    scene_path : str or Path
        render_inspect scene (TOML) or the name of a shipped scene.
    overrides : sequence of str
        ``section.key=value`` overrides (the CLI's ``--set``).
    out : str, Path or None
        Folder for ``heightmap.exr``, replaced as a whole (a non-empty folder render_inspect
        did not write is refused); None: :func:`~render_inspect.render.default_output_dir`.
    surface : {"machined", "design", "residual"}
        The height layer that becomes the mesh.
    exaggeration : float or None
        Vertical exaggeration; None uses the scene's ``render.diffuse.exaggeration``, and
        when that is unset too, :func:`~render_inspect.render.auto_exaggeration` of the
        simulated surface (as the Mitsuba renders do).
    collection : bpy.types.Collection or None
        Where to link the object (the active scene's collection when None).

    Returns
    -------
    dict
        ``object`` (bpy.types.Object named ``render_inspect_surface``), ``heightmap``
        (Path of the EXR), ``result`` (Simulation), ``scene`` (Scene).
    """
    if not str(scene_path).strip():
        raise InputError("scene file: choose a render_inspect scene (.toml) first; received an empty path")
    scene = load_scene(scene_path, list(overrides))
    if exaggeration is not None:
        check_positive("exaggeration", exaggeration)
    own = not out  # the add-on's own default folder may be replaced whatever it holds
    out = Path(out) if out else default_output_dir(scene.name)
    # the folder is checked and locked before the simulation, swapped in when complete
    with atomic_output_dir(out, command="blender", scene=scene, option="output folder",
                           overwrite=own) as tmp:
        result = simulate(scene)
        hm = result.heightmap
        write_heightmap_exr(tmp / "heightmap.exr", hm)
    if exaggeration is None:
        exaggeration = scene.render.diffuse.exaggeration
    if exaggeration is None:  # the renderer's automatic choice for this height map
        exaggeration = auto_exaggeration(hm, surface)
    exaggeration = float(exaggeration)
    path = out.resolve() / "heightmap.exr"
    obj = surface_object(hm, surface=surface, exaggeration=exaggeration, collection=collection)
    obj[PROP_HEIGHTMAP] = str(path)
    return {"object": obj, "heightmap": path, "result": result, "scene": scene}
