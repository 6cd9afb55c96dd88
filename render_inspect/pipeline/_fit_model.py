"""The forward model of ``fit`` (one evaluation: the scene with trial values -> the cut ->
the virtual interference microscope -> the height it reports), the tasks that describe an
evaluation, the instrument the measured file names, the values a key left to a preset
starts from, and the power the cut's random parts and the camera's noise add.

:mod:`render_inspect.fit` does the fitting on numbers; this module chains the stages for
it (:func:`predict_measurement` runs in this process or on a Dask worker)."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
import contextlib
import copy
import json
import math
import os
import socket
import stat
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from ..core.errors import InputError
from ..core.lazy import passive_omp_wait
from ..core.progress import set_reporter
from ..design import Surface, make_surface
from ..fit import EvaluationCache, run_local, set_value, task_hash, waviness
from ..instruments import (MAX_AUTO_SUBSAMPLES, InterferometerConfig, height_instrument,
                           microscope_from_config, recommended_subsamples)
from ..io import read_exr
from ..metrology import measure_frames
from ..processes import preset_settings
from ..scene import scene_from_dict
from ._simulate import simulate

if TYPE_CHECKING:
    from ..scene import Scene

__all__ = ["SameSimulation", "predict_measurement", "preset_value", "preset_fill", "ForwardModel",
           "file_instrument", "instrument_settings", "quiet", "widen_for_grid", "compute_all", "FLOOR_DRAWS",
           "LOCAL_THREADS", "passive_omp_wait", "design_surface", "KEPT_DESIGNS"]

#: pixels traced around the fit window by the virtual instrument (cropped after imaging)
MARGIN_PX = 8
#: realisations of the random parts (and the camera's noise) whose power is averaged into
#: the predictions' spectra
FLOOR_DRAWS = 6
#: evaluations of a batch run at once in this process (threads) when no Dask cluster is
#: used.  One: two at once (each giving the map it gives alone, and keeping a second core
#: busy through the other's single-threaded stages) ended a fit in a segmentation fault
#: inside the ray tracer's kernel once in five fits, although a lock let one thread at a
#: time build and trace Mitsuba's scenes
LOCAL_THREADS = 1
#: designs kept per process for the evaluations (:func:`design_surface`)
KEPT_DESIGNS = 4
_DESIGNS: dict[str, Surface] = {}
_DESIGNS_LOCK = threading.Lock()


# --------------------------------------------------------------------- the forward model
def predict_measurement(task_spec: dict) -> tuple[np.ndarray, dict]:
    """One evaluation: what the virtual instrument reports for the scene of ``task_spec``
    (``scene``: a scene dictionary whose region covers the field and whose section of the
    registered instrument that records interferometer frames
    (:func:`~render_inspect.instruments.height_instrument`, ``render.interferometer``)
    sets the instrument; ``seed``: the camera noise's seed;
    ``algorithm``).  Returns (height (ny, nx) mm with NaN where not measured, meta).
    Runs in this process or on a Dask worker."""
    passive_omp_wait()
    _numba_threads_as_launched()
    scene = scene_from_dict(task_spec["scene"], "(fit evaluation)")
    sim = simulate(scene, surface=design_surface(scene))
    entry = height_instrument()
    # (the height instrument has a render hook: height_instrument() picks one that does)
    ig = entry.render(sim.heightmap, getattr(scene.render, entry.name),  # type: ignore[misc]
                      surface="machined", seed=int(task_spec["seed"]))
    r = measure_frames(ig.recorded(), algorithm=task_spec.get("algorithm", "auto"))
    h = np.where(r.valid, r.height, np.nan)
    return h, {"origin_mm": [float(v) for v in ig.origin], "pixel_mm": float(ig.pixel),
               "shape": list(h.shape), "residual_sq_nm": sim.metrics["residual"]["Sq_nm"],
               "worker": f"{socket.gethostname()}:{os.getpid()}"}


def design_surface(scene: Scene) -> Surface:
    """The design of ``scene`` (:func:`~render_inspect.design.make_surface`), built once per
    process for the evaluations that share it.  The design does not change between a
    fit's evaluations, and what is worked out from it alone is kept on the surface: the
    check that the program's moves between cuts clear the part finds the part's highest
    point once, not once per evaluation (for a design without an interval bound, a dense
    evaluation over the whole part: a third of a profile fit's evaluation).  The same
    numbers either way.  The last :data:`KEPT_DESIGNS` designs are kept (a fit of a design
    key makes a new one per evaluation); a design read from a file is built again when
    the file changes."""
    d = scene.design.model_dump(mode="json")
    key = json.dumps([d, _file_stamps(d)], sort_keys=True, default=str)
    with _DESIGNS_LOCK:
        surface = _DESIGNS.pop(key, None)
    if surface is None:
        surface = make_surface(scene.design)
    with _DESIGNS_LOCK:
        _DESIGNS[key] = surface  # (the most recent last)
        while len(_DESIGNS) > KEPT_DESIGNS:
            _DESIGNS.pop(next(iter(_DESIGNS)))
    return surface


def _file_stamps(node: Any) -> list:
    """(name, modification time, size) of each file a design section names."""
    if isinstance(node, dict):
        return [s for v in node.values() for s in _file_stamps(v)]
    if isinstance(node, list):
        return [s for v in node for s in _file_stamps(v)]
    if isinstance(node, str) and node:
        with contextlib.suppress(OSError, ValueError):
            st = Path(node).stat()
            if stat.S_ISREG(st.st_mode):
                return [[node, st.st_mtime_ns, st.st_size]]
    return []


def _numba_threads_as_launched() -> None:
    """Make ``NUMBA_NUM_THREADS`` in the environment agree with the thread count numba runs
    with.  A Dask worker may get the variable from its nanny after numba has read it; a
    kernel compiled there (the first call of one not yet in the cache) re-reads the
    environment and refuses a count that differs from the running pool's.  (Harmless where
    the cluster sets the variable before numba starts.)  Where the variable is not set,
    numba's re-read gives its default, the count it runs with, and the environment is left
    alone: set in the user's own process, it would pass on to every LocalCluster started
    from it later."""
    if "NUMBA_NUM_THREADS" not in os.environ:
        return
    import numba

    os.environ["NUMBA_NUM_THREADS"] = str(numba.config.NUMBA_NUM_THREADS)


@contextlib.contextmanager
def quiet() -> Iterator[None]:
    """The forward model's own progress bars are not shown during a fit."""
    old = set_reporter(None)
    try:
        yield
    finally:
        set_reporter(old)


def compute_all(store: EvaluationCache, tasks: Sequence[dict], client: Any,
                compute: Callable[[dict], Any] | None = None) -> list:
    """Forward-model runs through the evaluation cache (in this process, or as one batch
    on Dask, each task run by ``compute``, default :func:`predict_measurement`): the
    predicted maps, in order."""
    compute = predict_measurement if compute is None else compute
    keys = [task_hash(t) for t in tasks]
    out: list[np.ndarray | None] = [None] * len(tasks)
    todo: dict[str, list[int]] = {}
    for i, k in enumerate(keys):
        hit = store.get(k)
        if hit is not None:
            out[i] = hit[0]
        else:
            todo.setdefault(k, []).append(i)
    try:
        if client is None:
            with quiet():
                runs = run_local(predict_measurement, [tasks[idx[0]] for idx in todo.values()],
                                 LOCAL_THREADS, catch=False)
                for (h, meta, _, _), (k, idx) in zip(runs, todo.items()):
                    for i in idx:
                        out[i] = store.put(k, h, meta)
        elif todo:
            futures = {k: client.submit(compute, tasks[idx[0]], pure=False)
                       for k, idx in todo.items()}
            for k, fut in futures.items():
                h, meta = fut.result()
                for i in todo[k]:
                    out[i] = store.put(k, h, meta)
    except InputError as err:
        raise InputError(f"the forward model fails at the scene's values: {err}") from None
    return out


# ------------------------------------------------------------------ preset values
def preset_value(scene: Scene, key: str) -> Any:
    """The value of a machine or material key the scene leaves to its preset (scene
    units), or None."""
    parts = key.split(".")
    node = preset_settings(scene).get(parts[0])
    if not node:
        return None
    for p in parts[1:]:
        if isinstance(node, dict):
            node = node.get(p)
        elif isinstance(node, list) and p.isdigit() and int(p) < len(node):
            node = node[int(p)]
        else:
            return None
        if node is None:
            return None
    return node


def preset_fill(scene: Scene) -> Callable[[str], Any]:
    """``fill(prefix)``: the preset's array for an array key the scene leaves unset."""
    def fill(prefix: str) -> Any:
        v = preset_value(scene, prefix)
        return copy.deepcopy(v) if isinstance(v, list) else None
    return fill


# ------------------------------------------------------------------ the measured file
_INSTRUMENT_ATTRS = ("objective", "mode", "wavelength_nm", "bandwidth_nm", "numerical_aperture")


def file_instrument(path: str | Path) -> dict:
    """The instrument settings a ``height.exr`` (written by ``measure``) names in its
    header; {} for other files."""
    if Path(path).suffix.lower() != ".exr":
        return {}
    _, attrs = read_exr(path)
    out = {}
    for k in _INSTRUMENT_ATTRS:
        v = attrs.get(k)
        if v not in (None, ""):
            out[k] = v
    inst = attrs.get("instrument")
    if isinstance(inst, str):
        try:
            inst = json.loads(inst)
        except ValueError:
            inst = None
    s = ((inst or {}).get("model") or {}).get("subsamples") if isinstance(inst, dict) else None
    if isinstance(s, int) and 1 <= s <= 8:
        out["subsamples"] = s
    return out


def instrument_settings(scene: Scene, file_settings: dict, objective: str | None, pixel: float,
                        window: Sequence[float], z: np.ndarray) -> tuple[dict, str]:
    """The instrument section of the evaluations (``[render.interferometer]``: the
    registered instrument that records interferometer frames): the scene's, with the file's
    objective and settings (else ``objective``), the measured pixel, the fit window as
    field of view, and the sub-sampling pinned (so that it does not jump between
    evaluations).  Returns (settings, where the objective came from)."""
    entry = height_instrument()
    icfg = getattr(scene.render, entry.name).model_dump(mode="json")
    source = "scene"
    if file_settings.get("objective"):
        icfg["objective"] = str(file_settings["objective"])
        source = "file"
        for k in ("mode", "wavelength_nm", "bandwidth_nm", "numerical_aperture"):
            if k in file_settings:
                icfg[k] = file_settings[k]
        if icfg.get("bandwidth_nm") == 0 and icfg.get("mode") == "csi":
            icfg["bandwidth_nm"] = None
    elif objective:
        icfg["objective"] = objective
        source = "--objective"
    icfg.update(pixel=float(pixel), field_of_view=[float(v) for v in window], margin=MARGIN_PX,
                reference_height=None)
    try:
        # (the height instrument's settings)
        cfg = cast(InterferometerConfig, entry.config.model_validate(icfg))
    except Exception as err:  # pydantic's error: say which setting
        raise InputError(f"the instrument settings of the measured file are not usable "
                         f"({' '.join(str(err).split())[:300]})") from None
    if file_settings.get("subsamples") and source == "file":
        icfg["subsamples"] = int(file_settings["subsamples"])
    elif cfg.subsamples is None:
        gy, gx = np.gradient(np.asarray(z, dtype=np.float64), pixel)
        g = np.hypot(gx, gy)
        g = g[np.isfinite(g)]
        slope = float(math.atan(np.percentile(g, 99.9))) if g.size else None
        s = min(recommended_subsamples(pixel, microscope_from_config(cfg), max_slope=slope),
                MAX_AUTO_SUBSAMPLES)
        icfg["subsamples"] = int(s)
    return entry.config.model_validate(icfg).model_dump(mode="json"), source


# ------------------------------------------------------------------ tasks
@dataclass
class ForwardModel:
    """What an evaluation's task holds: the scene (``base``, a dictionary) with the trial
    values, its region the fit window and margin at ``sim_pixel``, the instrument
    ``icfg`` (its camera noise off in the evaluations), and the random parts ``held`` at
    0 (their expected value; their power enters the spectra instead).

    ``random``: the scene's random parts (key -> amplitude); ``free_random``: those among
    the free keys (their power is scaled by (value / start)^2)."""

    base: dict
    fill: object
    sim_region: list
    sim_pixel: float
    icfg: dict
    seed: int
    random: dict = field(default_factory=dict)
    free_random: tuple = ()

    def _scene(self, values: dict, *, random: dict) -> dict:
        d = copy.deepcopy(self.base)
        for k, v in {**values, **random}.items():
            set_value(d, k, v, fill=self.fill)
        d["simulation"]["region"] = self.sim_region
        d["simulation"]["pixel"] = self.sim_pixel
        return d

    def task(self, values: dict) -> dict:
        """An evaluation: random parts at 0, no camera noise."""
        d = self._scene(values, random={k: 0.0 for k in self.random})
        d.setdefault("render", {})[height_instrument().name] = dict(self.icfg, noise=False)
        t = {"scene": d, "seed": int(self.seed), "algorithm": "auto"}
        if self.free_random:
            # a fitted random part's amplitude does not enter the simulation (held at 0)
            # but does enter the features (its power): it is part of the evaluation's key,
            # else a step in it alone would return the evaluation it was taken from
            t["fitted_random"] = {k: float(values[k]) for k in self.free_random}
        return t

    def draw(self, values: dict, r: int, *, only: str | None = None) -> dict:
        """Realisation ``r`` at ``values``: the random parts as set (free ones at 0) and
        the camera's noise on; with ``only``, that random part alone, no camera noise."""
        if only is None:
            rnd = {k: (0.0 if k in self.free_random else v) for k, v in self.random.items()}
        else:
            rnd = {k: (values[k] if k == only else 0.0) for k in self.random}
        d = self._scene(values, random=rnd)
        seeds = np.random.SeedSequence([int(self.seed), int(r)]).generate_state(2)
        d["simulation"]["seed"] = int(seeds[0] % 2**31)
        noise = only is None and bool(self.icfg.get("noise", True))
        d.setdefault("render", {})[height_instrument().name] = dict(self.icfg, noise=noise)
        return {"scene": d, "seed": int(seeds[1] % 2**31), "algorithm": "auto"}

    def shifted(self, values: dict) -> dict:
        """An evaluation's task (:meth:`task`) on the simulation grid moved by half its
        pixel along x and y: where the grid's nodes fall under the feed marks is arbitrary,
        and changes the sampled cusps (:func:`widen_for_grid`)."""
        t = self.task(values)
        s = 0.5 * self.sim_pixel
        t["scene"]["simulation"]["region"] = [float(v) + s for v in self.sim_region]
        return t

    def has_floor(self) -> bool:
        fixed = any(k not in self.free_random for k in self.random)
        return fixed or bool(self.icfg.get("noise", True))


def widen_for_grid(target: Any, clean: np.ndarray, shifted: np.ndarray) -> float:
    """Widen the ``map`` term's scale of ``target`` to the rms by which the waviness of
    the clean prediction ``clean`` changes when the simulation grid is moved by half its
    pixel (``shifted``, :meth:`ForwardModel.shifted`): the grid samples the cusps of the
    marks at points that move with their phase, and the waviness keeps a trace of it (a
    few hundredths of a nm at 18 samples per feed period) that no parameter controls and
    that moves with the feed.  Below that scale the ``map`` term would be rugged in the
    feed, and its minimum would not lie at the true values.  Returns the rms (mm)."""
    spec = target.spec
    a, b = (waviness(z, pixel=target.pixel, cutoff=target.cutoff, form=spec.form,
                     origin=target.origin) for z in (clean, shifted))
    d = (a - b)[np.isfinite(a - b)]
    rms = float(np.sqrt(np.mean(d ** 2))) if d.size else 0.0
    target.sigma_map = max(target.sigma_map, rms)
    return rms


class SameSimulation:
    """The forward model run once per simulation: tasks that differ only in the fitted
    random parts' amplitudes (``fitted_random``: held at 0 in the simulation, they scale
    the power the features add) share one."""

    def __init__(self, compute: Callable[[dict], Any]) -> None:
        self.compute = compute
        self.memo: dict = {}

    def __call__(self, t: dict) -> Any:
        key = task_hash({k: v for k, v in t.items() if k != "fitted_random"})
        if key not in self.memo:
            self.memo[key] = self.compute(t)
        return self.memo[key]
