"""What ``regress`` writes when an image differs from its reference: an HTML page with the
image, the reference, their difference and the p-values side by side (the PNGs are drawn
by :func:`render_inspect.report.image_png`)."""

from __future__ import annotations

from collections.abc import Iterator
import contextlib
import html
import os
import shutil
import tempfile
from pathlib import Path

from ..core.errors import RenderInspectError
from ..io import atomic_write_text

__all__ = ["write_summary_html", "RegressionFailed", "replaced_dir"]

def write_summary_html(path: str | Path, results: list, meta: dict) -> Path:
    """The HTML summary: one row per image (case, image, test, numbers, result) and, for
    every image that failed, its PNGs side by side (paths relative to the page).

    ``results``: dicts with ``case``, ``image``, ``kind``, ``passed``, ``summary`` (text),
    ``pngs`` (list of (caption, relative path)) and optional ``error``.
    """
    path = Path(path)
    esc = html.escape
    n_fail = sum(not r["passed"] for r in results)
    rows = []
    for r in results:
        status = "pass" if r["passed"] else "FAIL"
        rows.append(f"<tr class='{status.lower()}'><td>{esc(r['case'])}</td><td>{esc(r['image'])}"
                    f"</td><td>{esc(r.get('kind', ''))}</td><td>{esc(r.get('summary', ''))}</td>"
                    f"<td><b>{status}</b></td></tr>")
    panels = []
    for r in results:
        if r["passed"] and not r.get("show"):
            continue
        cells = "".join(f"<figure><img src='{esc(p)}' alt='{esc(c)}'><figcaption>{esc(c)}"
                        f"</figcaption></figure>" for c, p in r.get("pngs", []))
        panels.append(f"<section><h3>{esc(r['case'])} / {esc(r['image'])}: "
                      f"{'pass' if r['passed'] else 'FAIL'}</h3><p>{esc(r.get('summary', ''))}"
                      f"</p>{('<p class=err>' + esc(r['error']) + '</p>') if r.get('error') else ''}"
                      f"<div class='row'>{cells}</div></section>")
    info = "".join(f"<li><b>{esc(str(k))}</b>: {esc(str(v))}</li>" for k, v in meta.items())
    page = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>render-inspect regress</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em; }}
table {{ border-collapse: collapse; }} td, th {{ border: 1px solid #ccc; padding: 3px 8px; font-size: 90%; }}
tr.fail td {{ background: #fdd; }} tr.pass td {{ background: #efe; }}
.row {{ display: flex; flex-wrap: wrap; gap: 12px; }}
figure {{ margin: 0; }} figcaption {{ font-size: 85%; max-width: 260px; }}
img {{ image-rendering: pixelated; border: 1px solid #999; }} .err {{ color: #a00; }}
</style></head><body>
<h1>Image regression: {len(results) - n_fail} of {len(results)} images match their references</h1>
<ul>{info}</ul>
<table><tr><th>case</th><th>image</th><th>test</th><th>result</th><th></th></tr>
{''.join(rows)}</table>
{''.join(panels)}
</body></html>
"""
    return atomic_write_text(path, page)


class RegressionFailed(RenderInspectError):
    """Images differ from their references (the command exits with code 1)."""


@contextlib.contextmanager
def replaced_dir(out: str | Path) -> Iterator[Path]:
    """Yield a new folder beside ``out``; on success it replaces ``out`` whole (old files
    do not linger); on an exception it is removed and ``out`` is left as it was."""
    out = Path(out).resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    os.chmod(tmp, 0o755)
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if out.exists():
        old = out.parent / f".{out.name}.old-{os.getpid()}"
        os.replace(out, old)
    os.replace(tmp, out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
