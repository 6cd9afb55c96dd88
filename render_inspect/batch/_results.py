"""The results of a sweep on disk: ``results.jsonl`` (one JSON object per finished point,
appended atomically), ``results.csv`` and the summary table.

``results.jsonl`` is written by one process only (the sweep's client, which holds the
folder's lock).  Each record is one ``write`` of one complete line followed by ``fsync``;
a line cut short by a kill is ignored when the file is read and dropped when it is next
compacted (:meth:`ResultsLog.rewrite`, an atomic replace).
"""

from __future__ import annotations

import contextlib
import csv
import fcntl
import io
import json
import os
from pathlib import Path

from ..core.errors import InputError
from ..io import atomic_write_text, json_safe

__all__ = ["ResultsLog", "flatten", "csv_text", "summary_table", "folder_lock",
           "SUMMARY_METRICS"]

#: Metrics shown in the summary table (when present).
SUMMARY_METRICS = ("residual.Sq_nm", "residual.Sz_nm", "residual.min_nm")


class ResultsLog:
    """``results.jsonl``: append-only, one record per line, read tolerantly.

    Parameters
    ----------
    path : path
        The file (created on the first append).
    """

    def __init__(self, path):
        self.path = Path(path)

    def read(self) -> dict:
        """Records by point id, in file order; a later record of an id replaces an
        earlier one; incomplete or unreadable lines are skipped."""
        out: dict = {}
        if not self.path.is_file():
            return out
        for line in self.path.read_bytes().split(b"\n"):
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
            except ValueError:
                continue  # a line cut short by a kill
            if isinstance(rec, dict) and isinstance(rec.get("id"), str):
                out.pop(rec["id"], None)
                out[rec["id"]] = rec
        return out

    def append(self, record: dict) -> None:
        """Append one record as one line (a single ``write``), then ``fsync``."""
        line = json.dumps(json_safe(record), sort_keys=True, allow_nan=False) + "\n"
        data = line.encode("utf-8")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
        try:
            # a file that ends without a newline ends in a cut line: start a fresh one
            if os.fstat(fd).st_size:
                with open(self.path, "rb") as fh:
                    fh.seek(-1, os.SEEK_END)
                    if fh.read(1) != b"\n":
                        data = b"\n" + data
            os.write(fd, data)
            os.fsync(fd)
        finally:
            os.close(fd)

    def rewrite(self, records) -> None:
        """Replace the file atomically with ``records`` (one line each)."""
        text = "".join(json.dumps(json_safe(r), sort_keys=True, allow_nan=False) + "\n"
                       for r in records)
        atomic_write_text(self.path, text)


@contextlib.contextmanager
def folder_lock(folder):
    """Hold an exclusive lock on ``folder/.lock`` (two sweeps must not write one folder)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    fh = open(folder / ".lock", "a+")
    try:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InputError(f"--out {str(folder)!r} is in use by another sweep (its .lock is "
                             f"held); wait for it to finish or choose another folder") from None
        yield
    finally:
        with contextlib.suppress(OSError):
            fcntl.flock(fh, fcntl.LOCK_UN)
        fh.close()


def flatten(d, prefix: str = "") -> dict:
    """Scalar leaves of nested dicts as ``{"a.b": value}`` (lists are left out)."""
    out = {}
    if not isinstance(d, dict):
        return out
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, key + "."))
        elif isinstance(v, (list, tuple)):
            continue
        else:
            out[key] = v
    return out


def _cell(v):
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (list, tuple, dict)):
        return json.dumps(v)
    return v


def csv_text(records, param_keys) -> str:
    """``results.csv``: one row per record: ``id``, ``status``, the sweep keys, ``studies``,
    ``folder``, ``seconds``, ``error``, then every scalar metric (``metrics.<dotted>``)."""
    records = list(records)
    metric_cols: list[str] = []
    flat = []
    for r in records:
        f = flatten(r.get("metrics") or {})
        flat.append(f)
        for k in f:
            if k not in metric_cols:
                metric_cols.append(k)
    head = ["id", "status", *param_keys, "studies", "folder", "seconds", "error"]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(head + [f"metrics.{k}" for k in metric_cols])
    for r, f in zip(records, flat):
        params = r.get("params") or {}
        row = [r.get("id"), r.get("status"), *(_cell(params.get(k)) for k in param_keys),
               ";".join(r.get("studies") or []), _cell(r.get("folder")), _cell(r.get("seconds")),
               (r.get("error") or "").splitlines()[0] if r.get("error") else ""]
        w.writerow([_cell(x) for x in row] + [_cell(f.get(k)) for k in metric_cols])
    return buf.getvalue()


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def summary_table(records, param_keys, *, metrics=SUMMARY_METRICS) -> str:
    """A Markdown table: one row per point (sweep keys, status, the chosen metrics,
    seconds, the error's first line)."""
    records = list(records)
    shown = [m for m in metrics if any(flatten(r.get("metrics") or {}).get(m) is not None
                                       for r in records)]
    head = ["point", *param_keys, "status", *shown, "seconds", "error"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in records:
        f = flatten(r.get("metrics") or {})
        params = r.get("params") or {}
        err = (r.get("error") or "").splitlines()[0][:120] if r.get("error") else ""
        cells = [r.get("id", ""), *(_fmt(params.get(k)) for k in param_keys), r.get("status", ""),
                 *(_fmt(f.get(m)) for m in shown), _fmt(r.get("seconds")), err.replace("|", "/")]
        lines.append("| " + " | ".join(str(c) for c in cells) + " |")
    return "\n".join(lines) + "\n"
