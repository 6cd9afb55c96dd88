"""Retired scene keys: still accepted, with a warning that names the key to use instead
(docs/scene_keys.md lists them)."""

from __future__ import annotations

import warnings

__all__ = ["DeprecatedKeyWarning", "warn_deprecated"]


class DeprecatedKeyWarning(UserWarning):
    """A scene key that still works but has a successor (shown once per key)."""


def warn_deprecated(old: str, new: str | None, note: str = "") -> None:
    """Warn that the scene key ``old`` is retired in favour of ``new`` (None: it has no
    successor and is ignored)."""
    instead = f"use {new} instead" if new else "it is ignored"
    warnings.warn(f"scene key {old} is deprecated: {instead}" + (f" ({note})" if note else ""),
                  DeprecatedKeyWarning, stacklevel=3)
