"""PNG images: float images as 8-bit PNG, and 8-bit images with text chunks (the figures
are drawn in :mod:`render_inspect.report`)."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

from ._atomic import atomic_write_bytes


def save_png(path: str | Path, image: np.ndarray) -> Path:
    """Save a float image in [0, 1] (H x W or H x W x 3) as 8-bit PNG, row 0 at the top."""
    from PIL import Image

    a = np.clip(np.nan_to_num(np.asarray(image, dtype=np.float64)), 0, 1)
    a = (a * 255 + 0.5).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(a).save(buf, format="PNG")
    return atomic_write_bytes(path, buf.getvalue())


def png_bytes_with_text(img8: np.ndarray, text: dict) -> bytes:
    """8-bit PNG of ``img8`` (H x W or H x W x 3, row 0 at the top) with PNG text chunks
    ``text`` (values that are not text are written as JSON)."""
    from PIL import Image
    from PIL.PngImagePlugin import PngInfo

    info = PngInfo()
    for k, v in text.items():
        info.add_text(str(k), v if isinstance(v, str) else json.dumps(v, default=str))
    buf = io.BytesIO()
    Image.fromarray(img8).save(buf, format="PNG", pnginfo=info)
    return buf.getvalue()
