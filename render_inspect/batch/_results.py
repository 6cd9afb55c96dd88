"""The results of a sweep on disk: ``results.jsonl`` (one JSON object per finished point,
appended atomically), ``results.csv`` and the summary table.

``results.jsonl`` is written by one process only (the sweep's client, which holds the
folder's lock).  Each record is one ``write`` of one complete line followed by ``fsync``;
a line cut short by a kill is ignored when the file is read and dropped when it is next
compacted (:meth:`ResultsLog.rewrite`, an atomic replace).
"""

from __future__ import annotations

from typing import Any
from collections.abc import Iterable, Iterator, Sequence
import contextlib
import csv
import fcntl
import io
import json
import os
import re
from pathlib import Path

from ..core.errors import InputError
from ..io import atomic_write_text, json_safe, open_lock_file

__all__ = ["ResultsLog", "flatten", "csv_text", "summary_table", "folder_lock",
           "SUMMARY_METRICS", "csv_safe", "md_text"]

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

    def rewrite(self, records: Iterable[dict]) -> None:
        """Replace the file atomically with ``records`` (one line each)."""
        text = "".join(json.dumps(json_safe(r), sort_keys=True, allow_nan=False) + "\n"
                       for r in records)
        atomic_write_text(self.path, text)


@contextlib.contextmanager
def folder_lock(folder: str | Path) -> Iterator[None]:
    """Hold an exclusive lock on ``folder/.lock`` (two sweeps must not write one folder).

    The lock file is opened as every output folder's lock is
    (:func:`render_inspect.io.open_lock_file`: never through a symbolic link, never a
    file that holds more than a process id); it holds the process id while locked."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    fd = open_lock_file(folder / ".lock", option="--out", out_text=str(folder))
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = ""
            with contextlib.suppress(OSError, ValueError):
                txt = os.pread(fd, 64, 0).decode().strip()
                holder = f" (process {txt})" if txt.isdigit() else ""
            raise InputError(f"--out {str(folder)!r} is in use by another sweep{holder} (its "
                             f".lock is held); wait for it to finish or choose another "
                             f"folder") from None
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield
    finally:
        with contextlib.suppress(OSError):
            fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)


def flatten(d: dict, prefix: str = "") -> dict:
    """Scalar leaves of nested dicts as ``{"a.b": value}`` (lists are left out)."""
    out: dict = {}
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


#: first characters that make a spreadsheet read a cell as a formula (OWASP, "CSV
#: injection"): such text cells get a leading apostrophe
_FORMULA_START = ("=", "+", "-", "@", "\t", "\r", "\n")


def csv_safe(v: Any) -> Any:
    """A CSV cell that a spreadsheet shows as text: text starting with ``= + - @``, a tab
    or a line break is prefixed with an apostrophe (numbers are written as numbers)."""
    if isinstance(v, str) and v.startswith(_FORMULA_START):
        return "'" + v
    return v


def _cell(v):
    if v is None:
        return ""
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (list, tuple, dict)):
        return csv_safe(json.dumps(v))
    return csv_safe(v)


def csv_text(records: Iterable[dict], param_keys: Sequence[str], *,
             columns: dict | None = None) -> str:
    """``results.csv``: one row per record: ``id``, ``status``, the scene keys
    (``param_keys``, named by ``columns``: key -> column name, the key itself by default),
    ``studies``, ``folder``, ``seconds``, ``error``, then every scalar metric
    (``metrics.<dotted>``, units in their names).  Text cells that a spreadsheet would
    read as a formula are written as text (:func:`csv_safe`)."""
    columns = columns or {}
    records = list(records)
    metric_cols: list[str] = []
    flat = []
    for r in records:
        f = flatten(r.get("metrics") or {})
        flat.append(f)
        for k in f:
            if k not in metric_cols:
                metric_cols.append(k)
    head = ["id", "status", *(columns.get(k, k) for k in param_keys), "studies", "folder",
            "seconds", "error"]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([csv_safe(h) for h in head] + [csv_safe(f"metrics.{k}") for k in metric_cols])
    for r, f in zip(records, flat):
        params = r.get("params") or {}
        row = [r.get("id"), r.get("status"), *(params.get(k) for k in param_keys),
               ";".join(r.get("studies") or []), r.get("folder"), r.get("seconds"),
               (r.get("error") or "").splitlines()[0] if r.get("error") else ""]
        w.writerow([_cell(x) for x in row] + [_cell(f.get(k)) for k in metric_cols])
    return buf.getvalue()


#: characters with a meaning anywhere in a line of Markdown (code, emphasis, links, HTML,
#: tables, strike-through); ``_`` only at a word's edge (``nose_radius`` stays as it is)
_MD_INLINE = re.compile(r"([\\`*\[\]<>|~&]|(?<![A-Za-z0-9])_|_(?![A-Za-z0-9]))")
#: what gives a line of Markdown a meaning at its start (headings, quotes, lists, rules)
_MD_LINE_START = re.compile(r"^(\s*)([#>+=-]|\d+[.)])")


def _escape_start(m) -> str:
    mark = m.group(2)
    if mark[0].isdigit():  # an ordered list's "1." is escaped at its dot
        return m.group(1) + mark[:-1] + "\\" + mark[-1]
    return m.group(1) + "\\" + mark


def md_text(v: Any, *, block: bool = False) -> str:
    """``v`` as literal Markdown text: the characters that would format it escaped and,
    unless ``block``, line breaks turned into spaces (a value cannot start a heading or
    break a table); a ``block`` keeps its lines, each escaped, its start too."""
    text = "" if v is None else str(v)
    lines = text.splitlines() if block else [" ".join(text.split())]
    out = []
    for ln in lines:
        ln = _MD_INLINE.sub(r"\\\1", ln)
        out.append(_MD_LINE_START.sub(_escape_start, ln))
    return "\n".join(out)


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, (int, bool)):
        return str(v)
    return md_text(json.dumps(v) if isinstance(v, (list, tuple, dict)) else v)


def summary_table(records: Iterable[dict], param_keys: Sequence[str], *,
                  metrics: Sequence[str] = SUMMARY_METRICS) -> str:
    """A Markdown table: one row per point (sweep keys, status, the chosen metrics,
    its run time in seconds, the error's first line)."""
    records = list(records)
    shown = [m for m in metrics if any(flatten(r.get("metrics") or {}).get(m) is not None
                                       for r in records)]
    head = ["point", *param_keys, "status", *shown, "run time (s)", "error"]
    lines = ["| " + " | ".join(md_text(h) for h in head) + " |", "|" + "---|" * len(head)]
    for r in records:
        f = flatten(r.get("metrics") or {})
        params = r.get("params") or {}
        err = (r.get("error") or "").splitlines()[0][:120] if r.get("error") else ""
        cells = [md_text(r.get("id", "")), *(_fmt(params.get(k)) for k in param_keys),
                 md_text(r.get("status", "")), *(_fmt(f.get(m)) for m in shown),
                 _fmt(r.get("seconds")), md_text(err)]
        lines.append("| " + " | ".join(str(c) for c in cells) + " |")
    return "\n".join(lines) + "\n"
