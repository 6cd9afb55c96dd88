"""Tables as CSV text: rows of numbers and text under named columns."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
__all__ = ["table_csv"]


def table_csv(rows: Iterable[dict], keys: Sequence[str]) -> str:
    """CSV text of ``rows`` (dicts) in the columns ``keys``: numbers with 6 significant
    digits, text as it is, an empty cell where a row lacks the key or holds None."""
    lines = [",".join(keys)]
    for r in rows:
        lines.append(",".join("" if r.get(k) is None else
                              (r[k] if isinstance(r[k], str) else f"{r[k]:.6g}") for k in keys))
    return "\n".join(lines) + "\n"
