"""``fit``: the scene's tool, feed, machine and material keys fitted to a measured
surface."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

from ..core.errors import InputError
from ._args import (_add_cluster_args, _add_out_args, _add_program_arg, _add_set_arg, _add_verbosity,
                    _objective_names, _Registered, refuse_scene_in_out, say_tool_edge, scene_overrides)

if TYPE_CHECKING:
    from ..scene import Scene


def add_parsers(sub: Any) -> None:
    """``fit``: the scene's tool, feed, machine and material keys fitted to a measured
    surface (its own block: the pipeline's ``run_fit`` does the work)."""
    p = sub.add_parser("fit", help="fit free scene keys (tool, feed, machine, material) to a "
                                   "measured surface through the virtual instrument; predict "
                                   "the next cut: fit.json, fit.html")
    p.add_argument("measured", help="measured height map or profile: anything analyze reads "
                                    "(instrument file, X3P, the height.exr that measure "
                                    "writes, a profile export)")
    p.add_argument("--scene", required=True, help="scene file (TOML) or shipped scene name "
                                                  "describing the cut")
    p.add_argument("--free", required=True, action="append", metavar="KEY[,KEY...]",
                   help="numeric scene keys to fit, e.g. tool.nose_radius,process.feed_mm_per_min"
                        " (array entries by index: machine.errors.axial_sync.0.1)")
    _add_out_args(p)
    p.add_argument("--bounds", action="extend", nargs="+", default=[], metavar="KEY=A,B",
                   help="bounds of a free key (default: the schema's range; must lie inside it)")
    p.add_argument("--objective", default=None, choices=_Registered(_objective_names),
                   metavar="NAME",
                   help="virtual instrument objective when the file names none, a registered "
                        "preset: %(choices)s (default: the scene's "
                        "render.interferometer.objective)")
    p.add_argument("--at", default=None, metavar="X,Y|register",
                   help="where the measured field lies: its centre at X,Y mm, or 'register' "
                        "(found on the design); default: the file's origin")
    p.add_argument("--window", type=float, default=0.2, metavar="MM",
                   help="side of the fitted square, mm (default 0.2: each evaluation simulates "
                        "and images this much); for a profile the length of the fitted "
                        "stretch of the line")
    p.add_argument("--units", default=None, metavar="U|POS,HEIGHT",
                   help="a profile's units where its text file states none: um, mm, nm, or "
                        "POSITION,HEIGHT (as analyze)")
    p.add_argument("--line", default=None, metavar="X0,Y0,X1,Y1",
                   help="the line on the part a profile was taken along (mm; its first point "
                        "at X0,Y0); default for a turned part: the radial line through the "
                        "spindle axis that compare uses. --at X,Y is then the fitted "
                        "stretch's centre on the line")
    p.add_argument("--arms", choices=["one", "both"], default=None,
                   help="a profile along a diameter through the spindle axis: fit the "
                        "window's radii on both arms of the line together ('both', the "
                        "default where the profile reaches them on the other side of the "
                        "axis; each arm's estimate and their disagreement reported and "
                        "folded into the standard errors) or on the window's arm only "
                        "('one')")
    p.add_argument("--form", choices=["none", "plane", "poly2", "sphere"], default="plane",
                   help="form removed from measured and predicted maps before comparing")
    p.add_argument("--weights", action="append", default=[], metavar="TERM=W",
                   help="misfit term weights: map, psd, harmonics (default 1 each); for a "
                        "profile: profile, params, harmonics, psd")
    _add_cluster_args(p, workers="run the evaluations on a local Dask cluster of N processes",
                      scheduler="run the evaluations on the Dask cluster at ADDRESS")
    p.add_argument("--predict", action="extend", nargs="+", default=[], metavar="KEY=VALUE",
                   help="after the fit, simulate the fitted scene with KEY=VALUE (TOML value) "
                        "into DIR/predict, e.g. --predict process.feed_mm_per_min=0.4; the fit's "
                        "uncertainty is carried to it by 2 more predictions per fitted key "
                        "(outside --max-evaluations). Its numbers are means over 4 positions "
                        "of the fit window across the marks (docs/fit.md)")
    p.add_argument("--no-prediction-uncertainty", dest="prediction_uncertainty",
                   action="store_false",
                   help="with --predict: skip the simulations that carry the fit's "
                        "uncertainty to the prediction (its numbers then carry none, and "
                        "the summary and fit.json say it was not computed)")
    _add_set_arg(p, help="override a scene key before fitting (TOML value syntax)")
    _add_program_arg(p)
    p.add_argument("--seed", type=int, default=0, help="seed of the virtual camera's noise and "
                                                       "of the global search")
    p.add_argument("--global", dest="global_points", type=int, default=8, metavar="N",
                   help="points of a seeded Sobol design over the search box (the bounds "
                        "narrowed to half and twice the start) before the local fit "
                        "(default 8; 0: the scene's and the measurement's starts only)")
    p.add_argument("--max-evaluations", dest="max_evaluations", type=int, default=150,
                   metavar="N", help="largest number of evaluations of the scene at trial values, "
                        "a hard limit: the search, the standard errors' differences (5 per "
                        "free key are kept for them), the misfit profiles and, on both arms, "
                        "each arm's own estimate all count; the realisations of the camera's "
                        "noise at the scene's values, made once before the fit, do not "
                        "(default 150)")
    p.add_argument("--profile-points", dest="profile_points", type=int, default=3, metavar="N",
                   help="points either side of the solution along each parameter (misfit.png)")
    p.add_argument("--cache", default=None, metavar="DIR",
                   help="cached evaluations (default: OUT.cache beside --out); a fit run again "
                        "resumes from them")
    _add_verbosity(p)


def _fit(args: argparse.Namespace, overwrite: bool) -> dict:
    # the scene is checked first; the pipeline (numba, SciPy, the writers) is imported
    # after it, not at the top of the module, so that `render-inspect --help` and a
    # mistake in the scene or a key are answered at once
    from ..scene import find_scene, load_scene

    scene = load_scene(args.scene, scene_overrides(args))
    refuse_scene_in_out(args)
    say_tool_edge(scene)  # a measured edge the cut cannot take: refused before the fit
    # (imported once the input is checked)
    from .. import pipeline

    if pipeline.is_profile_measurement(args.measured):
        return _fit_profile(args, overwrite, pipeline, scene, find_scene(args.scene))
    for opt, v in (("--units", args.units), ("--line", args.line), ("--arms", args.arms)):
        if v is not None:
            raise InputError(f"{opt} is for a measured profile; {args.measured!r} is a map")
    if not args.prediction_uncertainty and not args.predict:
        raise InputError("--no-prediction-uncertainty is for --predict: no prediction was "
                         "asked for (add --predict KEY=VALUE)")
    return pipeline.run_fit(
        args.measured, scene, args.free, args.out,
        bounds=args.bounds, objective=args.objective, at=args.at, window_mm=args.window,
        form=args.form, weights=args.weights, workers=args.workers,
        scheduler=args.scheduler, predict=args.predict,
        predict_uncertainty=args.prediction_uncertainty, seed=args.seed,
        global_points=args.global_points, max_evaluations=args.max_evaluations,
        profile_points=args.profile_points, cache=args.cache, overwrite=overwrite,
        scene_file=find_scene(args.scene))


def _fit_profile(args: argparse.Namespace, overwrite: bool, pipeline: Any, scene: Scene,
                 scene_file: Any) -> dict:
    """``fit`` of a measured profile: the options that are for maps only are refused."""
    for opt, v, default in (("--predict", args.predict, []), ("--form", args.form, "plane"),
                            ("--no-prediction-uncertainty", args.prediction_uncertainty, True)):
        if v != default:
            raise InputError(f"{opt} is for a measured map; {args.measured!r} is a profile (its "
                             f"parabola over the fitted window is removed)")
    return pipeline.run_fit_profile(
        args.measured, scene, args.free, args.out,
        units=args.units, line=args.line, bounds=args.bounds, objective=args.objective,
        at=args.at, window_mm=args.window, weights=args.weights, workers=args.workers,
        scheduler=args.scheduler, seed=args.seed, global_points=args.global_points,
        max_evaluations=args.max_evaluations, profile_points=args.profile_points,
        cache=args.cache, overwrite=overwrite, arms=args.arms, scene_file=scene_file)


#: command -> what runs it, ``(args, overwrite) -> result``
RUN = {"fit": _fit}
