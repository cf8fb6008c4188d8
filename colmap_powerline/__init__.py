"""colmap-powerline: overhead power-line conductors in 3D from drone images and a COLMAP model."""

from typing import Any

from .errors import InputError
from .options import OptionError
from .scene import Scene, SceneImage, load_scene

__all__ = [
    "ExecutionOptions",
    "InputError",
    "OptionError",
    "OutputOptions",
    "ReconstructionOptions",
    "ReconstructionResult",
    "Scene",
    "SceneImage",
    "SfmOptions",
    "load_scene",
    "reconstruct",
    "run_sfm",
    "write_outputs",
]
__version__ = "0.1.0"

_LAZY = {
    "reconstruct": "pipeline",
    "write_outputs": "pipeline",
    "ReconstructionOptions": "results",
    "ReconstructionResult": "results",
    "OutputOptions": "results",
    "ExecutionOptions": "tasks",
    "run_sfm": "sfm",
    "SfmOptions": "sfm",
}


def __getattr__(name: str) -> Any:
    # The pipeline pulls in open3d: import it only when it is used.
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
