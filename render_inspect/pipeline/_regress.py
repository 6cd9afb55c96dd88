"""``regress``: render every regression case and compare it with its reference.

Each case (``scenes/regression/<name>.toml``) is simulated and rendered through the same
stages as ``simulate`` / ``render`` / ``compare``; its images are compared with the
references kept beside the cases (:mod:`render_inspect.batch`):

* deterministic images (the residual map; interferometer frames and the measured height
  without camera noise) value by value, ``|test - ref| <= atol + rtol |ref|`` and the
  same NaN pixels;
* Monte-Carlo images (diffuse-light path tracing; the interferometer with camera noise)
  rendered as ``K`` passes with their own seeds and tested against the reference's mean
  and variance of ``M`` passes: per-pixel two-sample t-test (pooled variance; see
  :mod:`render_inspect.batch`), Sidak-corrected to a false-alarm probability ``alpha``
  per image.

References change only with ``update=True`` (``render-inspect regress --update``), which
records the software version and the Mitsuba variant.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
import fnmatch
import logging
import platform
import shutil
import time
import tomllib
from datetime import datetime, timezone
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np

from .. import __version__
from ..batch import (
    RegressionFailed,
    case_hash,
    compare_deterministic,
    flip_mean,
    image_t_test,
    list_cases,
    pass_statistics,
    read_case,
    read_reference,
    toml_value,
    write_reference,
    write_summary_html,
)
from ..core.errors import InputError, SceneError
from ..core.units import MM_TO_NM
from ..instruments import height_instrument
from ..io import atomic_output_dir, atomic_write_bytes, check_output_dir, write_exr, write_json
from ..metrology import measure_frames
from ..render import variant_info
from ..report import image_png as map_png
from ..report import rgb_png
from ..scene import find_scene, load_scene, scene_sections
from ._render import part_heightmap, render_diffuse_views
from ._simulate import simulate

if TYPE_CHECKING:
    from ..scene import Scene

__all__ = ["run_regress", "case_images", "regression_cases_dir", "IMAGE_SETTINGS",
           "REFERENCE_SEED0", "SEED_STRIDE"]

log = logging.getLogger("render_inspect")

#: Seeds of the reference passes: REFERENCE_SEED0, +1, ...  Test passes use
#: ``simulation.seed * SEED_STRIDE + i``: the two never overlap (seed < 2,000,000).
REFERENCE_SEED0 = 2_000_000_000
SEED_STRIDE = 1000  # not a unit conversion
#: the passes' seeds stay below the reference's: ``seed * SEED_STRIDE + i < REFERENCE_SEED0``
MAX_PASS_SEED = REFERENCE_SEED0 // SEED_STRIDE

#: Per image: unit, tolerances of a deterministic comparison, significance of a
#: Monte-Carlo one.  ``atol`` covers what differs between Mitsuba variants and machines
#: (measured: interferometer frames 4.5e-6, measured height 4e-4 nm between llvm_ad_rgb
#: and scalar_rgb; the residual is bit-identical) with a margin of 20 or more, and is far
#: below any physical change (a frame changes by ~0.1 for a 10 nm height change).
IMAGE_SETTINGS = {
    "residual": {"unit": "nm", "atol": 1e-3, "rtol": 1e-5, "alpha": 1e-3,
                 "what": "machined - design, mean removed"},
    "interferogram": {"unit": "intensity 0..1", "atol": 1e-4, "rtol": 0.0, "alpha": 1e-3,
                      "what": "every frame, then the valid mask"},
    "measured_height": {"unit": "nm", "atol": 0.02, "rtol": 1e-6, "alpha": 1e-3,
                        "what": "height from the frames alone, mean of each region removed"},
    "diffuse_micro": {"unit": "linear radiance", "alpha": 1e-3, "what": "RGB, microscope view"},
    "diffuse_macro": {"unit": "linear radiance", "alpha": 1e-3, "what": "RGB, whole part"},
}


def regression_cases_dir() -> Path:
    """The shipped cases: ``render_inspect/scenes/regression``."""
    return Path(str(resources.files("render_inspect") / "scenes" / "regression"))


def _relative_nm(result) -> np.ndarray:
    """Measured height (mm) minus the mean of each connected region, nm; NaN where not
    measured."""
    h = np.where(result.valid, result.height, np.nan)
    out = np.full(h.shape, np.nan)
    labels = result.labels
    for lab in np.unique(labels[labels > 0]):
        m = (labels == lab) & np.isfinite(h)
        if m.any():
            out[m] = (h[m] - h[m].mean()) * MM_TO_NM
    return out


def _split_seed(overrides) -> tuple[list[str], int | None]:
    """``--set`` overrides without ``simulation.seed``, and that seed: in ``regress`` it is
    the seed of the Monte-Carlo passes (camera noise, path tracing) only.  The surface's
    own random draws (the machine's error motions, the material, the burrs) keep the
    case's seed, so that a case is one surface whatever the passes' seed."""
    rest, seed = [], None
    for ov in overrides or ():
        key, sep, value = str(ov).partition("=")
        if sep and key.strip() == "simulation.seed":
            try:
                v = tomllib.loads(f"v = {value.strip()}")["v"]
            except tomllib.TOMLDecodeError:
                v = None
            if type(v) is not int or not 0 <= v < MAX_PASS_SEED:
                raise InputError(f"--set simulation.seed must be a whole number in [0, "
                                 f"{MAX_PASS_SEED - 1}] (the seed of the Monte-Carlo passes), "
                                 f"received {value.strip()[:40]!r}")
            seed = v
        else:
            rest.append(ov)
    return rest, seed


def _case_scene(case, path: Path, overrides=()):
    rel = path.parent / case.scene
    base = rel if rel.is_file() else find_scene(case.scene)
    sets = [f"{k}={toml_value(v)}" for k, v in case.set.items()] + list(overrides or ())
    try:
        return load_scene(base, sets)
    except SceneError as err:
        raise SceneError(f"regression case {case.name}: {err}") from None


def case_images(scene: Scene, images: Sequence[str], *, seeds: Sequence[int]) -> dict:
    """Render the images of one case.

    Parameters
    ----------
    scene : Scene
    images : list of str
        Names from :data:`IMAGE_SETTINGS`.
    seeds : list of int
        Seeds of the Monte-Carlo passes (deterministic images use ``simulation.seed``).

    Returns
    -------
    dict
        name -> ``kind`` ("deterministic" / "monte_carlo"), ``channels`` (names),
        ``value`` (C, H, W) or ``passes`` (P, C, H, W) float64, ``flip_rows`` (row 0 is the
        smallest y), ``rgb`` (diffuse).
    """
    seed = int(scene.simulation.seed)
    sim = simulate(scene)
    hm = sim.heightmap
    out = {}
    if "residual" in images:
        r = hm.residual * MM_TO_NM
        r = r - np.nanmean(r)
        out["residual"] = {"kind": "deterministic", "channels": ["residual_nm"],
                           "value": r[None], "flip_rows": True}
    if "interferogram" in images or "measured_height" in images:
        entry = height_instrument()
        icfg = getattr(scene.render, entry.name)
        mcfg = scene.metrology
        noisy = bool(icfg.noise)
        frames, heights = [], []
        for s in (seeds if noisy else [seed]):
            # (the height instrument has a render hook: height_instrument() picks one that does)
            ig = entry.render(hm, icfg, surface="machined", seed=int(s))  # type: ignore[misc]
            frames.append(np.concatenate([ig.frames.astype(np.float64),
                                          ig.valid[None].astype(np.float64)]))
            if "measured_height" in images:
                res = measure_frames(ig.recorded(), algorithm=mcfg.phase_algorithm,
                                     csi_refine=mcfg.csi_refine, min_modulation=mcfg.min_modulation)
                heights.append(_relative_nm(res)[None])
        kind = "monte_carlo" if noisy else "deterministic"
        key = "passes" if noisy else "value"
        if "interferogram" in images:
            names = [f"frame_{i:03d}" for i in range(frames[0].shape[0] - 1)] + ["valid"]
            out["interferogram"] = {"kind": kind, "channels": names, "flip_rows": True,
                                    key: np.stack(frames) if noisy else frames[0]}
        if "measured_height" in images:
            out["measured_height"] = {"kind": kind, "channels": ["height_nm"], "flip_rows": True,
                                      key: np.stack(heights) if noisy else heights[0]}
    part_hm = None
    for view in ("micro", "macro"):
        name = f"diffuse_{view}"
        if name in images:
            # the views ``render`` and ``compare`` make: the tool marks' BSDF, the whole
            # part in the macro view
            if view == "macro" and part_hm is None:
                part_hm = part_heightmap(scene, hm)
            passes = [render_diffuse_views(scene, hm, scene.render.diffuse, seed=int(s),
                                           views=(view,), part_hm=part_hm)[view][0]
                      .astype(np.float64).transpose(2, 0, 1) for s in seeds]
            out[name] = {"kind": "monte_carlo", "channels": ["R", "G", "B"], "rgb": True,
                         "passes": np.stack(passes), "flip_rows": False}
    return out


def _settings(case, name) -> dict:
    s = dict(IMAGE_SETTINGS[name])
    tol = case.tolerance.get(name)
    if tol is not None:
        s.update({k: v for k, v in tol.model_dump().items() if v is not None})
    return s


def _select(cases: dict, only) -> dict:
    if not only:
        return cases
    names = [n.strip() for n in str(only).split(",") if n.strip()]
    sel = {}
    for n in names:
        hits = [c for c in cases if fnmatch.fnmatchcase(c, n)]
        if not hits:
            raise InputError(f"--only {n!r} matches no regression case; the cases are: "
                             f"{', '.join(cases)}")
        sel.update({c: cases[c] for c in hits})
    return dict(sorted(sel.items()))


def _as_f32(a):
    return np.asarray(a, dtype=np.float32).astype(np.float64)


def _write_failure(folder: Path, case: str, name: str, im: dict, ref: dict, cmp: dict) -> list:
    """PNGs and EXRs of one image next to its reference; returns (caption, path) pairs."""
    folder.mkdir(parents=True, exist_ok=True)
    flip, rgb = im.get("flip_rows", True), im.get("rgb", False)
    # (a deterministic image holds its value)
    test = (cast(np.ndarray, im.get("value")) if im["kind"] == "deterministic"
            else pass_statistics(im["passes"])["mean"])
    refv = ref.get("value") if ref.get("kind") == "deterministic" else ref.get("mean")
    pngs = []
    # the channel shown: the one with the most failing values
    mask = cmp.get("fail_mask") if cmp.get("fail_mask") is not None else cmp.get("reject")
    c = int(np.argmax(mask.reshape(mask.shape[0], -1).sum(axis=1))) if mask is not None else 0
    chan = im["channels"][c]
    stem = f"{case}/{name}"

    def put(tag, png, caption):
        atomic_write_bytes(folder / f"{name}_{tag}.png", png)
        pngs.append((caption, f"{stem}_{tag}.png"))

    if rgb:
        put("test", rgb_png(test.transpose(1, 2, 0)), f"test (mean of {im['passes'].shape[0]} passes)")
        if refv is not None:
            put("reference", rgb_png(refv.transpose(1, 2, 0)), "reference (mean)")
    else:
        png, lo, hi = map_png(test[c], flip_rows=flip)
        put("test", png, f"test, {chan} ({lo:.4g} .. {hi:.4g})")
        if refv is not None and refv.shape == test.shape:
            png, lo, hi = map_png(refv[c], flip_rows=flip, vmin=lo, vmax=hi)
            put("reference", png, f"reference, {chan} (same colour scale)")
    diff = cmp.get("diff")
    if diff is not None:
        d = diff[c]
        png, lo, hi = map_png(d, cmap="RdBu_r", symmetric=True, flip_rows=flip)
        put("difference", png, f"test - reference, {chan} (+-{hi:.3g})")
    if cmp.get("p") is not None:
        p = np.clip(cmp["p"][c], 1e-300, 1.0)
        thr = cmp["threshold"]
        png, _, hi = map_png(-np.log10(p), cmap="magma", vmin=0.0,
                             vmax=max(-np.log10(thr) * 1.5, 1.0), flip_rows=flip)
        put("pvalue", png, f"-log10 p, {chan} (rejected above {-np.log10(thr):.2f}; "
                           f"{cmp['n_reject']} of {cmp['n_tests']} values)")
    if mask is not None:
        png, _, _ = map_png(mask[c].astype(float), cmap="Reds", vmin=0, vmax=1, flip_rows=flip)
        put("failing", png, f"values that fail, {chan}")
    chans = {f"test.{n}": v for n, v in zip(im["channels"], test)}
    if refv is not None and refv.shape == test.shape:
        chans.update({f"reference.{n}": v for n, v in zip(im["channels"], refv)})
    if diff is not None:
        chans.update({f"difference.{n}": v for n, v in zip(im["channels"], diff)})
    if cmp.get("p") is not None:
        chans.update({f"p.{n}": v for n, v in zip(im["channels"], cmp["p"])})
    write_exr(folder / f"{name}.exr", chans, {"case": case, "image": name})
    return pngs


def _compare(case, name, im, ref, settings, n_test) -> tuple[dict, dict]:
    """Compare one rendered image with its reference entry; returns the result row."""
    row = {"case": case.name, "image": name, "kind": im["kind"], "unit": settings["unit"]}
    if ref is None or ref.get("missing"):
        row.update(passed=False, summary="no reference",
                   error=f"no reference for {case.name}/{name}: run `render-inspect regress "
                         f"--update --only {case.name}`")
        return row, {}
    if ref["kind"] != im["kind"]:
        row.update(passed=False, summary="kind differs",
                   error=f"the reference is {ref['kind']} but this render is {im['kind']} "
                         f"(camera noise switched?)")
        return row, {}
    if list(ref["channels"]) != list(im["channels"]):
        row.update(passed=False, summary="channels differ",
                   error=f"channels {im['channels']} differ from the reference's {ref['channels']}")
        return row, {}
    if im["kind"] == "deterministic":
        cmp = compare_deterministic(_as_f32(im["value"]), ref["value"], atol=settings["atol"],
                                    rtol=settings["rtol"])
        row.update(passed=cmp["passed"], n_values=cmp["n_values"], n_fail=cmp["n_fail"],
                   nan_mismatch=cmp["nan_mismatch"], max_abs_diff=cmp["max_abs_diff"],
                   atol=cmp["atol"], rtol=cmp["rtol"])
        mad = cmp["max_abs_diff"]
        row["summary"] = cmp.get("reason") or (
            f"max |diff| {mad:.3g} {settings['unit']} (atol {cmp['atol']:g} + rtol {cmp['rtol']:g}); "
            f"{cmp['n_fail']} of {cmp['n_values']} values outside, {cmp['nan_mismatch']} NaN mismatches")
    else:
        st = pass_statistics(im["passes"])
        cmp = image_t_test(st, ref, n_test=n_test, n_ref=int(ref["passes"]),
                               alpha=settings["alpha"])
        row.update(passed=cmp["passed"], n_tests=cmp["n_tests"], n_reject=cmp["n_reject"],
                   min_p=cmp["min_p"], threshold=cmp["threshold"], alpha=cmp["alpha"],
                   passes=n_test, reference_passes=int(ref["passes"]), dof_median=cmp["dof_median"])
        if im.get("rgb") and cmp.get("diff") is not None:
            row["flip_mean"] = flip_mean(st["mean"].transpose(1, 2, 0), ref["mean"].transpose(1, 2, 0))
        flip = f", FLIP {row['flip_mean']:.4f}" if row.get("flip_mean") is not None else ""
        row["summary"] = cmp.get("reason") or (
            f"t-test (pooled variance), {n_test} vs {int(ref['passes'])} passes: min p {cmp['min_p']:.2e} "
            f"(threshold {cmp['threshold']:.2e} = Sidak alpha {cmp['alpha']:g} over "
            f"{cmp['n_tests']} values); {cmp['n_reject']} rejected{flip}")
    return row, cmp


def run_regress(*, update: bool = False, only: str | None = None, out: str | Path | None = None,
                cases: str | Path | None = None, references: str | Path | None = None,
                overrides: Iterable[str] = (), overwrite: bool = False) -> dict:
    """``render-inspect regress``: render every regression case and compare it with its
    reference (or, with ``update``, make the references anew).

    Parameters
    ----------
    update : bool
        Replace the references of the selected cases (records the software version and
        the Mitsuba variant); nothing is compared.
    only : str, optional
        Case names or glob patterns, comma-separated.
    out : path, optional
        Where the summary (``summary.html``, ``summary.json``) and, for every image that
        differs, its PNGs and EXR go (default ``out/regress``): checked and locked before
        anything is rendered, replaced whole when the run ends
        (:func:`~render_inspect.io.atomic_output_dir`).
    cases : path, optional
        Folder of case files (default: the shipped ``scenes/regression``).
    references : path, optional
        Folder of references (default: ``<cases>/references``).
    overrides : list of str
        ``KEY=VALUE`` applied to every case after its own (what-if checks; not with
        ``update``).  ``simulation.seed=N`` sets the seed of the Monte-Carlo passes only
        (camera noise, path tracing: passes ``N x 1000 + i``); the surface's random draws
        (the machine's error motions, the material, the burrs) keep the case's own seed,
        so that another seed tests the statistics, not another surface.
    overwrite : bool
        Replace ``out`` even if render_inspect did not write it.

    Returns
    -------
    dict
        ``summary.json``'s content: ``passed``, ``failed``, ``images``, ``results``, ...

    Raises
    ------
    RegressionFailed
        After writing the summary, when an image differs from its reference.
    """
    t_all = time.perf_counter()
    cases_dir = Path(cases) if cases is not None else regression_cases_dir()
    refs_dir = Path(references) if references is not None else cases_dir / "references"
    out = Path(out if out is not None else "out/regress")
    if update and overrides:
        raise InputError(f"--set cannot be used with --update (references come from the case "
                         f"files alone), got --set {list(overrides)}")
    overrides, pass_seed = _split_seed(overrides)
    check_output_dir(out, overwrite=overwrite, command="regress")
    available = list_cases(cases_dir)
    if not available:
        raise InputError(f"no regression cases (*.toml) in {str(cases_dir)!r}")
    selected = _select(available, only)
    info = variant_info()
    meta = {"software_version": __version__, "mitsuba_variant": info["mitsuba_variant"],
            "mitsuba_version": info["mitsuba_version"], "drjit_version": info["drjit_version"],
            "python": platform.python_version()}
    rows, failures = [], []
    with atomic_output_dir(out, overwrite=overwrite, command="regress") as tmp:
        tmp = Path(tmp)
        for name, path in selected.items():
            t0 = time.perf_counter()
            case = read_case(path, sections=scene_sections())
            scene = _case_scene(case, path, overrides)
            settings = {n: _settings(case, n) for n in case.images}
            chash = case_hash(case, settings)
            if update:
                seeds = [REFERENCE_SEED0 + i for i in range(case.reference_passes)]
                ims = case_images(scene, case.images, seeds=seeds)
                entries = {}
                for n, im in ims.items():
                    e = {"kind": im["kind"], "channels": im["channels"], **settings[n]}
                    if im["kind"] == "deterministic":
                        e["value"] = im["value"]
                    else:
                        st = pass_statistics(im["passes"])
                        e.update(mean=st["mean"], var=st["var"], n=st["n"],
                                 passes=int(im["passes"].shape[0]), seed0=REFERENCE_SEED0)
                    entries[n] = e
                write_reference(refs_dir, name, entries,
                                {**meta, "case_hash": chash, "description": case.description,
                                 "created_utc": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")})
                for n in case.images:
                    rows.append({"case": name, "image": n, "kind": ims[n]["kind"], "passed": True,
                                 "summary": "reference updated"})
                log.info("regress %s: references updated (%s) in %.1f s", name,
                         ", ".join(case.images), time.perf_counter() - t0)
                continue
            ref = read_reference(refs_dir, name)
            seed = int(scene.simulation.seed) if pass_seed is None else pass_seed
            seeds = [seed * SEED_STRIDE + i for i in range(case.passes)]
            ims = case_images(scene, case.images, seeds=seeds)
            notes = []
            if ref is not None and ref.get("case_hash") != chash:
                notes.append("the case file changed since its references were made")
            if ref is not None and ref.get("mitsuba_variant") != meta["mitsuba_variant"]:
                notes.append(f"references from {ref.get('mitsuba_variant')}, rendered with "
                             f"{meta['mitsuba_variant']}")
            for n in case.images:
                entry = (ref or {}).get("images", {}).get(n)
                row, cmp = _compare(case, n, ims[n], entry, settings[n], case.passes)
                if notes:
                    row["notes"] = notes
                    row["summary"] += " (note: " + "; ".join(notes) + ")"
                if not row["passed"]:
                    failures.append(row)
                    if cmp:
                        row["pngs"] = _write_failure(tmp / name, name, n, ims[n], entry, cmp)
                rows.append(row)
            bad = [r["image"] for r in rows if r["case"] == name and not r["passed"]]
            log.info("regress %s: %s in %.1f s", name,
                     "ok" if not bad else f"DIFFERS ({', '.join(bad)})", time.perf_counter() - t0)
        if update and not only:
            stale = [d.name for d in refs_dir.iterdir() if d.is_dir() and not d.name.startswith(".")
                     and d.name not in available] if refs_dir.is_dir() else []
            for d in stale:  # references of deleted cases
                shutil.rmtree(refs_dir / d)
        summary = {**meta, "update": update, "cases": list(selected), "images": len(rows),
                   "passed": sum(r["passed"] for r in rows), "failed": len(failures),
                   "elapsed_s": time.perf_counter() - t_all, "references": str(refs_dir),
                   "overrides": list(overrides or ()), "pass_seed": pass_seed, "results": rows}
        write_json(tmp / "summary.json", summary)
        write_summary_html(tmp / "summary.html", rows,
                           {"software": f"render_inspect {__version__}",
                            "Mitsuba": f"{meta['mitsuba_variant']} {meta['mitsuba_version']}",
                            "references": str(refs_dir), "cases": ", ".join(selected),
                            "overrides": " ".join(overrides or ()) or "none",
                            "seed of the Monte-Carlo passes": (
                                "each case's own" if pass_seed is None else str(pass_seed)),
                            "time": f"{summary['elapsed_s']:.1f} s"})
    out = out.resolve()
    if failures:
        first = failures[0]
        raise RegressionFailed(
            f"{len(failures)} of {len(rows)} images differ from their references (first: "
            f"{first['case']}/{first['image']}: {first.get('error') or first['summary']}); "
            f"see {out / 'summary.html'}")
    log.info("regress: %d images %s in %.1f s -> %s", len(rows),
             "updated" if update else "match their references", summary["elapsed_s"],
             out / "summary.html")
    return summary
