"""``analyze``, ``measure`` and ``characterise``: a height map's ISO 25178-2 parameters,
height from interferometer frames, and the virtual instrument's own characteristics."""

from __future__ import annotations

import argparse
from typing import Any

from ._args import _add_out_args, _add_set_arg, _add_verbosity, _objective_names, _Registered


def add_parsers(sub: Any) -> None:
    p = sub.add_parser("analyze", help="ISO 25178-2 parameters of one height map file (measured "
                                       "or simulated): metrics.json, height.png, --x3p; ISO "
                                       "21920-2 parameters of a profile: metrics.json, profile.png")
    p.add_argument("file", help="height map: X3P, SUR, PLU, DAT (MetroPro), DATX, OPD, TMD, NMS, "
                                "heightmap.exr, ...; or a profile: a text export (CSV, TXT: "
                                "position, height), a Dektak .opdx, an X3P profile (PRF)")
    _add_out_args(p)
    p.add_argument("--form", choices=["none", "plane", "poly2", "sphere"], default="plane",
                   help="form removed first (none: the mean only; plane: a line on a profile)")
    p.add_argument("--filter", default=None, metavar="S,L",
                   help="ISO 16610-61 Gaussian nesting indices in mm, e.g. 0.0025,0.8 or ,0.8 "
                        "(a profile: ISO 16610-21 lambda_s,lambda_c; default ISO 21920-3's choice)")
    p.add_argument("--outliers", choices=["none", "sigma"], default="none",
                   help="sigma: leave out the 3-sigma spikes (counted either way)")
    p.add_argument("--slope", choices=["forward", "central"], default="forward",
                   help="derivative estimator of Sdq/Sdr (forward: as SurfaceTopography and surfalize)")
    p.add_argument("--x3p", action="store_true", help="also write the evaluated surface as height.x3p")
    p.add_argument("--units", default=None, metavar="U",
                   help="a profile text file's units when it does not state them: um, mm, nm or "
                        "POSITION,HEIGHT (e.g. um,nm)")
    _add_verbosity(p)

    p = sub.add_parser("measure", help="height from interferometer frames alone: height.exr, metrics.json")
    p.add_argument("frames", help="interferogram.exr (frames + settings), or a TIFF / PNG stack "
                                  "or a folder of frames with a settings JSON")
    _add_out_args(p)
    p.add_argument("--algorithm", default="auto",
                   choices=["auto", "4step", "5step", "hariharan", "lsq", "envelope",
                            "envelope+phase"],
                   help="PSI: 4step, 5step (= hariharan), lsq; CSI: envelope, envelope+phase; "
                        "auto: by mode and frame count")
    p.add_argument("--settings", default=None,
                   help="settings JSON of a TIFF / PNG stack (default: beside it)")
    p.add_argument("--min-modulation", type=float, default=0.05, dest="min_modulation",
                   help="pixels with lower fringe contrast are not measured (default 0.05)")
    _add_verbosity(p)

    p = sub.add_parser("characterise", help="the virtual instrument's transfer function, step "
                                            "response, slope limit and noise (ISO 25178-600 style)")
    p.add_argument("--objective", default="20x", choices=_Registered(_objective_names),
                   metavar="NAME", help="objective preset, a registered one: %(choices)s "
                                        "(default 20x)")
    _add_out_args(p)
    p.add_argument("--mode", choices=["psi", "csi"], default="psi")
    _add_set_arg(p, help="override an instrument key of [render.interferometer], e.g. "
                         "--set numerical_aperture=0.5 (TOML value syntax)")
    p.add_argument("--seed", type=int, default=0, help="seed of the camera noise")
    p.add_argument("--quick", action="store_true", help="fewer points, smaller fields (for tests)")
    _add_verbosity(p)


def _analyze(args: argparse.Namespace, overwrite: bool) -> dict:
    # the pipeline imports numba, scipy and pydantic: imported here, not at the top of the
    # module, so that `render-inspect --help` answers at once
    from .. import pipeline

    return pipeline.run_analyze(args.file, args.out, form=args.form, filter_spec=args.filter,
                                outliers=args.outliers, slope=args.slope, x3p=args.x3p,
                                overwrite=overwrite, units=args.units)


def _measure(args: argparse.Namespace, overwrite: bool) -> dict:
    # (the pipeline is imported lazily, as above)
    from .. import pipeline

    return pipeline.run_measure(args.frames, args.out, algorithm=args.algorithm,
                                settings=args.settings, min_modulation=args.min_modulation,
                                overwrite=overwrite)


def _characterise(args: argparse.Namespace, overwrite: bool) -> dict:
    # (the instrument is checked first, the pipeline imported after it, as above)
    from ..scene import instrument_config

    config = instrument_config(args.objective, args.mode, args.overrides)
    # (imported once the input is checked)
    from .. import pipeline

    return pipeline.run_characterise(
        config, args.out,
        quick=args.quick, seed=args.seed, overwrite=overwrite)


#: command -> what runs it, ``(args, overwrite) -> result``
RUN = {"analyze": _analyze, "measure": _measure, "characterise": _characterise}
