"""Worker process of the add-on: runs one task of ``_tasks.py`` and reports on stdout.

Started by :class:`_jobs.Job` as ``python _worker.py SPEC.json`` or, for a task that needs
Blender (the Cycles render), ``blender --background --factory-startup --python _worker.py --
SPEC.json``.  ``SPEC.json`` holds ``task``, ``params``, ``tasks_file`` and
``render_inspect_path`` (the folder holding the add-on's render_inspect package: inside the
extension, its bundled copy); the environment variable ``RENDER_INSPECT_SYS_PATH`` holds the
parent's ``sys.path`` (where Blender put the extension's wheels).  Both are appended to the
worker's own ``sys.path``.  Lines starting with :data:`PREFIX` carry JSON: ``{"progress": f,
"message": s}`` while working, then ``{"result": {...}}`` or ``{"error": "one line"}``.
SIGTERM (Esc in Blender) raises SystemExit, so output folders being written are removed.
"""

import importlib.util
import json
import os
import signal
import sys
import traceback

PREFIX = "@render_inspect@ "


def emit(obj) -> None:
    sys.stdout.write(PREFIX + json.dumps(obj) + "\n")
    sys.stdout.flush()


def _stop(signum, frame):
    raise SystemExit(128 + signum)


def main(argv) -> int:
    with open(argv[-1], encoding="utf-8") as fh:
        spec = json.load(fh)
    # after this interpreter's own entries: its bpy (the module, not Blender's scripts/modules
    # package of the same name) must win; the extension's wheels are found at the end
    extra = json.loads(os.environ.get("RENDER_INSPECT_SYS_PATH", "[]"))
    if spec.get("render_inspect_path"):
        extra.insert(0, spec["render_inspect_path"])
    for entry in extra:
        if entry not in sys.path:
            sys.path.append(entry)
    signal.signal(signal.SIGTERM, _stop)
    loader = importlib.util.spec_from_file_location("render_inspect_addon_tasks", spec["tasks_file"])
    tasks = importlib.util.module_from_spec(loader)
    loader.loader.exec_module(tasks)
    try:
        result = tasks.run(spec["task"], spec["params"],
                           lambda f, m: emit({"progress": float(f), "message": str(m)}))
    except Exception as err:  # reported to the user in one line; the traceback to stderr
        try:
            from render_inspect.errors import RenderInspectError
            expected = isinstance(err, (RenderInspectError, OSError))
        except ImportError:
            expected = False
        if not expected:
            traceback.print_exc()
        emit({"error": str(err) if expected else f"{type(err).__name__}: {err}"})
        return 1
    emit({"result": result})
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
