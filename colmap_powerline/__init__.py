"""colmap-powerline: overhead power-line conductors in 3D from drone images and a COLMAP model."""

from .errors import InputError
from .scene import Scene, SceneImage, load_scene

__all__ = ["InputError", "Scene", "SceneImage", "load_scene"]
__version__ = "0.1.0"
