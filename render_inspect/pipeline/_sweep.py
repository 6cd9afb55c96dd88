"""``sweep``: one scene, many parameter values, run on Dask; resumable.

Each point of a sweep file (:mod:`render_inspect.batch`) is the base scene with its
overrides, validated here; its identity is a hash of the resolved scene and of what it
runs (``[run]``), so the same point in another sweep or a re-run is recognised.  The
client process (the one that calls :func:`run_sweep`) is the only writer of
``results.jsonl``; workers write each point's folder atomically, last its ``point.json``.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import socket
import time
import traceback
from importlib import resources
from pathlib import Path

from .. import __version__
from ..batch import (
    Progress,
    ResultsLog,
    csv_text,
    dashboard_text,
    dask_client,
    default_plots,
    dotted_get,
    expand_points,
    folder_lock,
    plot_rows,
    point_id,
    read_sweep,
    summary_table,
    sweep_keys,
    toml_value,
)
from ..core.errors import InputError, RenderInspectError, SceneError
from ..core.units import MM_TO_NM
from ..io import (
    atomic_output_dir,
    atomic_write_bytes,
    atomic_write_text,
    check_output_path,
    claim_output_dir,
    write_json,
)
from ..scene import find_scene, load_scene, scene_from_dict, scene_sections
from ..report import save_map_png, sweep_plot_png
from ._compare import run_compare
from ._measure import measure_and_evaluate
from ._metrics import point_metrics, write_metrics
from ._render import run_render
from ._simulate import residual_title, simulate, write_simulation

__all__ = ["run_sweep", "run_point", "sweep_tasks", "find_sweep", "shipped_sweeps"]

log = logging.getLogger("render_inspect")

POINTS = "points"
#: The summary table is also printed for sweeps of at most this many points.
SHOW_TABLE_POINTS = 30


def shipped_sweeps() -> dict[str, Path]:
    """The sweeps that ship with the package (``scenes/sweeps/``): name -> path."""
    root = resources.files("render_inspect") / "scenes" / "sweeps"
    return {p.name[:-5]: Path(str(p)) for p in sorted(root.iterdir(), key=lambda q: q.name)
            if p.name.endswith(".toml")}


def find_sweep(name_or_path) -> Path:
    """A sweep file: ``name_or_path`` itself when it is a file, else the shipped sweep of
    that name (``fig15_small`` or ``fig15_small.toml``)."""
    path = Path(name_or_path)
    if path.is_file():
        return path
    shipped = shipped_sweeps()
    key = path.name[:-5] if path.name.endswith(".toml") else path.name
    if path.parent == Path(".") and key in shipped:
        return shipped[key]
    raise InputError(f"sweep file not found: {str(path)!r}; give a path to a .toml sweep file or "
                     f"the name of a shipped sweep ({', '.join(shipped)})")


def _base_scene(spec, sweep_path: Path) -> Path:
    """The base scene: a path relative to the sweep file, else a shipped scene's name."""
    rel = sweep_path.parent / spec.scene
    if rel.is_file():
        return rel.resolve()
    try:
        return find_scene(spec.scene)
    except SceneError as err:
        raise SceneError(f"sweep file {str(sweep_path)!r}: scene = {spec.scene!r}: {err}") from None


def sweep_tasks(spec, sweep_path, out) -> tuple[list[dict], list[dict], list[str]]:
    """Resolve every point of ``spec`` into a task for :func:`run_point`.

    Returns
    -------
    tasks : list of dict
        ``id``, ``index``, ``params``, ``studies``, ``overrides``, ``scene`` (validated,
        as a dict), ``run``, ``folder`` (absolute path of the point's folder).
    invalid : list of dict
        Failure records of points whose scene does not validate.
    keys : list of str
        The sweep keys (``params`` of every record).
    """
    sweep_path = Path(sweep_path)
    base = _base_scene(spec, sweep_path)
    keys = sweep_keys(spec)
    run = spec.run.model_dump(mode="json")
    by_id: dict = {}
    invalid: list = []
    for p in expand_points(spec):
        sets = [f"{k}={toml_value(v)}" for k, v in p.overrides.items()]
        try:
            scene = load_scene(base, sets)
        except SceneError as err:
            pid = point_id({"base": str(base), "overrides": p.overrides, "run": run})
            invalid.append({"id": pid, "index": p.index, "status": "failed",
                            "params": {k: p.overrides.get(k) for k in keys},
                            "studies": list(p.studies), "overrides": p.overrides,
                            "folder": None, "error": str(err), "error_type": "SceneError",
                            "software_version": __version__})
            continue
        sd = scene.to_dict()
        pid = point_id({"scene": sd, "run": run})
        if pid in by_id:  # another override set that gives the same scene
            t = by_id[pid]
            t["studies"] += [s for s in p.studies if s not in t["studies"]]
            continue
        by_id[pid] = {"id": pid, "index": p.index, "params": {k: dotted_get(sd, k) for k in keys},
                      "studies": list(p.studies), "overrides": p.overrides, "scene": sd,
                      "run": run, "folder": str(Path(out).resolve() / POINTS / pid)}
    return list(by_id.values()), invalid, keys


# ------------------------------------------------------------------------ on a worker
def _residual_png(sim, path: Path) -> None:
    hm, scene = sim.heightmap, sim.scene
    r = sim.metrics["residual"]
    save_map_png(path, (hm.residual - r["mean_nm"] / MM_TO_NM) * MM_TO_NM, extent=hm.extent,
                 cmap="RdBu_r", symmetric=True, label="machined - design (nm)",
                 title=residual_title(scene.name, sim.traits, r))


def _point_outputs(scene, folder: Path, run: dict) -> dict:
    sim = simulate(scene)
    if run["files"] == "all":
        sim_metrics = write_simulation(sim, folder)
    else:
        sim_metrics = sim.metrics
        _residual_png(sim, folder / "residual.png")
        atomic_write_text(folder / "scene.json", json.dumps(scene.to_dict(), indent=2, sort_keys=True))
    render = measured = compare = None
    if run["render"] != "none":
        render = run_render(scene, folder / "render", kind=run["render"], heightmap=sim.heightmap)
    if run["measure"]:
        m = scene.metrology
        _, _, measured = measure_and_evaluate(folder / "render" / "interferogram.exr",
                                           algorithm=m.phase_algorithm, csi_refine=m.csi_refine,
                                           min_modulation=m.min_modulation)
    if run["compare"]:
        compare = run_compare(scene, folder / "compare")
    metrics = point_metrics(sim_metrics, render=render, measured=measured, compare=compare)
    write_metrics(folder, metrics)
    return metrics


def run_point(task: dict) -> dict:
    """Run one sweep point (on a Dask worker): simulate, and render / measure / compare as
    its ``run`` asks, into its folder (written atomically, ``point.json`` last).

    Returns the point's record: ``id``, ``status`` (``"done"`` or ``"failed"``),
    ``params``, ``studies``, ``metrics`` (the point's metrics.json) or ``error`` (one line
    for the errors render_inspect raises on purpose; the exception and its traceback
    otherwise), ``folder`` (relative to the sweep's folder), ``seconds``, ``worker``.
    """
    t0 = time.perf_counter()
    folder = Path(task["folder"])
    rec = {"id": task["id"], "index": task["index"], "params": task["params"],
           "studies": task["studies"], "overrides": task["overrides"],
           "folder": f"{POINTS}/{folder.name}", "worker": f"{socket.gethostname()}:{os.getpid()}",
           "software_version": __version__}
    try:
        scene = scene_from_dict(task["scene"], source=f"sweep point {task['id']}")
        # the sweep owns its points' folders: an earlier one is replaced whatever it holds
        with atomic_output_dir(folder, overwrite=True, command="sweep point", scene=scene) as tmp:
            metrics = _point_outputs(scene, Path(tmp), task["run"])
            rec.update(status="done", metrics=metrics, seconds=time.perf_counter() - t0)
            write_json(Path(tmp) / "point.json", rec)
    except RenderInspectError as err:
        rec.update(status="failed", folder=None, error=str(err), error_type=type(err).__name__,
                   seconds=time.perf_counter() - t0)
    except Exception as err:  # recorded with its traceback; the sweep goes on
        rec.update(status="failed", folder=None, error=f"{type(err).__name__}: {err}",
                   error_type=type(err).__name__, traceback=traceback.format_exc(),
                   seconds=time.perf_counter() - t0)
    return rec


# -------------------------------------------------------------------------- client
def _recover(out: Path, tasks, records: dict, results: ResultsLog) -> int:
    """Remove half-written point folders; adopt finished folders (``point.json``) that
    have no record yet (the client was stopped between a worker's write and the record)."""
    pts = out / POINTS
    n = 0
    if pts.is_dir():
        for d in pts.iterdir():
            if d.name.startswith(".") and ".partial-" in d.name:
                shutil.rmtree(d, ignore_errors=True)
    for t in tasks:
        pj = Path(t["folder"]) / "point.json"
        if t["id"] in records or not pj.is_file():
            continue
        try:
            rec = json.loads(pj.read_text())
        except ValueError:
            continue
        if rec.get("id") == t["id"] and rec.get("status") == "done":
            rec["studies"] = t["studies"]
            results.append(rec)
            records[t["id"]] = rec
            n += 1
    return n


def _finish(out: Path, spec, keys, tasks, invalid, records: dict, results: ResultsLog,
            info: dict) -> dict:
    """Compact results.jsonl; write results.csv, summary.md, sweep.json and the plots."""
    order = {t["id"]: t["index"] for t in [*tasks, *invalid]}
    studies = {t["id"]: t["studies"] for t in [*tasks, *invalid]}
    mine = sorted((r for i, r in records.items() if i in order), key=lambda r: order[r["id"]])
    for r in mine:
        r["studies"] = studies[r["id"]]
        r["index"] = order[r["id"]]
    others = [r for i, r in records.items() if i not in order]
    results.rewrite(mine + others)
    atomic_write_text(out / "results.csv", csv_text(mine, keys))
    done = sum(r["status"] == "done" for r in mine)
    failed = sum(r["status"] == "failed" for r in mine)
    total = len(tasks) + len(invalid)
    plots = spec.plot or default_plots(spec)
    names = []
    for i, p in enumerate(plots):
        name = p.name or f"plot_{i:02d}_{p.kind}"
        atomic_write_bytes(out / f"{name}.png", sweep_plot_png(p, plot_rows(mine, p)))
        names.append(f"{name}.png")
    info = {**info, "name": spec.name, "description": spec.description, "keys": keys,
            "points": total, "done": done, "failed": failed, "pending": total - done - failed,
            "records_from_other_sweeps": len(others), "plots": names,
            "run": spec.run.model_dump(mode="json"), "software_version": __version__}
    head = [f"# Sweep {spec.name}", "", spec.description, "",
            f"{total} points: {done} done, {failed} failed, {total - done - failed} not run.  "
            f"Sweep keys: {', '.join(keys) or '(none)'}.  Plots: {', '.join(names)}.", ""]
    atomic_write_text(out / "summary.md", "\n".join(head) + "\n" + summary_table(mine, keys))
    write_json(out / "sweep.json", info)
    return info


def _is_sweep_folder(folder: Path) -> bool:
    """A sweep's folder from before output folders were marked (``results.jsonl`` or
    ``sweep.toml`` in it)."""
    return (folder / "results.jsonl").is_file() or (folder / "sweep.toml").is_file()


def run_sweep(sweep, out, *, scheduler: str | None = None, workers: int | None = None,
              retry_failed: bool = False, progress: bool | None = None,
              overwrite: bool = False) -> dict:
    """``render-inspect sweep``: run every point of a sweep file on Dask.

    Parameters
    ----------
    sweep : path
        The sweep file (TOML; :mod:`render_inspect.batch` describes it).
    out : path
        The sweep's folder: ``results.jsonl``, ``results.csv``, ``summary.md``,
        ``sweep.json``, the plots (PNG) and ``points/<id>/`` (each point's outputs).  Points
        already recorded there are not run again.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); default: a LocalCluster.
    workers : int, optional
        Process workers of the LocalCluster (default: the CPU count, at most the points).
    retry_failed : bool
        Run again the points recorded as failed.
    progress : bool, optional
        A progress bar (default: when stderr is a terminal; log lines otherwise).
    overwrite : bool
        Write the sweep into a non-empty folder that is not a sweep's (its files are left
        in place); without it such a folder is refused before anything runs.

    Returns
    -------
    dict
        ``sweep.json``'s content: ``points``, ``done``, ``failed``, ``ran`` (this call),
        ``skipped``, ``elapsed_s``, ``workers``, ``dashboard``, ...
    """
    t_all = time.perf_counter()
    sweep_path = Path(sweep)
    spec = read_sweep(sweep_path, sections=scene_sections())
    out = check_output_path(out, replaced=False)
    tasks, invalid, keys = sweep_tasks(spec, sweep_path, out)
    claim_output_dir(out, command="sweep", overwrite=overwrite, resumable=_is_sweep_folder)
    with folder_lock(out):
        atomic_write_bytes(out / "sweep.toml", sweep_path.read_bytes())
        results = ResultsLog(out / "results.jsonl")
        records = results.read()
        recovered = _recover(out, tasks, records, results)
        for rec in invalid:
            old = records.get(rec["id"])
            if old is None or (retry_failed and old.get("status") == "failed"):
                results.append(rec)
                records[rec["id"]] = rec

        def pending(t):
            r = records.get(t["id"])
            return r is None or (retry_failed and r.get("status") == "failed")

        todo = [t for t in tasks if pending(t)]
        total = len(tasks) + len(invalid)
        skipped = total - len(todo) - len(invalid)
        info = {"sweep_file": str(sweep_path.resolve()), "out": str(out), "scheduler": scheduler,
                "workers": None, "dashboard": None, "ran": 0, "skipped": skipped,
                "recovered": recovered, "invalid": len(invalid)}
        log.info("sweep %s: %d points (%d to run, %d finished before, %d invalid)", spec.name,
                 total, len(todo), skipped, len(invalid))
        try:
            if todo:
                _run_on_dask(todo, records, results, info, scheduler=scheduler, workers=workers,
                             total=total, progress=progress)
        finally:
            info["elapsed_s"] = time.perf_counter() - t_all
            info = _finish(out, spec, keys, tasks, invalid, records, results, info)
    if info["points"] <= SHOW_TABLE_POINTS:
        log.info("%s", (out / "summary.md").read_text().split("\n\n", 3)[-1].rstrip())
    log.info("sweep %s: %d done, %d failed of %d points in %.1f s -> %s", spec.name,
             info["done"], info["failed"], info["points"], info["elapsed_s"], out)
    if info["failed"]:
        log.info("failed points are listed in %s (error column); rerun with --retry-failed "
                 "to try them again", out / "summary.md")
    return info


def _run_on_dask(todo, records, results, info, *, scheduler, workers, total, progress):
    from distributed import as_completed

    with dask_client(scheduler=scheduler, workers=workers, tasks=len(todo)) as client:
        nw = len(client.scheduler_info().get("workers", {}))
        info["workers"] = nw
        info["dashboard"] = dashboard_text(client)
        log.info("Dask: %d workers at %s; dashboard: %s", nw, client.scheduler.address,
                 info["dashboard"])
        prog = Progress(total, done=total - len(todo), desc="sweep", bar=progress)
        futures = {}
        for t in todo:
            futures[client.submit(run_point, t, key=f"render-inspect-point-{t['id']}",
                                  pure=False)] = t
        try:
            for fut in as_completed(futures):
                t = futures.pop(fut)
                try:
                    rec = fut.result()
                except Exception as err:  # the worker died or the task was lost: recorded
                    rec = {"id": t["id"], "index": t["index"], "params": t["params"],
                           "studies": t["studies"], "overrides": t["overrides"], "folder": None,
                           "status": "failed", "error": f"{type(err).__name__}: {err}",
                           "error_type": type(err).__name__, "software_version": __version__}
                results.append(rec)
                records[rec["id"]] = rec
                info["ran"] += 1
                ok = rec["status"] == "done"
                note = (f"{t['id']} Sq {rec['metrics']['residual']['Sq_nm']:.4g} nm" if ok
                        else f"{t['id']} failed: {rec['error'].splitlines()[0][:100]}")
                prog.update(note, failed=not ok)
        finally:
            for fut in futures:
                fut.cancel()
            prog.close()
