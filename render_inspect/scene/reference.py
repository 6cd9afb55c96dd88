"""Print the scene-key reference (Markdown): ``python -m render_inspect.scene.reference``."""

from ._reference import scene_reference_markdown

if __name__ == "__main__":
    print(scene_reference_markdown(), end="")
