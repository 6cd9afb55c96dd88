"""``sweep``: one scene, many parameter values, run on Dask; resumable.

Each point of a sweep file (:mod:`render_inspect.batch`) is the base scene with its
overrides, validated here; its identity is a hash of the resolved scene and of what it
runs (``[run]``), so the same point in another sweep or a re-run is recognised.  The
client process (the one that calls :func:`run_sweep`) is the only writer of
``results.jsonl``; workers write each point's folder atomically, last its ``point.json``.
"""

from __future__ import annotations

import contextlib
import difflib
import json
import logging
import os
import shutil
import socket
import time
import traceback
from importlib import resources
from pathlib import Path
from typing import Any

from .. import __version__
from ..batch import (
    MACHINING_TIME,
    SUMMARY_METRICS,
    flatten,
    Progress,
    ResultsLog,
    SweepFile,
    call_with_threads,
    check_scheduler,
    check_workers_option,
    cluster_info,
    wait_for_workers,
    csv_text,
    dask_client,
    default_plots,
    dotted_get,
    expand_points,
    fixed_keys,
    folder_lock,
    md_text,
    plot_rows,
    point_id,
    read_sweep,
    summary_table,
    sweep_keys,
    toml_value,
)
from ..core.errors import InputError, RenderInspectError, SceneError
from ..core.limits import format_bytes, memory_budget
from ..core.units import MIB_TO_BYTES, MM_TO_NM
from ..io import (
    MARKER, atomic_output_dir, atomic_write_bytes,
    atomic_write_text,
    check_output_path,
    claim_output_dir, discarding_new_folder,
    write_json,
)
from ..processes import check_budget, cut_name, process_of
from ..scene import Scene, find_scene, load_scene, scene_from_dict, scene_sections
from ..report import morris_png, save_map_png, sweep_plot_png
from ._compare import run_compare
from ._measure import measure_and_evaluate
from ._metrics import point_metrics, write_metrics
from ._render import run_render, sweep_render_names
from ._simulate import residual_title, simulate, write_simulation
from ._sweep_check import check_sweep_tasks, failure_lines
from ._sweep_morris import morris_table, sweep_morris
from ._sweep_report import (add_machining_times, check_select_names, check_sweep_size, column_names, estimate_text,
                            first_record_check, point_seconds, selection, sweep_estimate)
from ._toolpath import check_tool_edge

__all__ = ["run_sweep", "run_point", "sweep_tasks", "find_sweep", "shipped_sweeps",
           "column_names", "check_sweep_tasks", "sweep_failure", "sweep_morris"]

log = logging.getLogger("render_inspect")

POINTS = "points"
#: The summary table is also printed for sweeps of at most this many points.
SHOW_TABLE_POINTS = 30
#: what a point's renders add to its simulation at the peak (Mitsuba 3, llvm_ad_rgb:
#: 446 - 658 MB measured above the simulation on the shipped sinusoidal grid; docs/limits.md)
RENDER_BYTES = 700 * MIB_TO_BYTES


def shipped_sweeps() -> dict[str, Path]:
    """The sweeps that ship with the package (``scenes/sweeps/``): name -> path."""
    root = resources.files("render_inspect") / "scenes" / "sweeps"
    return {p.name[:-5]: Path(str(p)) for p in sorted(root.iterdir(), key=lambda q: q.name)
            if p.name.endswith(".toml")}


def find_sweep(name_or_path: str | Path) -> Path:
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
    """The base scene: a path relative to the sweep file, else a shipped scene's name;
    loaded once here so that a scene that is not one is refused before any point."""
    rel = sweep_path.parent / spec.scene
    where = f"sweep file {str(sweep_path)!r}: scene = {spec.scene!r}"
    try:
        base = rel.resolve() if rel.is_file() else find_scene(spec.scene)
        load_scene(base, [])
    except SceneError as err:
        raise SceneError(f"{where}: {err}") from None
    except (OSError, ValueError) as err:
        raise SceneError(f"{where}: cannot be read ({type(err).__name__}: {err})") from None
    return base


def _point_memory(scene: Scene, run: dict) -> int:
    """Bytes one point holds at its peak: the process's estimate, checked against the
    memory budget (a point that cannot fit is not valid), and the renders it runs.  A
    measured cutting edge the point's cut cannot take makes it not valid too."""
    check_tool_edge(scene)
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    sim = scene.simulation
    process.precheck(cfg, tuple(sim.region))
    need = check_budget(sim, process.estimate_memory(cfg))
    return int(need) + (RENDER_BYTES if run.get("render", "none") != "none" else 0)


def sweep_tasks(spec: SweepFile, sweep_path: str | Path, out: str | Path
                ) -> tuple[list[dict], list[dict], list[str]]:
    """Resolve every point of ``spec`` into a task for :func:`run_point`.

    The base scene is read first (a scene that is not one is an error naming the sweep
    file); each point is its scene with the point's overrides, validated, and its memory
    checked against the budget.

    Returns
    -------
    tasks : list of dict
        ``id``, ``index``, ``params`` (the sweep keys and the keys ``set`` fixes, as the
        resolved scene has them), ``studies``, ``overrides``, ``scene`` (validated, as a
        dict), ``run``, ``folder`` (absolute path of the point's folder),
        ``memory_bytes`` (the point's estimated peak), ``estimate_s`` (a rough time).
    invalid : list of dict
        Points whose scene does not validate or does not fit the memory budget:
        ``index``, ``overrides``, ``error`` (:func:`run_sweep` refuses a sweep with any).
    keys : list of str
        The sweep keys (they vary).
    """
    sweep_path = Path(sweep_path)
    base = _base_scene(spec, sweep_path)
    keys = sweep_keys(spec)
    fixed = fixed_keys(spec)
    run = spec.run.model_dump(mode="json")
    by_id: dict = {}
    invalid: list = []
    for p in expand_points(spec):
        sets = [f"{k}={toml_value(v)}" for k, v in p.overrides.items()]
        try:
            scene = load_scene(base, sets)
            memory = _point_memory(scene, run)
        except RenderInspectError as err:
            invalid.append({"index": p.index, "overrides": p.overrides,
                            "studies": list(p.studies), "error": str(err),
                            "error_type": type(err).__name__})
            continue
        sd = scene.to_dict()
        pid = point_id({"scene": sd, "run": run})
        if pid in by_id:  # another override set that gives the same scene
            t = by_id[pid]
            t["studies"] += [s for s in p.studies if s not in t["studies"]]
            continue
        by_id[pid] = {"id": pid, "index": p.index,
                      "params": {k: dotted_get(sd, k) for k in [*keys, *fixed]},
                      "studies": list(p.studies), "overrides": p.overrides, "scene": sd,
                      "run": run, "folder": str(Path(out).resolve() / POINTS / pid),
                      "memory_bytes": memory, "estimate_s": point_seconds(scene)}
    return list(by_id.values()), invalid, keys


# ------------------------------------------------------------------------ on a worker
def _residual_png(sim, path: Path) -> None:
    hm, scene = sim.heightmap, sim.scene
    r = sim.metrics["residual"]
    save_map_png(path, (hm.residual - r["mean_nm"] / MM_TO_NM) * MM_TO_NM, extent=hm.extent,
                 cmap="RdBu_r", symmetric=True, label="machined - design (nm)",
                 title=residual_title(cut_name(scene), sim.traits, r))


def _point_outputs(scene: Scene, folder: Path, run: dict) -> dict:
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


def _finish(out: Path, spec, keys, tasks, records: dict, results: ResultsLog,
            info: dict, *, plots: bool = True) -> dict:
    """Compact results.jsonl; write results.csv, summary.md, sweep.json and the plots
    (``plots`` False: those of an earlier run are left as they are)."""
    order = {t["id"]: t["index"] for t in tasks}
    studies = {t["id"]: t["studies"] for t in tasks}
    mine = sorted((r for i, r in records.items() if i in order), key=lambda r: order[r["id"]])
    for r in mine:
        r["studies"] = studies[r["id"]]
        r["index"] = order[r["id"]]
    others = [r for i, r in records.items() if i not in order]
    add_machining_times(tasks, mine)
    results.rewrite(mine + others)
    fixed = fixed_keys(spec)
    scene = scene_from_dict(tasks[0]["scene"], source="sweep point") if tasks else None
    columns = column_names(scene, [*keys, *fixed])
    atomic_write_text(out / "results.csv", csv_text(mine, [*keys, *fixed], columns=columns))
    done = sum(r["status"] == "done" for r in mine)
    failed = sum(r["status"] == "failed" for r in mine)
    total = len(tasks)
    draw = plots
    specs = spec.plot or default_plots(spec)
    names = []
    for i, p in enumerate(specs if draw else []):
        name = p.name or f"plot_{i:02d}_{p.kind}"
        rows = plot_rows(mine, p)
        metric = p.y if p.kind == "curves" else p.value
        if not rows and done:
            # finished points, none with the metric: a name the metrics do not have
            known = sorted({k for r in mine if r.get("status") == "done"
                            for k in flatten(r.get("metrics") or {})})
            close = difflib.get_close_matches(str(metric), known, n=1)
            log.warning("warning: plot %s: no finished point has the metric %r%s", name, metric,
                        f"; did you mean {close[0]!r}?" if close else "")
        atomic_write_bytes(out / f"{name}.png", sweep_plot_png(p, rows))
        names.append(f"{name}.png")
    morris_lines = []
    if spec.morris is not None:
        morris = sweep_morris(spec, mine)
        write_json(out / "morris.json", morris)
        for name in spec.morris.outputs if draw else []:
            png = f"morris_{name.replace('.', '_')}.png"
            atomic_write_bytes(out / png, morris_png(morris, name, title=f"{spec.name}: {name}"))
            names.append(png)
        morris_lines = morris_table(morris)
    info = {**info, "name": spec.name, "description": spec.description, "keys": keys,
            "fixed_keys": fixed, "columns": columns,
            "points": total, "done": done, "failed": failed, "pending": total - done - failed,
            "records_from_other_sweeps": len(others), "plots": names,
            "failure_lines": failure_lines([r for r in mine if r["status"] == "failed"], total),
            "run": spec.run.model_dump(mode="json"), "software_version": __version__}
    select_text, chosen = selection(spec, keys, mine)
    info["select"] = chosen
    info["select_lines"] = select_text
    fixed_text = ", ".join(f"{md_text(k)} = {md_text(toml_value(tasks[0]['params'].get(k)))}"
                           for k in fixed) if tasks else ""
    head = [f"# Sweep {md_text(spec.name)}", "", md_text(spec.description, block=True), "",
            f"{total} points: {done} done, {failed} failed, {total - done - failed} not run.  "
            f"Sweep keys: {md_text(', '.join(keys)) or '(none)'}.  "
            f"Fixed for every point: {fixed_text or '(none)'}.  "
            f"Plots: {md_text(', '.join(names))}.", ""]
    if others:
        head += [f"{len(others)} records in results.jsonl are of points this sweep file no longer "
                 f"has (an earlier version of it); they are kept there, not in this summary "
                 f"or results.csv.", ""]
    head += [*(md_text(line) for line in select_text), ""] if select_text else []
    shown = [MACHINING_TIME, *SUMMARY_METRICS, *(spec.select.metrics() if spec.select else [])]
    atomic_write_text(out / "summary.md", "\n".join(head) + "\n"
                      + summary_table(mine, keys, metrics=list(dict.fromkeys(shown)))
                      + ("\n" + "\n".join(morris_lines) + "\n" if morris_lines else ""))
    write_json(out / "sweep.json", info)
    return info


def _is_sweep_folder(folder: Path) -> bool:
    """A sweep's folder from before output folders were marked (``results.jsonl`` or
    ``sweep.toml`` in it)."""
    return (folder / "results.jsonl").is_file() or (folder / "sweep.toml").is_file()


def run_sweep(sweep: str | Path, out: str | Path, *, scheduler: str | None = None,
              workers: int | None = None, client: Any = None, retry_failed: bool = False,
              progress: bool | None = None, overwrite: bool = False, yes: bool = False) -> dict:
    """``render-inspect sweep``: run every point of a sweep file on Dask.

    The whole sweep is checked before the first point runs: the file, its names, the
    number of points (at most :data:`render_inspect.batch.MAX_POINTS`), the base scene,
    and every point's scene and memory; any error refuses the sweep with one message and
    nothing is written.

    Parameters
    ----------
    sweep : path
        The sweep file (TOML; :mod:`render_inspect.batch` describes it).
    out : path
        The sweep's folder: ``results.jsonl``, ``results.csv``, ``summary.md``,
        ``sweep.json``, the plots (PNG) and ``points/<id>/`` (each point's outputs).  Points
        already recorded there are not run again.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``).
    workers : int, optional
        Process workers of a new LocalCluster (default: the CPU count), capped by the CPU
        count, the points to run and the memory budget (the log says which applied).
    client : distributed.Client, optional
        Run on this client (a notebook's, for example; left open).  Without ``client``,
        ``scheduler`` and ``workers``, a client open in this process
        (``distributed.get_client()``) is used, else a new LocalCluster.
    retry_failed : bool
        Run again the points recorded as failed.
    progress : bool, optional
        A progress bar (default: when stderr is a terminal; log lines otherwise).
    overwrite : bool
        Write the sweep into a non-empty folder that is not a sweep's (its files are left
        in place); without it such a folder is refused before anything runs.
    yes : bool
        Run a sweep with more than ``CONFIRM_POINTS`` (500) points still to run in
        ``out``; without it such a sweep is refused, with its size and a rough time,
        before anything runs.

    Returns
    -------
    dict
        ``sweep.json``'s content: ``points``, ``done``, ``failed``, ``ran`` (this call),
        ``skipped``, ``elapsed_s``, ``workers``, ``dashboard``, ``columns`` (the scene key
        of each ``results.csv`` column), ...
    """
    t_all = time.perf_counter()
    sweep_path = Path(sweep)
    spec = read_sweep(sweep_path, sections=scene_sections(), **sweep_render_names())
    out = check_output_path(out, replaced=False)
    tasks, invalid, keys = sweep_tasks(spec, sweep_path, out)
    check_sweep_tasks(sweep_path, tasks, invalid)
    check_workers_option(workers)
    if scheduler is not None:  # before the folder is made: an address that is no scheduler
        scheduler = check_scheduler(scheduler)

    def pending(t, records):
        r = records.get(t["id"])
        return r is None or (retry_failed and r.get("status") == "failed")

    # the cluster is reached (or its workers started) before the folder is claimed: a
    # cluster without workers is refused with nothing written
    before = ResultsLog(out / "results.jsonl").read() if out.is_dir() else {}
    todo_before = [t for t in tasks if pending(t, before)]
    n_todo = len(todo_before)
    estimate = sweep_estimate(todo_before, workers if scheduler is None and client is None
                              else None, [r for r in before.values()])
    check_sweep_size(sweep_path, estimate, len(tasks), yes=yes)
    check_select_names(spec, tasks, [r for r in before.values()], source=sweep_path)
    with contextlib.ExitStack() as stack:
        c = None
        if n_todo:
            c = stack.enter_context(dask_client(
                client=client, scheduler=scheduler, workers=workers, tasks=n_todo, wait=False,
                memory_per_task=max(t["memory_bytes"] for t in tasks), budget=memory_budget(None)))
        stack.enter_context(discarding_new_folder(out, (MARKER, ".lock", "sweep.toml")))
        claim_output_dir(out, command="sweep", overwrite=overwrite, resumable=_is_sweep_folder)
        with folder_lock(out):
            atomic_write_bytes(out / "sweep.toml", sweep_path.read_bytes())
            results = ResultsLog(out / "results.jsonl")
            records = results.read()
            recovered = _recover(out, tasks, records, results)
            todo = [t for t in tasks if pending(t, records)]
            total = len(tasks)
            skipped = total - len(todo) - recovered  # ran + skipped + recovered = total
            info: dict[str, Any] = {"sweep_file": str(sweep_path.resolve()), "out": str(out),
                                    "scheduler": scheduler, "workers": None, "dashboard": None,
                                    "ran": 0, "skipped": skipped, "recovered": recovered}
            log.info("sweep %s: %d points (%d to run, %d finished before)%s", spec.name, total,
                     len(todo), total - len(todo),
                     f"; {estimate_text(estimate)}" if todo else "")
            stopped = False
            try:
                if todo and c is not None:
                    _run_on_dask(c, todo, records, results, info, total=total, progress=progress,
                                 check=first_record_check(spec, sweep_path))
            except KeyboardInterrupt:
                stopped = True  # stop within a second or two: no plots (the next run draws them)
                raise
            finally:
                info["elapsed_s"] = time.perf_counter() - t_all
                info = _finish(out, spec, keys, tasks, records, results, info,
                               plots=not stopped)
    if info["points"] <= SHOW_TABLE_POINTS and info["done"]:  # else the failures say it all
        log.info("%s", (out / "summary.md").read_text().split("| point |", 1)[-1].join(
            ["| point |", ""]).rstrip())
    if info["records_from_other_sweeps"]:
        log.info("sweep %s: %d records in %s are of points this sweep file no longer has (an "
                 "earlier version of it): kept there, left out of results.csv and summary.md",
                 spec.name, info["records_from_other_sweeps"], out / "results.jsonl")
    for line in info.get("select_lines") or []:
        log.info("%s", line)
    log.info("sweep %s: %d done, %d failed of %d points in %.1f s -> %s", spec.name,
             info["done"], info["failed"], info["points"], info["elapsed_s"], out)
    if info["failed"]:
        log.info("failed points are listed in %s (error column); rerun with --retry-failed "
                 "to try them again", out / "summary.md")
    return info


def sweep_failure(info: dict, out: str | Path) -> str | None:
    """The command line's message for a sweep with failed points (None when none
    failed): how many failed, how many are done and how many did not run, then one line
    for each reason the points failed (points alike but for the numbers in their
    messages are one reason), with its points."""
    if not info.get("failed"):
        return None
    done, pending = info.get("done", 0), info.get("pending", 0)
    rest = (f"{done} point{'s are' if done != 1 else ' is'} done" if done else
            "no point is done")
    if pending:
        rest += f", {pending} did not run"
    lines = info.get("failure_lines") or []
    return (f"{info['failed']} of {info['points']} points failed (their errors are in "
            f"{out}/summary.md and results.csv); {rest}; rerun with --retry-failed to try "
            f"the failed ones again" + (
                "; point numbers count from 0 in the order of the sweep file, a number that "
                "differs between the points of one line is given as its range:\n"
                + "\n".join(lines) if lines else ""))


def _failed(t: dict, err: BaseException, memory_limit) -> dict:
    """The record of a point whose task did not return (its worker died or was lost)."""
    name = type(err).__name__
    text = f"{name}: {err}"
    if name == "KilledWorker":
        text = ("the Dask worker running the point died (" + (
            f"it may have exceeded its memory limit of {format_bytes(memory_limit)}, "
            if memory_limit else "") + f"{name})")
    return {"id": t["id"], "index": t["index"], "params": t["params"], "studies": t["studies"],
            "overrides": t["overrides"], "folder": None, "status": "failed", "error": text,
            "error_type": name, "software_version": __version__}


def _run_on_dask(c, todo, records, results, info, *, total, progress, check=None):
    from distributed import as_completed

    ci = cluster_info(c)
    nw = wait_for_workers(c, label="sweep", n=getattr(c, "expected_workers", None))
    info["workers"] = nw
    info["dashboard"] = ci["dashboard"]
    info["cluster"] = {k: ci.get(k) for k in ("kind", "workers", "threads", "capped",
                                              "memory_limit_bytes")}
    log.info("Dask: %d workers at %s; dashboard: %s", nw, c.scheduler.address, ci["dashboard"])
    prog = Progress(total, done=total - len(todo), desc="sweep", bar=progress)
    futures = {}
    for t in todo:
        futures[c.submit(call_with_threads, ci["threads"], run_point, t,
                         key=f"render-inspect-point-{t['id']}", pure=False)] = t
    try:
        for fut in as_completed(futures, loop=c.loop):
            t = futures.pop(fut)
            try:
                rec = fut.result()
            except Exception as err:  # the worker died or the task was lost: recorded
                rec = _failed(t, err, ci.get("memory_limit_bytes"))
            results.append(rec)
            records[rec["id"]] = rec
            info["ran"] += 1
            ok = rec["status"] == "done"
            if ok and check is not None:
                check(rec, t)  # the first finished point: the [select] metrics exist
                check = None
            note = (f"{t['id']} Sq {rec['metrics']['residual']['Sq_nm']:.4g} nm" if ok
                    else f"{t['id']} failed: {rec['error'].splitlines()[0][:100]}")
            prog.update(note, failed=not ok)
    finally:
        for fut in futures:
            fut.cancel()
        prog.close()
