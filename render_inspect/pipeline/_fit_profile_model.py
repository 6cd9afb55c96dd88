"""The forward model of a profile fit: the scene's cut over a thin band about a stretch of
the measured line, imaged by the virtual interferometer at the profile's spacing and
sampled along the line (:func:`predict_profile`), in one process or on a Dask worker."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.errors import InputError
from ..core.lazy import lazy_module
from ..fit import MISMATCH, task_hash
from ..scene import scene_from_dict
from ._compare_profile import BAND_HALF_MM, REGION_MARGIN_MM
from ._fit import _evaluation_pixel, _on_lattice
from ._fit_model import (MARGIN_PX, ForwardModel, compute_all, design_surface,
                         predict_measurement, quiet)
from ._simulate import simulate

if TYPE_CHECKING:
    from ..scene import Scene

__all__ = ["predict_profile", "simulated_cut", "simulate_profile", "profile_band", "ProfileModel", "MIN_POINTS",
           "compute_profiles", "after_verdict"]

ndimage = lazy_module("scipy.ndimage")

#: the least number of measured points in the fitted window
MIN_POINTS = 64


# --------------------------------------------------------------------- the forward model
def _sample(h, *, pixel, origin, p0, direction, s):
    """Bilinear samples of ``h`` at the points ``p0 + s * direction`` (mm); NaN where a
    neighbour is not measured."""
    x = p0[0] + direction[0] * s
    y = p0[1] + direction[1] * s
    col = (x - origin[0]) / pixel
    row = (y - origin[1]) / pixel
    vals = ndimage.map_coordinates(h, [row, col], order=1, mode="constant", cval=np.nan)
    valid = ndimage.map_coordinates(np.isfinite(h).astype(float), [row, col], order=1,
                                    mode="constant", cval=0.0)
    return np.where(valid > 0.999, vals, np.nan)


def predict_profile(task_spec: dict) -> tuple[np.ndarray, dict]:
    """One evaluation of a profile fit: :func:`~render_inspect.pipeline.predict_measurement`
    of the band, sampled along the task's ``line`` (``p0`` mm, unit ``direction``, positions
    ``s0 + i * step`` for ``i < count``).  Returns (a (1, count) array of heights, mm,
    meta).  A task of both arms of a diameter (``{"arms": [task, task]}``) returns the
    arms' rows, (2, count).  Runs in this process or on a Dask worker."""
    if "arms" in task_spec:
        zs, metas = zip(*(predict_profile(t) for t in task_spec["arms"]))
        return np.vstack(zs), dict(metas[0], arms=len(zs))
    line = task_spec["line"]
    spec = {k: v for k, v in task_spec.items() if k != "line"}
    h, meta = predict_measurement(spec)
    s = float(line["s0"]) + float(line["step"]) * np.arange(int(line["count"]))
    z = _sample(np.where(np.isfinite(h), h, np.nan), pixel=meta["pixel_mm"],
                origin=meta["origin_mm"], p0=line["p0"], direction=line["direction"], s=s)
    return z[None, :], meta


def simulated_cut(task_spec: dict) -> np.ndarray:
    """The scene's cut itself (the simulated machined surface, no instrument) of a profile
    evaluation's task, sampled along its ``line`` as :func:`predict_profile` samples the
    virtual measurement (mm; NaN off the simulated band): what the virtual instrument was
    given to measure."""
    line = task_spec["line"]
    scene = scene_from_dict(task_spec["scene"], "(fit evaluation)")
    with quiet():
        sim = simulate(scene, surface=design_surface(scene))
    hm = sim.heightmap
    s = float(line["s0"]) + float(line["step"]) * np.arange(int(line["count"]))
    return _sample(np.asarray(hm.machined, dtype=np.float64), pixel=float(hm.pixel),
                   origin=hm.origin, p0=line["p0"], direction=line["direction"], s=s)


def simulate_profile(scene: Scene, p0: Sequence[float], p1: Sequence[float], spacing: float, *,
                     seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The scene's cut along the line ``p0 -> p1`` (mm) as the virtual interferometer
    measures it (its camera noise on, seeded), sampled every ``spacing`` mm: a thin band
    about the line simulated at the evaluations' pixel and imaged at ``spacing``, as an
    evaluation of a profile fit does.  Returns (positions along the line from ``p0``, mm;
    heights, mm): a measured profile with a known answer (tests, benchmarks)."""
    length = math.hypot(p1[0] - p0[0], p1[1] - p0[1])
    u = [(p1[0] - p0[0]) / length, (p1[1] - p0[1]) / length]
    count = int(math.floor(length / spacing + 1e-9)) + 1
    d = scene.model_dump(mode="json")
    px = _evaluation_pixel(scene)
    # (the band of a fit's evaluation about the same stretch)
    fov, d["simulation"]["region"] = profile_band((p0, p1), spacing, px)
    d["simulation"]["pixel"] = px
    d["render"]["interferometer"].update(pixel=float(spacing), field_of_view=fov,
                                         margin=MARGIN_PX, noise=True)
    z, _ = predict_profile({"scene": d, "seed": int(seed), "algorithm": "auto",
                            "line": {"p0": list(p0), "direction": u, "s0": 0.0,
                                     "step": float(spacing), "count": count}})
    return np.arange(count) * float(spacing), z.ravel()


def profile_band(ends: Sequence[Sequence[float]], spacing: float,
                 sim_pixel: float) -> tuple[list[float], list[float]]:
    """The band a profile evaluation simulates about the stretch of a line between its two
    ``ends`` (mm), sampled every ``spacing`` mm: (the interferometer's field, the simulated
    region), the region on the lattice of the simulation pixel through the origin, as a
    map's fit has it (the grid's nodes fall under the marks at the same places wherever
    the band lies)."""
    h = BAND_HALF_MM
    fov = [min(e[0] for e in ends) - h, min(e[1] for e in ends) - h,
           max(e[0] for e in ends) + h, max(e[1] for e in ends) + h]
    grow = max(REGION_MARGIN_MM, (MARGIN_PX + 2) * spacing + 2 * sim_pixel)
    return fov, _on_lattice([fov[0] - grow, fov[1] - grow, fov[2] + grow, fov[3] + grow], sim_pixel)


@dataclass
class ProfileModel(ForwardModel):
    """:class:`ForwardModel` whose tasks also name the line sampled (:func:`predict_profile`)."""

    line: dict | None = None

    def task(self, values: dict) -> dict:
        return dict(super().task(values), line=self.line)

    def draw(self, values: dict, r: int, *, only: str | None = None) -> dict:
        return dict(super().draw(values, r, only=only), line=self.line)


def compute_profiles(store: Any, tasks: Sequence[dict], client: Any,
                     compute: Callable[[dict], Any]) -> list[np.ndarray]:
    """:func:`compute_all` with the profile's forward model."""
    if client is not None:
        return compute_all(store, tasks, client, compute)
    out = []
    for t in tasks:
        k = task_hash(t)
        hit = store.get(k)
        if hit is not None:
            out.append(hit[0])
            continue
        try:
            with quiet():
                z, meta = predict_profile(t)
        except InputError as err:
            raise InputError(f"the forward model fails at the scene's values: {err}") from None
        out.append(store.put(k, z, meta))
    return out


def after_verdict(findings: list[str], goodness: dict, described: str) -> dict:
    """The check after a profile fit from its ``findings`` (empty: the model describes the
    window, ``described`` says what) and the misfit against the camera's noise floor
    (``goodness["ratio"]``: a model error said in words where over :data:`MISMATCH`)."""
    ratio = goodness.get("ratio")
    notes = []
    if ratio is not None and ratio > MISMATCH and not findings:
        notes.append(f"the misfit is {ratio:.3g} times what the camera's noise alone leaves: "
                     f"the cusps' shape differs from the model's; the standard errors are "
                     f"scaled by it (the model's error)")
        # (the marks' period is described, their shape is not: said so in the verdict too)
        described = f"{described} in period, not in shape (misfit {ratio:.3g} x the noise)"
    return {"describes": not findings, "findings": findings, "notes": notes,
            "misfit_over_noise": ratio,
            "verdict": (described if not findings else "this model does not describe this "
                                                       "measurement: " + "; ".join(findings))}
