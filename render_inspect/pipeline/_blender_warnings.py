"""The warnings of the add-on's pipeline functions (:mod:`._blender`): what the command
line prints as ``warning: ...`` for the same work, collected as lines for a panel.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
import logging
from typing import Any

from ..processes import findings_summary
from ..scene import unit_warnings
from ._toolpath import edge_warnings

__all__ = ["note", "scene_warnings", "variant_warnings", "warnings_into"]


class _Collect(logging.Handler):
    """Keeps the text of each warning render_inspect logs (the lines the command line
    prints as ``warning: ...``), once each, in order."""

    def __init__(self, found: list[str]) -> None:
        super().__init__(logging.WARNING)
        self.found = found

    def emit(self, record: logging.LogRecord) -> None:
        note(self.found, record.getMessage())


def note(found: list[str], text: str, prefix: str = "") -> None:
    """Add ``text`` (without a leading ``warning:``) to ``found`` unless it is there
    already, with or without a variant's ``prefix``."""
    text = str(text).strip()
    if text.lower().startswith("warning:"):
        text = text[len("warning:"):].strip()
    if text and text not in found and f"{prefix}{text}" not in found and not any(
            f.endswith(f": {text}") for f in found):
        found.append(f"{prefix}{text}")


@contextmanager
def warnings_into(found: list[str]) -> Iterator[list[str]]:
    """The warnings render_inspect logs while the block runs, collected into ``found``
    (what the command line would print); the logger's own handlers still get them."""
    logger = logging.getLogger("render_inspect")
    handler = _Collect(found)
    level = logger.level
    if logger.getEffectiveLevel() > logging.WARNING:
        logger.setLevel(logging.WARNING)
    logger.addHandler(handler)
    try:
        yield found
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)


def scene_warnings(scene: Any, found: list[str]) -> None:
    """What the command line says before a run: values that look like unit mistakes, and
    a measured tool edge the nose arc reaches beyond."""
    for text in unit_warnings(scene, sampling=True):
        note(found, text)
    tool = getattr(scene, "tool", None)
    if tool is not None and (getattr(tool, "edge_profile", None) or getattr(tool, "waviness", None)):
        for text in edge_warnings(scene):
            note(found, text)


def variant_warnings(name: str, metrics: dict, found: list[str]) -> None:
    """What ``simulate`` says after a variant's cut: the cut beyond a measured tool edge,
    and the findings of a machine program read from a file."""
    for text in (metrics.get("tool_edge") or {}).get("warnings", []):
        note(found, text, f"{name}: ")
    program = metrics.get("program")
    if isinstance(program, dict) and program.get("findings"):
        note(found, f"program findings: {findings_summary(program)}", f"{name}: ")
