"""Outputs: wires.json, wires.ply, wire_points.ply (and primitives.ply), written atomically.

Point clouds go through open3d's tensor API so that the per-point ``wire_id`` label is a
PLY property that open3d (and CloudCompare, PDAL, …) read back. Each file is written to a
temporary name in the output folder and renamed into place only when complete, so a
failed run never leaves a half-written file, and a previous run's file survives a failed
rewrite.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import open3d as o3d

from .clearance import WireMeasures, measures_csv
from .coverage import WireCoverage
from .files import ply_header, wire_colors, write_atomic
from .spans import LineSupport, WireSpan, supports_csv
from .support import WireSupport
from .wires import FittedWire

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]


def write_point_cloud(
    path: Path | str,
    pts: F64,
    colors: npt.NDArray[Any] | None = None,
    labels: npt.NDArray[Any] | None = None,
) -> Path:
    """Binary PLY with xyz (float64), optional uint8 colours and an int32 ``wire_id``."""
    pts = np.asarray(pts, np.float64).reshape(-1, 3)
    pcd = o3d.t.geometry.PointCloud(o3d.core.Tensor(pts, o3d.core.float64))
    if colors is not None:
        c = np.asarray(colors)
        c = c.astype(np.float64) / 255.0 if c.dtype == np.uint8 else c.astype(np.float64)
        pcd.point.colors = o3d.core.Tensor(c.reshape(-1, 3), o3d.core.float64)
    if labels is not None:
        pcd.point.wire_id = o3d.core.Tensor(
            np.asarray(labels, np.int32).reshape(-1, 1), o3d.core.int32
        )

    def write(tmp: Path) -> None:
        if len(pts) == 0:  # open3d refuses to write an empty cloud; a reader expects a file
            fields = [("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
            fields += [(c, "<f8") for c in ("red", "green", "blue")] if colors is not None else []
            fields += [("wire_id", "<i4")] if labels is not None else []
            tmp.write_bytes(ply_header(np.dtype(fields), 0))
            return
        if not o3d.t.io.write_point_cloud(str(tmp), pcd, write_ascii=False):
            raise OSError(f"{path}: open3d could not write the point cloud")

    return write_atomic(path, write)


def read_point_cloud(
    path: Path | str,
) -> tuple[F64, npt.NDArray[np.uint8] | None, npt.NDArray[np.int32] | None]:
    """(points, colours or None, wire ids or None) of a PLY written by :func:`write_point_cloud`."""
    pcd = o3d.t.io.read_point_cloud(str(path))
    pts = pcd.point.positions.numpy().astype(np.float64)
    colors = labels = None
    if "colors" in pcd.point:
        c = pcd.point.colors.numpy()
        colors = (np.clip(c, 0, 1) * 255 + 0.5).astype(np.uint8) if c.dtype != np.uint8 else c
    if "wire_id" in pcd.point:
        labels = pcd.point.wire_id.numpy().reshape(-1).astype(np.int32)
    return pts, colors, labels


def _finite(obj: Any) -> Any:
    """Replace NaN/inf by None so the JSON is strict."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    if isinstance(obj, np.generic):
        return _finite(obj.item())
    return obj


def _convert_measures(m: WireMeasures, convert: Callable[[F64], F64]) -> WireMeasures:
    """The measures with their points in another CRS (lengths and clearances unchanged)."""

    def pt(p: list[float]) -> list[float]:
        return convert(np.array([p], np.float64))[0].tolist()

    return dataclasses.replace(
        m,
        lowest_point=pt(m.lowest_point),
        clearance_vertical_point=pt(m.clearance_vertical_point),
        clearance_3d_point=pt(m.clearance_3d_point),
        flagged=[
            dataclasses.replace(f, lowest_clearance_point=pt(f.lowest_clearance_point))
            for f in m.flagged
        ],
    )


def export_results(
    output_path: Path,
    *,
    wires: Sequence[FittedWire],
    points: F64,
    labels: npt.NDArray[np.int64],
    primitives: F64 | None,
    metadata: dict[str, Any],
    ground_height: Callable[[F64], F64] | None = None,
    sample_step: float = 0.1,
    to_crs: tuple[Callable[[F64], F64], str] | None = None,
    measures: Sequence[WireMeasures] | None = None,
    supports: Sequence[WireSupport] | None = None,
    coverage: Sequence[WireCoverage] | None = None,
    placement: Sequence[WireSpan] | None = None,
    line_supports: Sequence[LineSupport] | None = None,
) -> dict[str, Path]:
    """Write the output contract of DESIGN.md into ``output_path``; returns the files.

    ``to_crs`` = (function, name) writes every coordinate (points, polylines, ends, lowest
    points) in that CRS instead of the model frame; the catenary parameters and the wire's
    vertical plane stay in the model frame, where the catenary is a catenary.
    """
    output_path = Path(output_path)
    output_path.mkdir(parents=True, exist_ok=True)
    out: dict[str, Path] = {}
    convert: Callable[[F64], F64] = (lambda xyz: xyz) if to_crs is None else to_crs[0]
    wire_docs = [w.to_json(ground_height, sample_step) for w in wires]
    if measures is not None:
        measures = [_convert_measures(m, convert) for m in measures] if to_crs else measures
        for d, m in zip(wire_docs, measures, strict=True):
            d["clearance_m"] = m.clearance_vertical_m
            d["kind"] = m.kind
            d["measures"] = m.to_json()
    if supports is not None:
        for d, sup in zip(wire_docs, supports, strict=True):
            d["support"] = sup.to_json()
    if coverage is not None:
        for k, (d, cov) in enumerate(zip(wire_docs, coverage, strict=True)):
            d["coverage"] = cov.to_json()
            if measures is not None:  # no: its sag there comes from its curve continued
                d["coverage"]["sag_max_at_measured"] = cov.measured_at(measures[k].sag_max_at_m)
    if placement is None:  # one line, one span, no support found
        placement = [WireSpan(1, 1, (None, None), w.wire_id) for w in wires]
    for d, pl in zip(wire_docs, placement, strict=True):
        d.update(pl.to_json())
    if to_crs is not None:
        for d in wire_docs:
            for gap in d.get("coverage", {}).get("gaps", []):
                gap["at"] = convert(np.array([gap["at"]]))[0].tolist()
            for key in ("ends", "polyline"):
                d[key] = np.round(convert(np.array(d[key])), 4).tolist()
            d["lowest_point"] = convert(np.array([d["lowest_point"]]))[0].tolist()
    doc = {
        **metadata,
        "crs": to_crs[1] if to_crs is not None else "model frame",
        "catenary_frame": "model frame",
        "supports": [
            sup.to_json(convert if to_crs is not None else None) for sup in line_supports or []
        ],
        "wires": wire_docs,
    }
    text = json.dumps(_finite(doc), allow_nan=False)
    out["wires.json"] = write_atomic(output_path / "wires.json", lambda p: p.write_text(text))
    if measures is not None:
        table = measures_csv(measures, supports, coverage, placement)
        out["wires.csv"] = write_atomic(output_path / "wires.csv", lambda p: p.write_text(table))
    if line_supports is not None:
        rows = supports_csv(line_supports, convert if to_crs is not None else None)
        out["supports.csv"] = write_atomic(
            output_path / "supports.csv", lambda p: p.write_text(rows)
        )
    dense = [w.polyline(sample_step) for w in wires]
    ids = (
        np.concatenate([np.full(len(d), w.wire_id) for d, w in zip(dense, wires, strict=True)])
        if wires
        else np.zeros(0, np.int64)
    )
    dense_pts = convert(np.concatenate(dense)) if dense else np.zeros((0, 3))
    points = convert(points) if len(points) else points
    out["wires.ply"] = write_point_cloud(
        output_path / "wires.ply", dense_pts, wire_colors(ids), ids
    )
    # Only the points of the reported wires: the rest failed the whole-wire check or fit
    # no wire, and would be noise in a cloud whose voids they fill.
    on = labels >= 0
    out["wire_points.ply"] = write_point_cloud(
        output_path / "wire_points.ply", points[on], wire_colors(labels[on]), labels[on]
    )
    if primitives is not None:
        out["primitives.ply"] = write_point_cloud(
            output_path / "primitives.ply", convert(primitives) if len(primitives) else primitives
        )
    logger.info("export: %s", ", ".join(str(p) for p in out.values()))
    return out
