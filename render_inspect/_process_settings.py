"""Settings of the ``render-inspect`` program's own process, made before numpy is loaded.

A command runs for seconds to minutes and is alone in its process, so two libraries'
defaults, chosen for long-lived programs that share their process, are changed there
(never for a program that imports the package, Blender included: its process is its own):

* **OpenBLAS's idle threads sleep at once.**  After each matrix product, OpenBLAS (numpy's
  and SciPy's) keeps its threads spinning for about 2^28 processor cycles (0.1 s) in wait
  for the next one, and starts them spinning when it is loaded.  On a machine with few
  cores they take the cores from the computation's own threads (numba's, the figure
  process).  ``OPENBLAS_THREAD_TIMEOUT=4`` (OpenBLAS's smallest: 2^4 cycles) makes them
  sleep instead; a product still runs on all its threads.  A value the user set is kept.
* **Large temporary arrays reuse freed memory.**  glibc's allocator gives each block above
  its mmap threshold (128 KiB at first, raised as such blocks are freed, to 32 MiB at most)
  fresh pages from the system and returns them when the block is freed, and the system
  zeroes every fresh page on its first touch: each temporary array of a megapixel map
  costs its size in zeroed pages.  The threshold is set to its largest value from the
  start, with the heap trimmed beyond twice that (what glibc itself sets as it raises the
  threshold): the blocks of up to 32 MiB are taken from memory freed before.  The peak of
  memory is the same to about 1 %.
* **numpy's arrays in the system's ordinary pages.**  On Linux numpy asks the system for
  2 MiB pages ("transparent huge pages", ``madvise``) for every array of 4 MiB or more.  A
  virtual machine that hands its free memory back to its host (free page reporting or a
  memory balloon: many cloud and CI machines) reports just such large free blocks, so a
  fresh 2 MiB page is mostly memory the host must supply and zero again on its first
  touch: on a 2-core machine of that kind a 16 M-sample ``simulate`` spent about 15 % of
  its CPU time zeroing them, in bursts that made its system time vary from 0.7 to 1.7 s.
  ``NUMPY_MADVISE_HUGEPAGE=0`` (numpy's own switch) turns the request off; the system's
  own choice (``/sys/kernel/mm/transparent_hugepage/enabled`` ``always``) still applies.
  A value the user set is kept.

The results do not depend on any of them (the same products, the same arrays).
"""

from __future__ import annotations

import os
import sys

__all__ = ["apply", "MMAP_THRESHOLD", "TRIM_THRESHOLD"]

#: numpy's switch for its transparent-huge-page requests (read when numpy is imported)
NUMPY_HUGEPAGE = "NUMPY_MADVISE_HUGEPAGE"

#: bytes: glibc's largest mmap threshold on 64-bit systems (its DEFAULT_MMAP_THRESHOLD_MAX)
MMAP_THRESHOLD = 32 * 1024 * 1024
#: bytes: the free memory at the heap's top kept before it is returned to the system
TRIM_THRESHOLD = 2 * MMAP_THRESHOLD

# mallopt's parameter numbers (glibc's malloc.h)
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3


def apply() -> dict[str, bool]:
    """Make the settings above in this process (call before numpy is imported); returns
    which were made (a platform without glibc's ``mallopt`` keeps its allocator)."""
    made = {"openblas_thread_timeout": False, "malloc_thresholds": False,
            "numpy_small_pages": False}
    if "OPENBLAS_THREAD_TIMEOUT" not in os.environ:
        os.environ["OPENBLAS_THREAD_TIMEOUT"] = "4"
        made["openblas_thread_timeout"] = True
    if NUMPY_HUGEPAGE not in os.environ:
        os.environ[NUMPY_HUGEPAGE] = "0"
        made["numpy_small_pages"] = _numpy_loaded_without_hugepages()
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            mallopt = ctypes.CDLL(None).mallopt
        except (OSError, AttributeError):  # not glibc (musl has no mallopt)
            return made
        mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
        mallopt.restype = ctypes.c_int
        made["malloc_thresholds"] = bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)
                                         and mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))
    return made


def _numpy_loaded_without_hugepages() -> bool:
    """True: numpy, when it loads, reads the switch just set; where it is loaded already
    (a start-up hook imported it), its requests are turned off in place."""
    np = sys.modules.get("numpy")
    if np is None:
        return True
    core = getattr(np, "_core", None) or getattr(np, "core", None)
    setter = getattr(getattr(core, "multiarray", None), "_set_madvise_hugepage", None)
    if setter is None:
        return False
    setter(False)
    return True
