"""File helpers every output uses, without open3d: atomic writes, binary PLY headers, and
the colours wires are drawn in (so that LAS, the dense-cloud fill and the report need not
load open3d)."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

_PALETTE = np.array(
    [
        [230, 25, 75],
        [60, 180, 75],
        [255, 225, 25],
        [0, 130, 200],
        [245, 130, 48],
        [145, 30, 180],
        [70, 240, 240],
        [240, 50, 230],
        [210, 245, 60],
        [250, 190, 212],
        [0, 128, 128],
        [220, 190, 255],
        [170, 110, 40],
        [128, 0, 0],
        [170, 255, 195],
    ],
    dtype=np.uint8,
)


_PLY_NAMES = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort", "i4": "int",
              "u4": "uint", "f4": "float", "f8": "double"}  # fmt: skip


def ply_header(dtype: np.dtype, count: int, comments: Sequence[str] = ()) -> bytes:
    """The header of a binary little-endian PLY whose vertices are ``dtype`` records."""
    lines = ["ply", "format binary_little_endian 1.0", *(f"comment {c}" for c in comments)]
    lines.append(f"element vertex {count}")
    for name in dtype.names or ():
        lines.append(f"property {_PLY_NAMES[dtype[name].str[1:]]} {name}")
    return ("\n".join(lines) + "\nend_header\n").encode("ascii")


def wire_colors(ids: npt.ArrayLike) -> npt.NDArray[np.uint8]:
    """(N,) wire ids → (N, 3) uint8 colours: a fixed palette per id, grey for -1."""
    ids = np.asarray(ids, np.int64)
    out = _PALETTE[np.mod(ids, len(_PALETTE))]
    out[ids < 0] = 128
    return out


def write_atomic(path: Path | str, write_fn: Callable[[Path], Any]) -> Path:
    """Call ``write_fn(tmp_path)`` and move the result to ``path`` only if it succeeded."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        write_fn(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path
