"""Image regression cases and their references on disk.

A case is a TOML file in ``scenes/regression/``::

    description = "Li et al. (2018) grid, Z compensation"
    scene = "sts_sinusoidal_grid"            # a shipped scene, or a path relative to this file
    images = ["residual", "interferogram", "measured_height", "diffuse_micro"]

    [set]                                    # overrides (dotted scene keys), like --set
    "simulation.region" = [-0.064, -0.064, 0.064, 0.064]

    [tolerance.residual]                     # optional: per-image tolerances / significance
    atol = 0.001

Its references are ``references/<case>/<image>.exr`` beside the cases, and
``references/<case>/reference.json`` (what made them: software version, Mitsuba variant,
passes and seeds, the case's hash).  A deterministic image is stored as its value (one
EXR channel per image channel); a Monte-Carlo image as the mean, the sample variance and
the count of finite passes (``<channel>.mean``, ``.var``, ``.n``).
"""

from __future__ import annotations

from collections.abc import Sequence
import json
import tomllib
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import Field, ValidationError, ValidationInfo, model_validator

from ..core.errors import InputError
from ..core.section import Section
from ..io import read_exr, write_exr, write_json
from ._summary import replaced_dir
from ._sweepfile import _check_keys, point_id

__all__ = ["RegressCase", "read_case", "list_cases", "write_reference", "read_reference",
           "case_hash", "IMAGE_NAMES", "Tolerance"]

#: The images a case may ask for.
IMAGE_NAMES = ("residual", "interferogram", "measured_height", "diffuse_micro", "diffuse_macro")
ImageName = Literal["residual", "interferogram", "measured_height", "diffuse_micro", "diffuse_macro"]


class Tolerance(Section):
    """Per-image settings that replace the defaults."""
    atol: float | None = Field(None, ge=0, description="deterministic: absolute, image unit")
    rtol: float | None = Field(None, ge=0, description="deterministic: relative")
    alpha: float | None = Field(None, gt=0, lt=0.5, description="Monte-Carlo: false-alarm probability")


class RegressCase(Section):
    """A regression case file (see the module docstring)."""
    name: str = ""
    description: str = ""
    scene: str
    set: dict[str, Any] = Field(default_factory=dict)
    images: list[ImageName] = Field(..., min_length=1)
    passes: int = Field(16, ge=2, le=1024, description="Monte-Carlo test passes (K)")
    reference_passes: int = Field(64, ge=2, le=4096, description="Monte-Carlo reference passes (M)")
    tolerance: dict[ImageName, Tolerance] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _keys(self, info: ValidationInfo):
        _check_keys(self.set, "set", (info.context or {}).get("sections"))
        return self


def read_case(path: str | Path, *, sections: Sequence[str] | None = None) -> RegressCase:
    """Read and validate a case file; its ``name`` is the file's stem."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise InputError(f"regression case {str(path)!r} is not valid TOML: {err}") from None
    data.setdefault("name", path.stem)
    try:
        case = RegressCase.model_validate(data, context={"sections": sections})
    except ValidationError as err:
        lines = []
        for e in err.errors():
            loc = ".".join(str(p) for p in e["loc"])
            msg = e["msg"] if e["type"] != "extra_forbidden" else "unknown key"
            got = "" if e["type"] == "missing" else f"; received {e.get('input')!r}"
            lines.append(f"  {loc}: {msg}{got}")
        raise InputError(f"invalid regression case {str(path)!r}:\n" + "\n".join(lines)) from None
    return case


def list_cases(folder: Path) -> dict[str, Path]:
    """Case files in ``folder``: name -> path, sorted by name."""
    folder = Path(folder)
    return {p.stem: p for p in sorted(folder.glob("*.toml"))}


def case_hash(case: RegressCase, settings: dict) -> str:
    """Identity of a case's definition and the image settings that apply to it (its
    ``description``, prose that does not change an image, is left out)."""
    return point_id({"case": case.model_dump(mode="json", exclude={"description"}),
                     "settings": settings})


def _channels(prefix_names, arr) -> dict:
    return {n: np.asarray(a, dtype=np.float32) for n, a in zip(prefix_names, arr)}


def write_reference(folder: str | Path, case: str, images: dict, meta: dict) -> Path:
    """Write ``folder/<case>/`` anew (built beside it, then swapped in).

    Parameters
    ----------
    images : dict
        image name -> dict with ``kind`` ("deterministic" / "monte_carlo"), ``channels``
        (names), and ``value`` (C, H, W) or ``mean``, ``var``, ``n`` (C, H, W) arrays, and
        any further JSON-able settings (unit, passes, seeds, tolerances).
    meta : dict
        Provenance written into ``reference.json``.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    dst = folder / case
    with replaced_dir(dst) as tmp:
        index = {}
        for name, im in images.items():
            ch = list(im["channels"])
            if im["kind"] == "deterministic":
                chans = _channels(ch, im["value"])
            else:
                chans = {}
                for k in ("mean", "var", "n"):
                    chans.update(_channels([f"{c}.{k}" for c in ch], im[k]))
            write_exr(tmp / f"{name}.exr", chans, {"case": case, "image": name,
                                                    "kind": im["kind"],
                                                    "software_version": meta["software_version"],
                                                    "mitsuba_variant": meta["mitsuba_variant"]})
            index[name] = {k: v for k, v in im.items() if k not in ("value", "mean", "var", "n")}
        write_json(tmp / "reference.json", {**meta, "case": case, "images": index})
    return dst


def read_reference(folder: str | Path, case: str) -> dict | None:
    """``reference.json`` of a case plus its arrays (``images[name]["value"]`` or
    ``["mean"]``, ``["var"]``, ``["n"]``, each (C, H, W)); None when there is none."""
    d = Path(folder) / case
    meta_p = d / "reference.json"
    if not meta_p.is_file():
        return None
    meta = json.loads(meta_p.read_text())
    for name, im in meta.get("images", {}).items():
        p = d / f"{name}.exr"
        if not p.is_file():
            im["missing"] = True
            continue
        chans, _ = read_exr(p)
        ch = im["channels"]
        if im["kind"] == "deterministic":
            im["value"] = np.stack([chans[c] for c in ch]).astype(np.float64)
        else:
            for k in ("mean", "var", "n"):
                im[k] = np.stack([chans[f"{c}.{k}"] for c in ch]).astype(np.float64)
    return meta
