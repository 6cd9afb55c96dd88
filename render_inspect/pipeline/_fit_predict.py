"""``fit --predict``: the fitted scene with the user's changes (the next cut) simulated over
the fit window into ``predict/``, with the fit's uncertainty of its free keys carried to the
predicted numbers (:mod:`render_inspect.fit`'s :func:`~render_inspect.fit.plan_propagation`)
and the fit's verdict at the prediction's top."""

from __future__ import annotations

import copy
import json
import logging
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from ..core.errors import InputError
from ..core.progress import task
from ..fit import (PREDICTED_QUANTITIES, combine_propagation, plan_propagation, scene_hash,
                   set_value)
from ..io import write_marker
from ..report import key_unit
from ..scene import apply_overrides, scene_from_dict
from ._fit_model import quiet
from ._metrics import write_metrics
from ._simulate import simulate, write_simulation

__all__ = ["predict_next_cut", "predicted_scene"]

log = logging.getLogger("render_inspect")


def predicted_scene(data: dict, values: dict, predict: Sequence[str], fill: Any) -> Any:
    """The scene ``data`` with ``values`` (key -> number) set and the ``--predict`` items
    (``KEY=VALUE``, TOML values) applied."""
    d = copy.deepcopy(data)
    for k, v in values.items():
        set_value(d, k, v, fill=fill)
    items = []
    for item in predict:
        if "=" not in str(item):
            raise InputError(f"--predict expects KEY=VALUE (TOML value), received {item!r}")
        items.append(str(item))
    return scene_from_dict(apply_overrides(d, items), "(--predict)")


def _on_window(scene: Any, window: Sequence[float], pixel: float) -> Any:
    return scene_from_dict(apply_overrides(
        scene.to_dict(), [f"simulation.region={json.dumps(list(window))}",
                          f"simulation.pixel={pixel!r}"]), "(predict)")


def _values(metrics: dict) -> dict:
    out = {}
    for path, _, _ in PREDICTED_QUANTITIES:
        node: Any = metrics
        for part in path.split("."):
            node = node.get(part) if isinstance(node, dict) else None
        if isinstance(node, (int, float)) and not isinstance(node, bool):
            out[path] = float(node)
    return out


def predict_next_cut(folder: Path, fitted: dict, predict: Sequence[str], fill: Any,
                     window: Sequence[float], record: dict,
                     evaluation_pixel: Callable[[Any], float]) -> dict:
    """Simulate the fitted scene ``fitted`` with the ``predict`` changes over ``window``
    (mm) at ``evaluation_pixel(scene)`` into ``folder/predict/`` (as ``simulate`` writes it),
    then at +-1 standard deviation along each eigen-direction of the fitted keys'
    covariance (the same window, pixel and seed; not counted in ``--max-evaluations``);
    return fit.json's ``prediction``, which ``predict/metrics.json`` also holds under
    ``prediction`` (and the fit's ``inputs``: its command line and input files, with the
    SHA-256 of the predicted scene as run).

    Where the fit's verdict says the model does not describe the measurement the
    prediction is marked as no measurement-backed forecast and carries no uncertainty (no
    further simulation)."""
    centre_scene = predicted_scene(fitted, {}, predict, fill)
    pixel = evaluation_pixel(centre_scene)
    centre_scene = _on_window(centre_scene, window, pixel)
    with task("fit: predict the next cut"):
        sim = simulate(centre_scene)
    out = folder / "predict"
    out.mkdir()
    pm = write_simulation(sim, out)
    after = (record.get("model_check") or {}).get("after") or {}
    backed = bool(after.get("describes", True))
    prop = plan_propagation(record, predict)
    prediction: dict = {"settings": list(predict), "folder": "predict",
                        "simulation_pixel_mm": pixel,
                        "measurement_backed": backed,
                        "verdict": after.get("verdict"),
                        "values": _values(pm),
                        "residual": pm.get("residual"), "toolpath": pm.get("toolpath")}
    if not backed:
        prediction["note"] = ("the fit's verdict is that this model does not describe this "
                              "measurement: the fitted values are no measurement of the part, "
                              "and this prediction is the model's, not the part's")
    if prop.blocked is not None:
        prediction["uncertainty"] = None
        prediction["no_uncertainty"] = prop.blocked
    else:
        results: list[dict | None] = []
        with task(f"fit: the prediction's uncertainty ({len(prop.points)} simulations at "
                  f"+-1 standard deviation of the fitted keys)", total=len(prop.points)) as step, \
                quiet():
            for pt in prop.points:
                try:
                    s = _on_window(predicted_scene(fitted, pt.values, predict, fill), window,
                                   pixel)
                    results.append(simulate(s).metrics)
                except InputError as err:
                    log.warning("the prediction at %s was refused (%s): its direction carries "
                                "no uncertainty", pt.values, err)
                    results.append(None)
                step.advance()
        prediction["uncertainty"] = combine_propagation(prop, pm, results,
                                                        seed=centre_scene.simulation.seed,
                                                        unit=key_unit)
        prediction["uncertainty"]["budget"] = (
            "outside --max-evaluations: that limits the fit's evaluations (the scene "
            "through the virtual instrument); these simulations of the prediction come "
            "after the fit and are counted here")
    pm_doc = dict(pm)
    pm_doc["prediction"] = {k: v for k, v in prediction.items()
                            if k not in ("residual", "toolpath", "folder")}
    if record.get("inputs"):
        # the fit's command line and input files; the scene as run is the predicted one
        inp = record["inputs"]
        pm_doc["inputs"] = {**inp, "scene": {**inp["scene"],
                                             "sha256_as_run": scene_hash(centre_scene.to_dict())}}
    write_metrics(out, pm_doc)
    write_marker(out, command="simulate", scene=centre_scene)
    return prediction

