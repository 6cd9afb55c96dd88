"""Height maps in a chunked Zarr store (``heightmap.zarr``), for maps too large for one array.

Layout (Zarr format 3, a folder):

- group attributes: the same as ``heightmap.exr``'s header: ``pixel_size_mm`` (float),
  ``origin_mm`` ([x, y] of the centre of pixel [0, 0]), ``units`` = "mm", ``scene`` (JSON
  text), ``software_version``, ``meta`` (JSON text); plus ``levels``: the pyramid (list of
  {"path", "factor", "shape"}) and, when known, ``residual_histogram`` ({"lo_mm",
  "hi_mm", "counts"}).
- arrays ``design``, ``machined``, ``residual`` (machined - design, computed in float64):
  float32, (ny, nx), row 0 the smallest y, column 0 the smallest x, NaN where not covered;
  square chunks (the tiles they were computed in).
- ``levels/<k>/{design,machined,residual}``: area averages over 2^k x 2^k blocks (see
  ``render_inspect.io._pyramid``), for previews and coarse views.
- every array has the dimension names ``y``, ``x``; beside them (at full resolution and
  in each level's group) 1-D coordinate arrays ``x`` and ``y``: the pixel centres in mm.
  ``xarray.open_zarr(path)`` opens the store as a Dataset with these coordinates.
- group attribute ``ome``: OME-NGFF 0.5 ``multiscales`` metadata, one multiscale image
  per channel whose datasets are the full resolution and the levels, each with its
  ``scale`` and ``translation`` (mm; axes y, x).

float32 keeps 24 bits: a relative error of at most 2^-24 (6e-8), i.e. 0.06 nm on 1 mm of
sag and below 1e-5 nm on a residual of 100 nm; the residual is formed in float64 before it
is rounded, so it does not lose the digits the heights share.

Compression: Blosc LZ4, level 5, byte shuffle.  Measured on a 16 M-sample map (two
channels): 0.26 s and 78 MB, against none 0.42 s / 134 MB (more bytes to write), Blosc
zstd-1 0.58 s / 75 MB and zstd-1 0.87 s / 113 MB; reading one channel back takes 0.08 s.
"""

from __future__ import annotations

from collections.abc import Sequence
import functools
import json
import os
import stat
from pathlib import Path
from typing import Any

import numpy as np

from ..core import cancel
from ..core.units import GIB_TO_BYTES, MIB_TO_BYTES
from ..core.errors import InputError
from ..core.limits import MAX_ABS_MM, PIXEL_RANGE_MM
from ._exr import exr_placement
from ._pyramid import block_sums, coarsen, level_count, level_shape, means

CHANNELS = ("design", "machined", "residual")
#: most bytes one chunk of a store may decode to: a 16384 x 16384 float32 tile (the
#: stores render_inspect writes use the simulation's tiles, 1024 x 1024 by default)
MAX_CHUNK_BYTES = GIB_TO_BYTES
#: metadata files of a Zarr store (format 2 and 3)
_METADATA = {"zarr.json", ".zarray", ".zattrs", ".zgroup", ".zmetadata"}


def codec() -> Any:
    """The compressor of every array in the store (see the module notes)."""
    from zarr.codecs import BloscCodec

    return BloscCodec(cname="lz4", clevel=5, shuffle="shuffle")


def zarr_read_overhead(store: "ZarrHeightMap", rows: slice | None = None,
                       cols: slice | None = None) -> int:
    """Bytes zarr holds beyond the window while it reads one: the chunks it decodes at
    once (the chunks the window touches, at most ``async.concurrency`` of zarr's
    configuration), each compressed and decoded."""
    try:
        import zarr

        concurrency = int(zarr.config.get("async.concurrency") or 10)
    except Exception:  # an unusual configuration: assume zarr's default
        concurrency = 10
    cy, cx = store.chunk_shape
    ny, nx = store.shape
    r0, r1 = (rows.start or 0, rows.stop if rows and rows.stop is not None else ny) if rows else (0, ny)
    c0, c1 = (cols.start or 0, cols.stop if cols and cols.stop is not None else nx) if cols else (0, nx)
    touched = ((r1 - 1) // cy - r0 // cy + 1) * ((c1 - 1) // cx - c0 // cx + 1)
    return 2 * max(min(concurrency, touched), 1) * store.chunk_bytes


#: the axes of every array of a store (rows are y, columns x), as xarray and OME-NGFF name them
DIMS = ("y", "x")
#: what each channel holds (the arrays' ``long_name``)
LONG_NAMES = {"design": "design height", "machined": "machined height",
              "residual": "machined - design height"}
#: the OME-NGFF version whose ``multiscales`` metadata the stores carry (Zarr format 3)
OME_VERSION = "0.5"


def level_coordinates(n: int, origin: float, pixel: float, factor: int) -> np.ndarray:
    """Centres (mm) of the ``n`` pixels of a pyramid level of ``factor`` along one axis:
    origin + ((F - 1) / 2 + i F) pixel (the centre of a full block)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return origin + ((factor - 1) / 2.0 + np.arange(int(n), dtype=np.float64) * factor) * pixel


def ome_multiscales(shape: tuple[int, ...], pixel: float, origin: Sequence[float],
                    levels: int) -> dict:
    """The OME-NGFF (0.5) ``ome`` group attribute of a store: one multiscale image per
    channel, its datasets the full-resolution array and the pyramid levels, each with
    its ``scale`` (the level's pixel, mm) and ``translation`` (its pixel [0, 0]'s centre,
    mm), axes y and x in millimetres."""
    ox, oy = float(origin[0]), float(origin[1])
    out = []
    for name in CHANNELS:
        datasets = []
        for k in range(levels + 1):
            f = 1 << k
            shift = (f - 1) / 2.0 * pixel
            datasets.append({"path": name if k == 0 else f"levels/{k}/{name}",
                             "coordinateTransformations": [
                                 {"type": "scale", "scale": [pixel * f, pixel * f]},
                                 {"type": "translation", "translation": [oy + shift, ox + shift]}]})
        out.append({"name": name,
                    "axes": [{"name": d, "type": "space", "unit": "millimeter"} for d in DIMS],
                    "datasets": datasets, "type": "mean",
                    "metadata": {"description": "level k: means of the finite samples of "
                                                "2^k x 2^k blocks of full-resolution pixels",
                                 "height_unit": "millimeter"}})
    return {"version": OME_VERSION, "multiscales": out}


def _coordinates(grp, shape, pixel: float, origin, factor: int) -> None:
    """1-D coordinate arrays ``x`` and ``y`` (pixel centres, mm) beside a level's arrays."""
    for axis, n, o in (("x", shape[1], origin[0]), ("y", shape[0], origin[1])):
        a = grp.create_array(axis, shape=(int(n),), chunks=(min(int(n), 1 << 16),),
                             dtype="float64", dimension_names=(axis,), compressors=[codec()])
        a[...] = level_coordinates(n, float(o), pixel, factor)
        a.attrs.update({"units": "mm", "long_name": f"{axis} of the pixel centres",
                        "axis": axis.upper()})


def _whole(fn):
    """Run ``fn`` with a stop (Ctrl-C, SIGTERM) held back until it returns: zarr writes
    metadata and chunks on its own I/O thread, and a stop that ended the main thread's
    wait for it would leave that thread writing on into an output folder already
    removed (:func:`render_inspect.core.cancel.deferred`)."""
    @functools.wraps(fn)
    def run(*a, **k):
        with cancel.deferred():
            return fn(*a, **k)
    return run


@_whole
def create_heightmap_zarr(path: str | Path, shape: Sequence[int], *, chunk: int, attrs: dict,
                          levels: int = 0) -> Any:
    """Create an empty store (arrays filled with NaN) and return its zarr group.

    Every level (the full resolution and each pyramid level) holds the arrays of
    :data:`CHANNELS` with dimension names ``y`` and ``x`` and 1-D coordinate arrays ``x``
    and ``y`` (pixel centres, mm), so that ``xarray.open_zarr(path)`` (or ``group =
    "levels/2"``) opens it as a Dataset; the group attribute ``ome`` carries OME-NGFF
    ``multiscales`` metadata of the pyramid (:func:`ome_multiscales`).

    Parameters
    ----------
    path : folder to create (must not exist)
    shape : (ny, nx) of the full-resolution map
    chunk : side of the square chunks of the full-resolution arrays (pixels)
    attrs : ``grid_attrs`` (render_inspect.io._heightmap; more keys may be added):
        ``pixel_size_mm`` and ``origin_mm`` place the coordinates
    levels : pyramid levels (factors 2 .. 2^levels)
    """
    import zarr

    path = Path(path)
    if path.exists():
        raise InputError(f"heightmap store already exists: {str(path)!r}")
    ny, nx = (int(shape[0]), int(shape[1]))
    pixel = float(attrs.get("pixel_size_mm", 1.0))
    origin = tuple(float(v) for v in attrs.get("origin_mm", (0.0, 0.0)))
    g = zarr.open_group(str(path), mode="w-", zarr_format=3)
    lv: list[Any] = []
    for k in range(levels + 1):
        shp = level_shape((ny, nx), k)
        c = max(chunk >> k, 1) if (1 << k) <= chunk else min(max(shp), 1024)
        grp = g if k == 0 else g.require_group(f"levels/{k}")
        for name in CHANNELS:
            a = grp.create_array(name, shape=shp, chunks=(min(c, shp[0]), min(c, shp[1])),
                                 dtype="float32", fill_value=np.nan, compressors=[codec()],
                                 dimension_names=DIMS)
            a.attrs.update({"units": "mm", "long_name": LONG_NAMES[name]})
        _coordinates(grp, shp, pixel, origin, 1 << k)
        if k:
            lv.append({"path": f"levels/{k}", "factor": 1 << k, "shape": list(shp)})
    g.attrs.update({**attrs, "levels": lv,
                    "ome": ome_multiscales((ny, nx), pixel, origin, levels)})
    consolidate(path)
    return g


@_whole
def consolidate(path: str | Path) -> None:
    """Gather the store's metadata into its root ``zarr.json`` (what ``xarray.open_zarr``
    reads first; zarr-python's consolidated metadata, not yet part of the Zarr format 3
    specification: readers without it read each array's own ``zarr.json``)."""
    import warnings

    import zarr

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "not part of the Zarr format 3 specification"
        zarr.consolidate_metadata(str(path))


@_whole
def write_heightmap_zarr(path: str | Path, design: np.ndarray, machined: np.ndarray, *, attrs: dict,
                         chunk: int = 1024, levels: int | None = None) -> Path:
    """Write a height map that is in memory into a new store (residual formed in float64)."""
    design = np.asarray(design)
    machined = np.asarray(machined)
    if levels is None:
        levels = level_count(design.shape)
    g = create_heightmap_zarr(path, design.shape, chunk=chunk, attrs=attrs, levels=levels)
    res = np.empty(design.shape, dtype=np.float32)
    for a in range(0, design.shape[0], 1024):
        np.subtract(machined[a:a + 1024], design[a:a + 1024], out=res[a:a + 1024], casting="same_kind")
    for name, arr in (("design", design), ("machined", machined), ("residual", res)):
        g[name][...] = np.asarray(arr, dtype=np.float32)
        if levels:
            s, c = block_sums(arr, 2)
            g[f"levels/1/{name}"][...] = means(s, c)
            for k in range(2, levels + 1):
                s, c = coarsen(s, c, 2)
                g[f"levels/{k}/{name}"][...] = means(s, c)
    set_store_attrs(path, chunk_files=chunk_files(path))
    return Path(path)


def chunk_files(path: str | Path) -> dict[str, int]:
    """How many chunk files each array of a store holds (the array's folder relative to the
    store -> count).  Recorded as the attribute ``chunk_files`` when a store is complete, so
    that one that has lost chunks since (a copy cut short) is refused when it is read: zarr
    itself reads a missing chunk as empty (NaN), which would pass for unmeasured points."""
    root = Path(path)
    out: dict[str, int] = {}
    for top, _dirs, files in os.walk(root, followlinks=False):
        _count_chunks(out, root, top, len(files))
    return out


def _count_chunks(counts: dict[str, int], root: Path, top: str, n: int) -> None:
    """Add the ``n`` files of the folder ``top`` to their array's count when they are
    chunks (below the array's ``c`` folder)."""
    parts = Path(os.path.relpath(top, root)).parts
    if n and "c" in parts:
        arr = "/".join(parts[:parts.index("c")])
        counts[arr] = counts.get(arr, 0) + n


@_whole
def set_store_attrs(path: str | Path, **attrs: Any) -> None:
    """Add (or replace) group attributes of a store."""
    import zarr

    zarr.open_group(str(path), mode="r+", use_consolidated=False).attrs.update(attrs)
    consolidate(path)


#: most bytes of the root group's metadata (its attributes and the consolidated metadata of
#: every array; a store render_inspect writes holds a few tens of kB)
MAX_ROOT_METADATA_BYTES = 16 * MIB_TO_BYTES
#: most bytes of any other metadata file (one array's or group's)
MAX_METADATA_BYTES = MIB_TO_BYTES


def check_store_tree(path: str | Path, *, what: str = "heightmap store") -> dict[str, int]:
    """A store read as untrusted input, checked before zarr reads a byte of it: every
    entry inside the folder is a plain folder or a regular file (no symbolic link,
    whatever it points to, so that nothing outside the store is read through it; no
    device, pipe or socket), and no metadata file is larger than
    :data:`MAX_ROOT_METADATA_BYTES` (the root ``zarr.json``) or
    :data:`MAX_METADATA_BYTES` (any other), so that a huge JSON file is refused before it
    is parsed.  Chunk sizes are checked when an array is read (``_check_array``).  Returns
    the chunk files of each array (:func:`chunk_files`, counted in the same walk)."""
    root = Path(path)
    counts: dict[str, int] = {}
    for top, dirs, files in os.walk(root, followlinks=False):
        _count_chunks(counts, root, top, len(files))
        for n in dirs + files:
            full = os.path.join(top, n)
            rel = os.path.relpath(full, root)
            try:
                st = os.lstat(full)
            except OSError as err:
                raise InputError(f"{what} {str(root)!r}: {rel!r} cannot be read "
                                 f"({err.strerror or err})") from None
            if stat.S_ISLNK(st.st_mode):
                raise InputError(f"{what} {str(root)!r}: {rel!r} is a symbolic link; a store's "
                                 f"arrays, groups and files must lie inside it (copy the "
                                 f"store with the links resolved): refused")
            if stat.S_ISDIR(st.st_mode):
                continue
            if not stat.S_ISREG(st.st_mode):
                raise InputError(f"{what} {str(root)!r}: {rel!r} is not a regular file (a "
                                 f"device, a pipe or a socket): refused")
            if n in _METADATA:
                limit = MAX_ROOT_METADATA_BYTES if top == str(root) else MAX_METADATA_BYTES
                if st.st_size > limit:
                    raise InputError(f"{what} {str(root)!r}: {rel!r} is {st.st_size} bytes; "
                                     f"metadata files are at most {limit // MIB_TO_BYTES} MiB "
                                     f"(refused before it is read)")
    return counts


class ZarrHeightMap:
    """A height map in a store, read window by window.

    Attributes
    ----------
    shape : (ny, nx)
    pixel : float, mm
    origin : (x, y) of the centre of pixel [0, 0], mm
    scene, meta : dict
    attrs : dict (all group attributes)
    """

    def __init__(self, path: str | Path, *, what: str = "heightmap store"):
        import zarr

        path = Path(path)
        if not path.is_dir():
            raise InputError(f"{what} not found: {str(path)!r}")
        self.path = path
        self.what = what
        present = check_store_tree(path, what=what)
        for name in CHANNELS:
            self._check_declared_type(name)
        try:
            # each array's own metadata (what _check_declared_type read), not the copy
            # gathered in the root (consolidated metadata) that a store may also hold
            self.group = zarr.open_group(str(path), mode="r", use_consolidated=False)
            self.attrs: dict[str, Any] = dict(self.group.attrs)
            # the channels are arrays (the store's tree is checked above)
            arrays: dict[str, Any] = {name: self.group[name] for name in CHANNELS
                                      if name in self.group}
        except Exception as err:  # zarr raises its own and builtin errors on damaged stores
            raise InputError(f"{what} {str(path)!r} is not a readable Zarr store "
                             f"({type(err).__name__}: {err})") from None
        if "machined" not in arrays:
            raise InputError(f"{what} {str(path)!r}: the store has no 'machined' array")
        self.what = what
        self.pixel, self.origin = exr_placement(self.attrs, what=what, path=path)
        lo, hi = PIXEL_RANGE_MM
        if not lo <= self.pixel <= hi:
            raise InputError(f"{what} {str(path)!r}: pixel_size_mm must lie within {lo:g} .. "
                             f"{hi:g} mm, received {self.pixel:.3g}")
        if max(abs(self.origin[0]), abs(self.origin[1])) > MAX_ABS_MM:
            raise InputError(f"{what} {str(path)!r}: origin_mm must lie within +-{MAX_ABS_MM:g} "
                             f"mm, received {list(self.origin)}")
        shape = tuple(int(n) for n in arrays["machined"].shape)
        if len(shape) != 2 or any(a.shape != shape for a in arrays.values()):
            raise InputError(f"{what} {str(path)!r}: its arrays must be 2-D and of one shape, "
                             f"received {[tuple(a.shape) for a in arrays.values()]}")
        if min(shape) < 1:
            raise InputError(f"{what} {str(path)!r}: its arrays are empty (shape {list(shape)})")
        self.shape = shape
        self._checked: dict[str, int] = {}
        self.chunk_bytes = max(self._check_array(name, a) for name, a in arrays.items())
        self.chunk_shape = tuple(int(c) for c in arrays["machined"].chunks)
        written = self.attrs.get("chunk_files")
        if isinstance(written, dict):
            lost = {a: (present.get(a, 0), n) for a, n in written.items()
                    if isinstance(n, int) and present.get(a, 0) < n}
            if lost:
                a, (n_now, n) = next(iter(sorted(lost.items())))
                raise InputError(f"{what} {str(path)!r}: array {a!r} holds {n_now} chunk files, "
                                 f"{n} when the store was written: chunks are missing (a copy "
                                 f"cut short?), and would be read as unmeasured points; refused"
                                 + (f" ({len(lost)} arrays)" if len(lost) > 1 else ""))
        try:
            self.scene = json.loads(self.attrs.get("scene") or "{}")
            self.meta = json.loads(self.attrs.get("meta") or "{}")
        except (TypeError, ValueError):
            raise InputError(f"{what} {str(path)!r}: damaged 'scene' or 'meta' attribute") from None

    @property
    def levels(self) -> list[dict]:
        return list(self.attrs.get("levels", []))

    def index_window(self, region: Sequence[float]) -> tuple[slice, slice]:
        """Rows and columns of the pixels whose centres lie in ``region`` (x0, y0, x1, y1; mm)."""
        x0, y0, x1, y1 = region
        ox, oy = self.origin
        p = self.pixel
        c0 = max(int(np.ceil((x0 - ox) / p - 1e-9)), 0)
        c1 = min(int(np.floor((x1 - ox) / p + 1e-9)), self.shape[1] - 1)
        r0 = max(int(np.ceil((y0 - oy) / p - 1e-9)), 0)
        r1 = min(int(np.floor((y1 - oy) / p + 1e-9)), self.shape[0] - 1)
        if c1 < c0 or r1 < r0:
            raise InputError(f"region {list(region)} mm does not overlap the map "
                             f"(x {ox:g}..{ox + p * (self.shape[1] - 1):g}, y {oy:g}..{oy + p * (self.shape[0] - 1):g} mm)")
        return slice(r0, r1 + 1), slice(c0, c1 + 1)

    def _check_declared_type(self, name: str) -> None:
        """What an array's metadata declares (``zarr.json`` of format 3, ``.zarray`` of
        format 2), checked before zarr opens it: a 2-D shape and chunk shape of whole
        numbers >= 1, real numbers only."""
        for meta, key in (("zarr.json", "data_type"), (".zarray", "dtype")):
            f = self.path / name / meta
            try:
                if not f.is_file() or f.stat().st_size > MIB_TO_BYTES:
                    continue
                d = json.loads(f.read_text(encoding="utf-8"))
                declared = d.get(key)
            except (OSError, ValueError, AttributeError):
                continue  # zarr says what is wrong with it
            where = f"{self.what} {str(self.path)!r}: array {name!r}"
            if meta == "zarr.json":
                grid = d.get("chunk_grid")
                chunks = (grid.get("configuration") or {}).get("chunk_shape") \
                    if isinstance(grid, dict) else None
            else:
                chunks = d.get("chunks")
            for what_key, value in (("shape", d.get("shape")), ("chunk_shape", chunks)):
                if not (isinstance(value, list) and len(value) == 2 and all(
                        type(v) is int and v >= 1 for v in value)):
                    raise InputError(f"{where}: {what_key} must be two whole numbers >= 1, "
                                     f"received {str(value)[:60]}")
            try:
                dtype = np.dtype(declared) if isinstance(declared, str) else None
            except TypeError:
                dtype = None
            if dtype is not None and dtype.kind == "c":
                raise InputError(f"{where} holds complex numbers ({dtype}); a height map must be "
                                 f"real (store np.real(z) or np.abs(z) explicitly)")
            if dtype is None or dtype.kind not in "fiu":
                raise InputError(f"{where} must hold real numbers (float or integer), its data "
                                 f"type is {str(declared)[:40]!r}")

    def _check_array(self, name: str, arr) -> int:
        """Check one array of the store before any chunk is read: real numbers, chunks of
        at least one and at most :data:`MAX_CHUNK_BYTES` bytes decoded, and only regular
        files in its folder, none larger than a chunk can be (no links to devices, no
        chunk that would expand without bound).  Returns the bytes one chunk decodes to."""
        if name in self._checked:
            return self._checked[name]
        where = f"{self.what} {str(self.path)!r}: array {name!r}"
        try:
            dtype = np.dtype(arr.dtype)
        except TypeError:
            raise InputError(f"{where} must hold real numbers, its data type is "
                             f"{arr.dtype!s:.40}") from None
        if dtype.kind == "c":
            raise InputError(f"{where} holds complex numbers ({dtype}); a height map must be "
                             f"real (store np.real(z) or np.abs(z) explicitly)")
        if dtype.kind not in "fiu":
            raise InputError(f"{where} must hold real numbers (float or integer), its data type "
                             f"is {dtype}")
        chunks = tuple(getattr(arr, "chunks", ()) or ())
        if len(chunks) != 2 or not all(isinstance(c, (int, np.integer)) and c >= 1 for c in chunks):
            raise InputError(f"{where}: chunk_shape must be two whole numbers >= 1, received "
                             f"{list(chunks)}")
        chunk_bytes = int(chunks[0]) * int(chunks[1]) * dtype.itemsize
        if chunk_bytes > MAX_CHUNK_BYTES:
            raise InputError(f"{where}: a chunk of {chunks[0]} x {chunks[1]} values decodes to "
                             f"{chunk_bytes / MIB_TO_BYTES:.0f} MiB, more than the "
                             f"{MAX_CHUNK_BYTES // MIB_TO_BYTES} MiB allowed per chunk (a small "
                             f"compressed chunk could expand without bound); rechunk the store")
        shards = tuple(getattr(arr, "shards", None) or ())
        file_limit = chunk_bytes
        if len(shards) == 2 and all(isinstance(c, (int, np.integer)) and c >= 1 for c in shards):
            file_limit = int(shards[0]) * int(shards[1]) * dtype.itemsize
        file_limit = int(file_limit * 1.1) + 2 ** 16  # codecs may add a little
        folder = self.path / name
        for root, dirs, files in os.walk(folder):
            for n in dirs + files:
                full = os.path.join(root, n)
                st = os.lstat(full)
                rel = os.path.relpath(full, self.path)
                if n in dirs and stat.S_ISDIR(st.st_mode):
                    continue
                if not stat.S_ISREG(st.st_mode):
                    raise InputError(f"{self.what} {str(self.path)!r}: {rel!r} is not a regular "
                                     f"file (a link, a device or a pipe): refused")
                if n not in _METADATA and st.st_size > file_limit:
                    raise InputError(f"{self.what} {str(self.path)!r}: {rel!r} holds "
                                     f"{st.st_size} bytes, more than a chunk of array {name!r} "
                                     f"can ({file_limit} bytes)")
                if n in _METADATA and st.st_size > MIB_TO_BYTES:
                    raise InputError(f"{self.what} {str(self.path)!r}: {rel!r} is "
                                     f"{st.st_size} bytes; metadata files are at most 1 MiB")
        self._checked[name] = chunk_bytes
        return chunk_bytes

    def read(self, channel: str, rows: slice = slice(None), cols: slice = slice(None), *,
             level: int = 0) -> np.ndarray:
        """Samples of ``channel`` as stored (float32 in the stores render_inspect writes;
        only the chunks that hold the window are read).  A chunk that cannot be decoded is
        an :class:`InputError` naming the store."""
        if channel not in CHANNELS:
            raise InputError(f"channel must be one of {list(CHANNELS)}, got {channel!r}")
        name = channel if level == 0 else f"levels/{level}/{channel}"
        try:
            arr: Any = self.group[name]
        except KeyError:
            raise InputError(f"{self.what} {str(self.path)!r} has no array {name!r}") from None
        self._check_array(name, arr)
        try:
            return arr[rows, cols]
        except (MemoryError, KeyboardInterrupt):
            raise
        except Exception as err:  # codecs raise RuntimeError/ValueError/... on damaged chunks
            raise InputError(f"{self.what} {str(self.path)!r}: array {name!r} cannot be read "
                             f"(a damaged chunk: {type(err).__name__}: {str(err)[:120]})") from None

    def dask(self, channel: str, *, level: int = 0) -> Any:
        """``channel`` (at pyramid ``level``) as a ``dask.array`` in the store's chunks:
        nothing is read until a window of it is computed (:meth:`rows` reads one, turning
        a damaged chunk into an :class:`InputError`)."""
        import dask.array as da

        name = self._name(channel, level)
        arr = self.group[name]
        self._check_array(name, arr)
        return da.from_zarr(arr)

    def rows(self, channel: str, r0: int, r1: int, *, level: int = 0) -> np.ndarray:
        """Rows ``r0`` .. ``r1 - 1`` of ``channel`` (float64), read through
        :meth:`dask` (the chunks decoded in parallel threads)."""
        name = self._name(channel, level)
        try:
            return self.dask(channel, level=level)[r0:r1].compute(scheduler="threads") \
                .astype(np.float64, copy=False)
        except (MemoryError, KeyboardInterrupt, InputError):
            raise
        except Exception as err:  # codecs raise RuntimeError/ValueError/... on damaged chunks
            raise InputError(f"{self.what} {str(self.path)!r}: array {name!r} cannot be read "
                             f"(a damaged chunk: {type(err).__name__}: {str(err)[:120]})") from None

    def _name(self, channel: str, level: int) -> str:
        if channel not in CHANNELS:
            raise InputError(f"channel must be one of {list(CHANNELS)}, got {channel!r}")
        name = channel if level == 0 else f"levels/{level}/{channel}"
        if name not in self.group:
            raise InputError(f"{self.what} {str(self.path)!r} has no array {name!r}")
        return name

    def level_for(self, max_side: int) -> int:
        """The finest pyramid level whose larger side is at most ``max_side`` (the
        coarsest level if none is)."""
        best = len(self.levels)
        for i, lv in enumerate(self.levels, start=1):
            if max(lv["shape"]) <= max_side:
                return i
        return best if max(self.shape) > max_side else 0

    def window(self,
               region: Sequence[float] | None = None) -> tuple[np.ndarray, np.ndarray, tuple[float, float]]:
        """(design, machined, origin) of the pixels in ``region`` (whole map if None):
        float64 arrays and the (x, y) centre of their pixel [0, 0], mm."""
        rows, cols = self.index_window(region) if region is not None else (slice(0, self.shape[0]),
                                                                           slice(0, self.shape[1]))
        origin = (self.origin[0] + cols.start * self.pixel, self.origin[1] + rows.start * self.pixel)
        return (self.read("design", rows, cols).astype(np.float64),
                self.read("machined", rows, cols).astype(np.float64), origin)
