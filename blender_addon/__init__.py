"""render_inspect for Blender: simulate a diamond-machined surface from a scene file,
load it as a mesh (vertical exaggeration stated in the object's custom properties) and
render it with Cycles under the same diffuse light as render_inspect's Mitsuba renders.

The add-on is a thin layer over the ``render_inspect`` Python package, which must be
importable in Blender's Python (with ``pip install bpy`` it is the same environment).
"""

from . import operators, panel, properties

_MODULES = (properties, operators, panel)


def register():
    for module in _MODULES:
        module.register()


def unregister():
    for module in reversed(_MODULES):
        module.unregister()
