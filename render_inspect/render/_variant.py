"""Choose, check and record the Mitsuba 3 variant; keep renders bitwise repeatable.

The variant is chosen once per process:

1. ``RENDER_INSPECT_MITSUBA_VARIANT`` (environment) if set: used as given, an error if it
   does not work;
2. ``cuda_ad_rgb`` when a CUDA GPU is present (``/dev/nvidia0`` or ``nvidia-smi``) and a
   tiny test render on it succeeds;
3. ``llvm_ad_rgb`` when a usable libLLVM (>= 16) is found and a tiny test render works
   (``DRJIT_LIBLLVM_PATH`` is pointed at Debian's ``libLLVM-19`` when it is unset);
4. ``scalar_rgb`` otherwise, with one message on stderr saying why.

Only this package imports :mod:`mitsuba` / :mod:`drjit`, and only inside functions.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import sys
import threading
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..core import cancel
from ..core.errors import InputError, RenderInspectError
from ..core.lazy import collector_paused
from ..core.limits import check_address_space, mitsuba_address_space

__all__ = ["mitsuba_variant", "import_mitsuba", "single_thread", "variant_info",
           "spectral_variant", "start_mitsuba"]

_LLVM_CANDIDATES = (
    "/usr/lib/x86_64-linux-gnu/libLLVM-19.so.1",
    "/usr/lib/x86_64-linux-gnu/libLLVM-19.so",
    "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1",
    "/usr/lib/llvm-19/lib/libLLVM-19.so",
    "/usr/lib/llvm-19/lib/libLLVM.so.1",
    "/usr/lib/aarch64-linux-gnu/libLLVM-19.so.1",
)

_STATE: dict = {"variant": None, "message": None, "override": None}
#: held while the variant is chosen: a thread asking meanwhile waits for that choice
_CHOOSING = threading.Lock()


def _point_at_llvm() -> str | None:
    """Set ``DRJIT_LIBLLVM_PATH`` to a libLLVM >= 16 if unset; return the path used."""
    cur = os.environ.get("DRJIT_LIBLLVM_PATH")
    if cur:
        return cur
    for cand in _LLVM_CANDIDATES:
        if Path(cand).is_file():
            os.environ["DRJIT_LIBLLVM_PATH"] = cand
            return cand
    return None


def _has_cuda_gpu() -> bool:
    return Path("/dev/nvidia0").exists() or shutil.which("nvidia-smi") is not None


def _smoke_test(mi) -> None:
    """A 4 x 4 AOV render of a rectangle: raises if the variant does not really work."""
    import numpy as np

    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "aov", "aovs": "pp:position"},
        "sensor": {"type": "orthographic",
                   "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 1], target=[0, 0, 0],
                                                              up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 4, "height": 4,
                            "rfilter": {"type": "box"}},
                   "sampler": {"type": "stratified", "sample_count": 1, "jitter": False}},
        "shape": {"type": "rectangle"},
    })
    img = np.array(mi.render(scene, seed=0))
    if img.shape != (4, 4, 3) or not np.allclose(img[0, :, 0], [-0.75, -0.25, 0.25, 0.75],
                                                 atol=1e-5):
        raise RuntimeError(f"test render gave unexpected values {img[0, :, 0]}")


def _try(mi, variant: str) -> str | None:
    """Set ``variant`` and smoke-test it; return None on success, else the reason."""
    if variant not in mi.variants():
        return f"variant {variant} is not compiled into this Mitsuba build"
    try:
        mi.set_variant(variant)
        _smoke_test(mi)
    except Exception as exc:  # any failure of the engine means: not usable
        return f"{type(exc).__name__}: {exc}"
    return None


def mitsuba_variant() -> str:
    """Select (once per process) and return the Mitsuba variant in use.

    Returns
    -------
    str
        ``"cuda_ad_rgb"``, ``"llvm_ad_rgb"`` or ``"scalar_rgb"``.  Recorded by every render
        in its outputs (``mitsuba_variant``).
    """
    if _STATE["variant"] is not None:
        return _STATE["variant"]
    with _CHOOSING:  # (once: a second thread waits for the first one's choice)
        if _STATE["variant"] is not None:
            return _STATE["variant"]
        _point_at_llvm()
        if "mitsuba" not in sys.modules:
            # Mitsuba's LLVM JIT ends with a segmentation fault when its reservations are
            # refused: refuse the render first under an address-space limit it cannot meet
            check_address_space(mitsuba_address_space(), what="a Mitsuba render")
        # importing Mitsuba and trying its variants are not interrupted part-way: an
        # exception raised by a signal's handler inside their C++ set-up (which builds
        # Python objects) aborts the process; a stop asked for meanwhile is raised right
        # after
        with cancel.deferred():
            return _choose_variant()


def start_mitsuba() -> threading.Thread | None:
    """Choose the variant (:func:`mitsuba_variant`: Mitsuba and Dr.Jit imported, the
    variant's test render) in a thread, started, so that a render does it while it
    prepares what it traces (a few tenths of a second, much of it in the libraries' native
    set-up, which leaves the interpreter free); the render's own call then waits for that
    choice.  None, and nothing started, when the variant is already chosen or when called
    from a thread other than the process's main thread (a Dask worker's task: no threads
    of the package's own there).  A failure in the thread is left to the render's own
    call, which raises it.  Join the thread before the process ends (its native set-up
    must not be cut off by the interpreter's teardown)."""
    if _STATE["variant"] is not None or threading.current_thread() is not threading.main_thread():
        return None

    def run() -> None:
        try:
            # (the collector paused: Mitsuba's modules live as long as the process)
            with collector_paused():
                mitsuba_variant()
        except Exception:  # (the render's own call chooses again and raises it there)
            pass

    thread = threading.Thread(target=run, name="render_inspect-mitsuba", daemon=True)
    thread.start()
    return thread


def _choose_variant() -> str:
    import mitsuba as mi

    forced = os.environ.get("RENDER_INSPECT_MITSUBA_VARIANT")
    if forced:
        why = _try(mi, forced)
        if why is not None:
            raise InputError(f"RENDER_INSPECT_MITSUBA_VARIANT={forced!r} does not work ({why}); "
                             f"unset it or choose one of {mi.variants()}")
        _STATE["variant"] = forced
        return forced
    reasons = []
    order = (["cuda_ad_rgb"] if _has_cuda_gpu() else []) + ["llvm_ad_rgb"]
    for variant in order:
        why = _try(mi, variant)
        if why is None:
            _STATE["variant"] = variant
            return variant
        reasons.append(f"{variant}: {why}")
    why = _try(mi, "scalar_rgb")
    if why is not None:
        raise RenderInspectError(f"no Mitsuba variant works on this machine (scalar_rgb: {why}; "
                                 f"{'; '.join(reasons)}); reinstall mitsuba (make setup)")
    msg = ("render_inspect: Mitsuba falls back to the slow scalar_rgb variant ("
           + "; ".join(reasons) + "). Install libLLVM >= 16 (Debian: libllvm19) or set "
           "DRJIT_LIBLLVM_PATH to use llvm_ad_rgb.")
    print(msg, file=sys.stderr)
    _STATE["variant"] = "scalar_rgb"
    _STATE["message"] = msg
    return "scalar_rgb"


def import_mitsuba() -> tuple[Any, Any, str]:
    """Return ``(mi, dr, variant)`` with the chosen variant set (inside
    :func:`spectral_variant`: its spectral counterpart)."""
    variant = _STATE["override"] or mitsuba_variant()
    with cancel.deferred():  # (see mitsuba_variant)
        import drjit as dr
        import mitsuba as mi

        if mi.variant() != variant:
            _set_variant_quietly(mi, variant)
    return mi, dr, variant


@contextlib.contextmanager
def spectral_variant() -> Iterator[str | None]:
    """Run the block with the spectral counterpart of the chosen variant
    (``llvm_ad_rgb`` -> ``llvm_ad_spectral``, ``cuda_ad_rgb`` -> ``cuda_ad_spectral``);
    yields its name, or None (and changes nothing) when the chosen variant is
    ``scalar_rgb`` (a Python BSDF on scalar rays would be far too slow) or the build
    lacks it.  Afterwards :func:`import_mitsuba` gives the chosen RGB variant again: it
    sets it when it is asked for, not at the end of the block, since every switch
    reloads Mitsuba's Python modules (0.08 s of CPU): renders in a row (the passes of a
    Monte-Carlo image) switch once."""
    base = mitsuba_variant()
    import mitsuba as mi

    spectral = base.replace("_rgb", "_spectral")
    if base.startswith("scalar") or spectral not in mi.variants() or _STATE["override"]:
        yield _STATE["override"]
        return
    _STATE["override"] = spectral
    try:
        if mi.variant() != spectral:
            _set_variant_quietly(mi, spectral)
        yield spectral
    finally:
        _STATE["override"] = None


def _set_variant_quietly(mi, variant: str) -> None:
    """``mi.set_variant`` without Dr.Jit's hint about ``@dr.syntax``: every switch makes
    Mitsuba decorate its own Python integrators again, and after 1000 decorations Dr.Jit
    warns about code in loops (a hint for user code; here they are the package's own switches)."""
    with warnings.catch_warnings(), cancel.deferred():  # (see mitsuba_variant)
        warnings.filterwarnings("ignore", message="The AST-transforming decorator",
                                category=RuntimeWarning)
        mi.set_variant(variant)


def variant_info() -> dict:
    """Provenance of the renderer: variant, Mitsuba / Dr.Jit versions, libLLVM path."""
    mi, dr, variant = import_mitsuba()
    return {"mitsuba_variant": variant, "mitsuba_version": mi.__version__,
            "drjit_version": dr.__version__,
            "libllvm": os.environ.get("DRJIT_LIBLLVM_PATH", "") if variant.startswith("llvm") else "",
            "fallback_message": _STATE["message"] or ""}


@contextlib.contextmanager
def single_thread() -> Iterator[None]:
    """Run the block with one Dr.Jit worker thread (restored afterwards).

    On the LLVM variant, building the BVH of a large mesh with several threads gives
    slightly different trees from run to run (measured: 17 % of pixels differed between
    processes); loading scenes inside this block makes renders bitwise repeatable.
    """
    mi, dr, variant = import_mitsuba()
    if not variant.startswith("llvm"):
        yield
        return
    old = dr.thread_count()
    dr.set_thread_count(1)
    try:
        yield
    finally:
        dr.set_thread_count(old)
