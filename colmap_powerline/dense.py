"""Fill the voids of a dense cloud with the wires: ``colmap-powerline fill``.

Dense matching (COLMAP's ``fused.ply``, Pix4D, Metashape) leaves the wires out. :func:`fill`
streams a dense PLY (binary or ASCII; xyz plus optional colours and normals, as COLMAP
writes it) in chunks through a memory map, so memory stays bounded whatever its size; adds
the fitted wires (every 0.1 m, and the measured points with ``include_measured``) with a
class; optionally drops the dense cloud's stray points around the wires (the halo dense
matching leaves along them: within ``halo_m`` of a wire's track but off the wire); and
writes PLY and, with ``las``, LAS 1.4 with ASPRS classes.

Classes: 1 unclassified, 2 ground (dense points within ``ground_tolerance_m`` of the ground
surface, estimated from the dense cloud's own lowest points per cell), 13 shield wire,
14 conductor, 15 tower (dense points above the ground within a support's reach of its
centre, its cross-arms, plus ``tower_margin_m``, and up to its top plus that margin; the
supports ``reconstruct`` found, from ``wires.json``).
"""

from __future__ import annotations

import dataclasses
import json
import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from .errors import InputError
from .export import read_point_cloud
from .files import ply_header, write_atomic
from .georef import crs_converter, frame_wkt
from .las import CONDUCTOR, GROUND, TOWER, UNCLASSIFIED, WIRE_CLASS, write_las
from .scene import GroundModel

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]
_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip


# The vertex layout of COLMAP's fused.ply (stereo_fusion): float xyz and normals, uchar RGB.
FUSED_PLY_DTYPE = np.dtype(
    [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4"),
     ("red", "u1"), ("green", "u1"), ("blue", "u1")]
)  # fmt: skip


@dataclass(frozen=True)
class PlyVertices:
    """The vertex block of a PLY file, readable in chunks."""

    path: Path
    count: int
    dtype: np.dtype
    offset: int  # bytes before the vertex data
    binary: bool

    def chunks(self, size: int = 1_000_000) -> Iterator[np.ndarray]:
        """Structured arrays of at most ``size`` vertices, in file order."""
        if self.binary:
            for k in range(0, self.count, size):
                # One short-lived map per chunk: mapped file pages would otherwise stay
                # resident and grow the RSS with the file.
                n = min(size, self.count - k)
                data = np.memmap(
                    self.path,
                    self.dtype,
                    mode="r",
                    offset=self.offset + k * self.dtype.itemsize,
                    shape=n,
                )
                chunk = np.array(data)
                del data
                yield chunk
            return
        with self.path.open("rb") as f:
            f.seek(self.offset)
            left = self.count
            while left > 0:
                n = min(size, left)
                rows = np.loadtxt(f, dtype=np.float64, max_rows=n, ndmin=2)
                if len(rows) < n:
                    raise InputError(
                        f"{self.path}: PLY ends after {self.count - left + len(rows)}"
                        f" of {self.count} vertices"
                    )
                out = np.zeros(n, self.dtype)
                for i, name in enumerate(self.dtype.names or ()):
                    out[name] = rows[:, i]
                left -= n
                yield out


def open_ply(path: Path | str) -> PlyVertices:
    """Parse a PLY header (one-line errors for anything this cannot read)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: dense cloud does not exist")
    with path.open("rb") as f:
        if f.readline().strip() != b"ply":
            raise InputError(f"{path}: not a PLY file")
        fmt, count, props, in_vertex, seen_vertex = None, 0, [], False, False
        while True:
            line = f.readline()
            if not line:
                raise InputError(f"{path}: PLY header has no end_header")
            words = line.decode("ascii", "replace").split()
            if not words or words[0] in ("comment", "obj_info"):
                continue
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "element":
                if seen_vertex and words[1] != "vertex":
                    in_vertex = False  # faces etc. follow the vertices: not needed
                    continue
                if words[1] != "vertex":
                    raise InputError(f"{path}: element {words[1]!r} before the vertices")
                in_vertex, seen_vertex, count = True, True, int(words[2])
            elif words[0] == "property" and in_vertex:
                if words[1] == "list":
                    raise InputError(f"{path}: list property in the vertices")
                if words[1] not in _PLY_TYPES:
                    raise InputError(f"{path}: unknown PLY type {words[1]!r}")
                props.append((words[2], _PLY_TYPES[words[1]]))
            elif words[0] == "end_header":
                offset = f.tell()
                break
    if fmt not in ("binary_little_endian", "binary_big_endian", "ascii"):
        raise InputError(f"{path}: unsupported PLY format {fmt!r}")
    names = [n for n, _ in props]
    if not {"x", "y", "z"} <= set(names):
        raise InputError(f"{path}: PLY vertices have no x, y, z")
    endian = ">" if fmt == "binary_big_endian" else "<"
    dtype = np.dtype([(n, endian + t) for n, t in props])
    binary = fmt != "ascii"
    if binary and path.stat().st_size < offset + count * dtype.itemsize:
        raise InputError(f"{path}: PLY is truncated ({count} vertices announced)")
    return PlyVertices(path, count, dtype, offset, binary)


def _xyz(chunk: np.ndarray) -> F64:
    return np.c_[chunk["x"], chunk["y"], chunk["z"]].astype(np.float64)


def _rgb(chunk: np.ndarray) -> npt.NDArray[np.uint8] | None:
    names = chunk.dtype.names or ()
    for r, g, b in (("red", "green", "blue"), ("r", "g", "b")):
        if {r, g, b} <= set(names):
            return np.c_[chunk[r], chunk[g], chunk[b]].astype(np.uint8)
    return None


@dataclass
class WireSet:
    """The wires of a ``wires.json``: points every 0.1 m (+ measured), class, id."""

    fitted: F64
    fitted_id: npt.NDArray[np.int32]
    fitted_class: npt.NDArray[np.uint8]
    measured: F64
    measured_id: npt.NDArray[np.int32]
    measured_class: npt.NDArray[np.uint8]
    crs: str
    # The model frame → ``crs`` conversion the wires were written with; None when they
    # are in the model frame.
    from_model: Callable[[F64], F64] | None = None
    wkt: str | None = None  # the CRS of their coordinates, when geographic (for LAS)
    # The supports (towers, poles): (K, 5) x, y, ground z, top z, reach in plan.
    supports: F64 = dataclasses.field(default_factory=lambda: np.zeros((0, 5)))


def load_wires(wires_path: Path | str) -> WireSet:
    """Read ``wires.json`` (and ``wire_points.ply`` beside it, when there)."""
    wires_path = Path(wires_path)
    try:
        doc = json.loads(wires_path.read_text())
        wires = doc["wires"]
        polys = [np.asarray(w["polyline"], np.float64).reshape(-1, 3) for w in wires]
        supports: F64 = np.array(
            [[*t["position"], t["top_z"], t.get("reach_m", 0.0)] for t in doc.get("supports", [])],
            np.float64,
        ).reshape(-1, 5)
    except FileNotFoundError:
        raise InputError(f"{wires_path}: wires file does not exist") from None
    except (ValueError, KeyError, TypeError) as e:
        raise InputError(f"{wires_path}: not a colmap-powerline wires.json ({e})") from None
    cls_of = {int(w["id"]): WIRE_CLASS.get(w.get("kind", "conductor"), CONDUCTOR) for w in wires}
    ids = np.repeat(np.array([w["id"] for w in wires], np.int32), [len(p) for p in polys])
    measured = np.zeros((0, 3))
    measured_id = np.zeros(0, np.int32)
    ply = wires_path.parent / "wire_points.ply"
    if ply.exists():
        pts, _, labels = read_point_cloud(ply)
        if labels is not None:
            on_wire = labels >= 0
            measured, measured_id = pts[on_wire], labels[on_wire].astype(np.int32)
    crs = str(doc.get("crs", "model frame"))
    from_model, wkt = None, None
    origin = _origin(doc)
    if crs != "model frame":
        try:
            output_crs = str(doc["options"]["output_crs"])
            if origin is None:
                raise ValueError
            from_model = crs_converter(origin, output_crs)[0]
            wkt = frame_wkt(origin, output_crs)
        except (KeyError, TypeError, ValueError):
            raise InputError(
                f"{wires_path}: written in {crs} without the georeference it came from "
                "(georeference.origin_wgs84, options.output_crs)"
            ) from None
    return WireSet(
        fitted=np.concatenate(polys) if polys else np.zeros((0, 3)),
        fitted_id=ids,
        fitted_class=np.array([cls_of[int(i)] for i in ids], np.uint8),
        measured=measured,
        measured_id=measured_id,
        measured_class=np.array([cls_of.get(int(i), CONDUCTOR) for i in measured_id], np.uint8),
        crs=crs,
        supports=supports,
        from_model=from_model,
        wkt=wkt if wkt is not None or origin is None else frame_wkt(origin, None),
    )


def _origin(doc: dict) -> tuple[float, float, float] | None:
    """The WGS84 origin of the model frame a ``wires.json`` records, if any."""
    try:
        lat, lon, alt = (float(v) for v in doc["georeference"]["origin_wgs84"])
    except (KeyError, TypeError, ValueError):
        return None
    return lat, lon, alt


def _check_overlap(
    dense_path: Path | str, wires_path: Path | str, wires: WireSet, lo: F64, hi: F64
) -> None:
    """Refuse a cloud and wires that are not in one frame: most of the wires must lie over
    the cloud in plan (a wire may run past a cloud's edge)."""
    if not len(wires.fitted) or not np.all(np.isfinite(lo)):
        return
    margin = 0.05 * float(np.max(hi - lo)) + 1.0
    xy = wires.fitted[:, :2]
    inside = np.all((xy >= lo - margin) & (xy <= hi + margin), axis=1)
    if inside.mean() < 0.5:
        raise InputError(
            f"{dense_path}: the wires of {wires_path} ({wires.crs}) lie outside this cloud "
            f"(x {lo[0]:.1f}..{hi[0]:.1f}, y {lo[1]:.1f}..{hi[1]:.1f} in that frame): "
            "not the same frame"
        )


@dataclass
class FillResult:
    output_path: Path
    las_path: Path | None
    num_dense: int
    num_dropped: int
    num_ground: int
    num_wire_points: int
    num_tower: int = 0  # dense points on the supports (class 15)


def dense_ground(ply: PlyVertices, cell: float = 1.0, chunk: int = 1_000_000) -> GroundModel:
    """A ground surface from a dense cloud, in one streamed pass: the 5th percentile of each
    ``cell`` (its lowest point when the cell is sparse), so stray points below the ground
    do not make the surface."""
    lowest: dict[int, float] = {}
    bias = 1 << 30  # cell indices as non-negative 31-bit halves of one int64 key
    for c in ply.chunks(chunk):
        xyz = _xyz(c)
        ij = np.floor(xyz[:, :2] / cell).astype(np.int64) + bias
        key = (ij[:, 0] << 31) | ij[:, 1]
        order = np.lexsort((xyz[:, 2], key))  # by cell, then by height
        k_sorted = key[order]
        starts = np.flatnonzero(np.r_[True, k_sorted[1:] != k_sorted[:-1]])
        counts = np.diff(np.r_[starts, len(order)])
        q = xyz[order[starts + (0.05 * (counts - 1)).astype(np.int64)], 2]
        for k, z in zip(k_sorted[starts].tolist(), q.tolist(), strict=True):
            if z < lowest.get(k, np.inf):
                lowest[k] = z
    keys = np.fromiter(lowest.keys(), np.int64, len(lowest))
    z = np.fromiter(lowest.values(), np.float64, len(lowest))
    ij = np.c_[keys >> 31, keys & ((1 << 31) - 1)] - bias
    return GroundModel((ij + 0.5) * cell, z, cell)


def fill(
    dense_path: Path | str,
    wires_path: Path | str,
    output_path: Path | str,
    *,
    include_measured: bool = False,
    drop_stray: bool = False,
    halo_m: float = 1.0,
    wire_tolerance_m: float = 0.3,
    ground_cell_m: float = 1.0,
    ground_tolerance_m: float = 0.3,
    tower_margin_m: float = 1.5,
    las: bool = False,
    crs_wkt: str | None = None,
    chunk: int = 1_000_000,
    ground: GroundModel | None = None,
    dense_frame: str = "model",
) -> FillResult:
    """Merge the wires into a dense cloud; write ``output_path`` (PLY) and, with ``las``,
    the same points as LAS beside it (``.las``). ``ground``: the cloud's
    :func:`dense_ground` when the caller has it already (it is one pass over the cloud),
    in the cloud's own frame.

    ``dense_frame``: the frame of the cloud's points. ``"model"`` (COLMAP's fused.ply: the
    model the wires came from): when the wires were written in a projected CRS
    (``wires.json``'s ``crs``), the cloud is converted to it the same way, so the merged
    cloud is all in that CRS. ``"wires"``: the cloud is in the wires' frame already (a
    georeferenced cloud from other software in the same CRS)."""
    if dense_frame not in ("model", "wires"):
        raise InputError(f"dense frame {dense_frame!r}: 'model' or 'wires'")
    ply = open_ply(dense_path)
    wires = load_wires(wires_path)
    dense_to_crs = wires.from_model if dense_frame == "model" else None
    to_wires: Callable[[F64], F64] = (lambda xyz: xyz) if dense_to_crs is None else dense_to_crs
    output_path = Path(output_path)
    if output_path.suffix.lower() != ".ply":
        raise InputError(f"{output_path}: the merged cloud is written as PLY (name it .ply)")
    wire_pts = np.concatenate(
        [wires.fitted, wires.measured if include_measured else np.zeros((0, 3))]
    )
    wire_id = np.concatenate(
        [wires.fitted_id, wires.measured_id if include_measured else np.zeros(0, np.int32)]
    )
    wire_cls = np.concatenate(
        [wires.fitted_class, wires.measured_class if include_measured else np.zeros(0, np.uint8)]
    )
    if ground is None:
        ground = dense_ground(ply, ground_cell_m, chunk)
    if dense_to_crs is not None:
        cells = dense_to_crs(np.c_[ground.cells_xy, ground.cells_z])
        ground = GroundModel(cells[:, :2], cells[:, 2], ground.cell_size)
    ground_tree = cKDTree(ground.cells_xy)
    support_tree = cKDTree(wires.supports[:, :2]) if len(wires.supports) else None
    wire_tree = cKDTree(wires.fitted) if len(wires.fitted) else None
    wire_tree_xy = cKDTree(wires.fitted[:, :2]) if len(wires.fitted) else None

    def classify(xyz: F64) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.uint8]]:
        _, gi = ground_tree.query(xyz[:, :2])
        near_ground = np.abs(xyz[:, 2] - ground.cells_z[gi]) <= ground_tolerance_m
        cls = np.where(near_ground, GROUND, UNCLASSIFIED).astype(np.uint8)
        if support_tree is not None:
            # Above the ground within a support's reach (its cross-arms) and up to its top
            # (+ tower_margin_m): the tower or pole.
            sup = wires.supports
            d, si = support_tree.query(xyz[:, :2])
            tower = (
                ~near_ground
                & (d <= sup[si, 4] + tower_margin_m)
                & (xyz[:, 2] <= sup[si, 3] + tower_margin_m)
            )
            cls[tower] = TOWER
        keep = np.ones(len(xyz), bool)
        if drop_stray and wire_tree is not None and wire_tree_xy is not None:
            d_xy, wi = wire_tree_xy.query(xyz[:, :2], distance_upper_bound=halo_m)
            near = np.isfinite(d_xy)
            in_halo = np.zeros(len(xyz), bool)
            in_halo[near] = np.abs(xyz[near, 2] - wires.fitted[wi[near], 2]) <= halo_m
            if in_halo.any():
                d3, _ = wire_tree.query(xyz[in_halo])
                keep[np.flatnonzero(in_halo)[d3 > wire_tolerance_m]] = False
        return keep, cls

    # One classifying pass keeps a byte of class and a keep flag per point (and the
    # cloud's minimum corner for the LAS offset); the writing passes only read.
    keeps, classes = [], []
    lo = wire_pts.min(axis=0) if len(wire_pts) else np.full(3, np.inf)
    dense_lo, dense_hi = np.full(2, np.inf), np.full(2, -np.inf)
    for c in ply.chunks(chunk):
        xyz = to_wires(_xyz(c))
        keep, cls = classify(xyz)
        keeps.append(keep)
        classes.append(cls)
        if len(xyz):
            lo = np.minimum(lo, xyz.min(axis=0))
            dense_lo = np.minimum(dense_lo, xyz[:, :2].min(axis=0))
            dense_hi = np.maximum(dense_hi, xyz[:, :2].max(axis=0))
    _check_overlap(dense_path, wires_path, wires, dense_lo, dense_hi)
    keep_all = np.concatenate(keeps) if keeps else np.zeros(0, bool)
    cls_all = np.concatenate(classes) if classes else np.zeros(0, np.uint8)
    n_keep = int(keep_all.sum())
    n_ground = int(((cls_all == GROUND) & keep_all).sum())
    n_tower = int(((cls_all == TOWER) & keep_all).sum())

    def chunks_out() -> Iterator[tuple[F64, npt.NDArray, npt.NDArray, npt.NDArray[np.uint8]]]:
        k = 0
        for c in ply.chunks(chunk):
            keep, cls = keep_all[k : k + len(c)], cls_all[k : k + len(c)]
            k += len(c)
            rgb = _rgb(c)
            if rgb is None:
                rgb = np.full((len(c), 3), 160, np.uint8)
            yield (
                to_wires(_xyz(c))[keep],
                cls[keep],
                np.full(int(keep.sum()), -1, np.int32),
                rgb[keep],
            )
        colors = np.where(wire_cls[:, None] == CONDUCTOR, [255, 40, 40], [40, 40, 255])
        yield wire_pts, wire_cls, wire_id, colors.astype(np.uint8)

    out_dtype = np.dtype(
        [("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("red", "u1"), ("green", "u1"),
         ("blue", "u1"), ("class", "u1"), ("wire_id", "<i4")]
    )  # fmt: skip
    comment = (
        f"colmap-powerline fill: {ply.path.name} + {Path(wires_path).name} "
        f"(coordinates: {wires.crs})"
    )

    def write_ply(tmp: Path) -> None:
        with tmp.open("wb") as f:
            f.write(ply_header(out_dtype, n_keep + len(wire_pts), [comment]))
            for xyz, cls, wid, rgb in chunks_out():
                rec = np.zeros(len(xyz), out_dtype)
                rec["x"], rec["y"], rec["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
                rec["red"], rec["green"], rec["blue"] = rgb[:, 0], rgb[:, 1], rgb[:, 2]
                rec["class"], rec["wire_id"] = cls, wid
                f.write(rec.tobytes())

    write_atomic(output_path, write_ply)
    las_path = None
    if las:
        wkt = crs_wkt if crs_wkt is not None else wires.wkt
        las_path = write_las(output_path.with_suffix(".las"), chunks_out(), lo, wkt)
    result = FillResult(
        output_path, las_path, ply.count, ply.count - n_keep, n_ground, len(wire_pts), n_tower
    )
    logger.info(
        "fill: %d dense points (%d ground, %d on %d supports%s) + %d wire points → %s%s",
        ply.count,
        n_ground,
        n_tower,
        len(wires.supports),
        f", {result.num_dropped} stray points dropped" if drop_stray else "",
        len(wire_pts),
        output_path,
        f" and {las_path}" if las_path else "",
    )
    return result
