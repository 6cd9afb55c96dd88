"""A self-contained HTML page: images embedded as base64 data URIs, inline CSS, no
scripts and no external links, so the file can be mailed or archived on its own."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
import base64
import html
import json
import re

from ._format import fmt_number

__all__ = ["HtmlReport", "data_uri", "table_html"]

_CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',Helvetica,Arial,sans-serif;margin:24px;
color:#1d2329;background:#fff;max-width:1400px}
h1{font-size:24px;margin:0 0 4px 0}h2{font-size:19px;border-bottom:2px solid #d0d7de;
padding-bottom:4px;margin-top:32px}h3{font-size:15px;margin:18px 0 6px 0}
p.lead{color:#57606a;margin-top:0}
table{border-collapse:collapse;margin:8px 0 16px 0;font-size:13px}
th,td{border:1px solid #d0d7de;padding:4px 8px;text-align:right;vertical-align:top}
th{background:#f6f8fa;text-align:left}td.k{text-align:left;font-family:monospace}
figure{margin:8px 0 18px 0}figure img{max-width:100%;border:1px solid #eaeef2}
figcaption{font-size:13px;color:#57606a;margin-top:4px;max-width:1100px}
pre{background:#f6f8fa;padding:10px;font-size:12px;overflow:auto;max-height:420px}
.note{background:#fff8c5;border:1px solid #d4a72c;padding:6px 10px;font-size:13px}
.good{color:#1a7f37}.bad{color:#cf222e}
nav a{margin-right:12px;font-size:13px}ul{font-size:14px}
ul.warn{background:#fff8c5;border:1px solid #d4a72c;padding:6px 10px 6px 28px}
td.hash{font-family:monospace;font-size:12px;word-break:break-all;text-align:left}
@media print{body{margin:0;max-width:none;font-size:11pt}nav{display:none}
figure,table,ul.warn{break-inside:avoid}h2,h3{break-after:avoid}
figure img{max-width:100%;border:none}pre{max-height:none;overflow:visible;white-space:pre-wrap}}
"""


#: a SHA-256 in hex: set in a monospace cell that may break
_HASH = re.compile(r"[0-9a-f]{64}")


def data_uri(png: bytes, mime: str = "image/png") -> str:
    """``data:`` URI of an image (base64)."""
    return f"data:{mime};base64," + base64.b64encode(png).decode("ascii")


def _fmt(v: object) -> str:
    if v is None or isinstance(v, (bool, int, float)):
        return html.escape(fmt_number(v, sig=4))
    if isinstance(v, (list, tuple)):
        return ", ".join(_fmt(x) for x in v)
    if isinstance(v, dict):
        return html.escape(json.dumps(v, default=str))
    return html.escape(str(v))


def table_html(rows: Iterable[Sequence[object]], *, header: Sequence[str] | None = None,
               key_first: bool = True) -> str:
    """An HTML table.  ``rows``: list of lists (first cell is the row key when
    ``key_first``); ``header``: column titles."""
    out = ["<table>"]
    if header:
        out.append("<tr>" + "".join(f"<th>{html.escape(str(h))}</th>" for h in header) + "</tr>")
    for r in rows:
        cells = []
        for i, c in enumerate(r):
            cls = ' class="k"' if key_first and i == 0 else (
                ' class="hash"' if isinstance(c, str) and _HASH.fullmatch(c) else "")
            txt = html.escape(str(c)) if key_first and i == 0 else _fmt(c)
            cells.append(f"<td{cls}>{txt}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


class HtmlReport:
    """Build the page section by section, then :meth:`render` it."""

    def __init__(self, title: str, subtitle: str = ""):
        self.title = title
        self.subtitle = subtitle
        self.parts: list[str] = []
        self.toc: list[tuple[str, str]] = []

    def section(self, title: str) -> None:
        anchor = "s" + str(len(self.toc) + 1)
        self.toc.append((anchor, title))
        self.parts.append(f'<h2 id="{anchor}">{html.escape(title)}</h2>')

    def heading(self, title: str) -> None:
        self.parts.append(f"<h3>{html.escape(title)}</h3>")

    def text(self, text: str, *, cls: str | None = None) -> None:
        c = f' class="{cls}"' if cls else ""
        self.parts.append(f"<p{c}>{html.escape(text)}</p>")

    def figure(self, png: bytes, caption: str = "", *, alt: str = "") -> None:
        self.parts.append(f'<figure><img alt="{html.escape(alt or caption[:80])}" '
                          f'src="{data_uri(png)}"><figcaption>{html.escape(caption)}'
                          f"</figcaption></figure>")

    def table(self, rows: Iterable[Sequence[object]], *,
              header: Sequence[str] | None = None) -> None:
        self.parts.append(table_html(rows, header=header))

    def list(self, items: Iterable[object], *, cls: str | None = None) -> None:
        c = f' class="{cls}"' if cls else ""
        self.parts.append(f"<ul{c}>" + "".join(f"<li>{html.escape(str(i))}</li>" for i in items)
                          + "</ul>")

    def pre(self, text: str) -> None:
        self.parts.append(f"<pre>{html.escape(text)}</pre>")

    def render(self) -> str:
        nav = " ".join(f'<a href="#{a}">{html.escape(t)}</a>' for a, t in self.toc)
        return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
                f"<title>{html.escape(self.title)}</title><style>{_CSS}</style></head><body>\n"
                f"<h1>{html.escape(self.title)}</h1>\n<p class=\"lead\">{html.escape(self.subtitle)}</p>\n"
                f"<nav>{nav}</nav>\n" + "\n".join(self.parts) + "\n</body></html>\n")
