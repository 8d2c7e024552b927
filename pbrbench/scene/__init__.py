"""Scene files: specification (:mod:`.spec`), loading (:mod:`.load`) and the Mitsuba builder."""

from pbrbench.scene.load import load_library, load_scene_file, resolve
from pbrbench.scene.spec import SceneSpec

__all__ = ["SceneSpec", "load_library", "load_scene_file", "resolve"]
