"""The functions Blender calls back for the add-on's properties (``update=``, ``items=``).

Blender keeps a reference to each from its own C data until it shuts down.  In Blender 4.2
(and bpy 4.2 as a module) that shutdown runs only when the ``bpy`` module object is freed
at interpreter exit; a callback whose module globals hold ``bpy`` (or any module that
leads to it) keeps ``bpy`` alive, Blender's shutdown never runs, and its static destructors
then free the registered Python classes after Python has gone: a segmentation fault at
exit.  So this module holds no module at its top level: it imports what it needs inside
the functions, and holds only plain data (tests/test_blender_addon.py checks).
"""

#: Variants before the first Simulate: the turning pair.
DEFAULT_VARIANT_ITEMS = (("compensated", "Compensated", "The compensated tool path"),
                         ("uncompensated", "Uncompensated",
                          "The same part cut without compensation"))
#: Blender keeps only pointers to the strings of dynamic enum items: they live here.
VARIANT_ITEMS: list = []


def scene_changed(self, context):
    """``preset`` / ``scene_path`` changed: read the scene's numbers into ``params``."""
    from ._scenes import load_params

    load_params(self)


def variant_items(self, context):
    """The two variants of the last Simulate, in order (the process's own pair:
    compensated / uncompensated for turning, servo lag / ideal servo, vibration on /
    off, RCSE / conventional); the turning pair before the first Simulate."""
    import json

    try:
        sim = json.loads(self.simulation_json) if self.simulation_json else {}
    except ValueError:
        sim = {}
    variants = sim.get("variants") if isinstance(sim, dict) else None
    items = [(str(name), str(name).replace("_", " ").capitalize(),
              str((info or {}).get("label", name))[:200])
             for name, info in (variants or {}).items()]
    VARIANT_ITEMS[:] = items or DEFAULT_VARIANT_ITEMS
    return VARIANT_ITEMS
