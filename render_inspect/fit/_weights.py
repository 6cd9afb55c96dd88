"""The misfit terms' weights a user gives (``--weights TERM=W``), checked the same way
for maps and profiles."""

from __future__ import annotations

from collections.abc import Iterable
import math

from ..core.errors import InputError

__all__ = ["check_weights", "parse_weights"]


def check_weights(weights: dict, terms: Iterable[str], *, of: str = "") -> None:
    """``--weights``: every term one of ``terms``, each a number >= 0, one at least > 0
    (``of``: what the terms are of, in the message, e.g. " for a profile")."""
    bad = sorted(set(weights) - set(terms))
    if bad:
        raise InputError(f"--weights: unknown term {bad[0]!r}{of}; the terms are "
                         f"{', '.join(terms)}")
    for k, v in weights.items():
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
            raise InputError(f"--weights {k} must be a number >= 0, received {v!r}")
    if not any(weights.get(k, 0) > 0 for k in terms):
        raise InputError("--weights: at least one term must have a weight > 0")


def parse_weights(items: Iterable[str] | None, terms: Iterable[str], *, of: str = "") -> dict:
    """``--weights TERM=W[,TERM=W...]`` (given once or more) -> {term: weight}, every term
    of ``terms`` 1 unless given (checked by :func:`check_weights` when the misfit is made)."""
    out = {k: 1.0 for k in terms}
    for item in items or ():
        for part in str(item).split(","):
            if not part.strip():
                continue
            if "=" not in part:
                raise InputError(f"--weights expects TERM=W ({', '.join(terms)}{of}), received "
                                 f"{part!r}")
            k, v = part.split("=", 1)
            try:
                out[k.strip()] = float(v)
            except ValueError:
                raise InputError(f"--weights {k.strip()} must be a number >= 0, received "
                                 f"{v!r}") from None
    return out
