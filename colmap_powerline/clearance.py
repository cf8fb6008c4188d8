"""Sag and ground clearance of every fitted wire: the numbers an inspection checks.

Sag is measured as inspectors define it: the vertical distance between the chord joining the
wire's two ends and the wire — its maximum over the span and its value at mid-span. The
clearance is measured to a ground *surface* interpolated from ground points (the sparse
model's, or a dense cloud's when one is given): the minimum vertical distance (the wire
straight above the ground) and the minimum 3D distance (to a bank or a slope beside it), with
where along the wire each happens. ``min_clearance_m`` flags the stretches of a wire that
come closer to the ground than that, vertically.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Hashable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from .coverage import WireCoverage
from .scene import GroundModel
from .spans import SPAN_COLUMNS, WireSpan
from .support import WireSupport
from .wires import FittedWire

F64 = npt.NDArray[np.float64]


@dataclass
class Stretch:
    """A stretch of a wire closer to the ground than the limit (positions along the wire)."""

    s_start_m: float  # horizontal distance from the wire's first end
    s_end_m: float
    min_clearance_m: float
    lowest_clearance_point: list[float]


@dataclass
class WireMeasures:
    """Sag and clearance of one wire (model units; metres when georeferenced)."""

    wire_id: int
    catenary_a_m: float  # catenary constant (horizontal tension / weight per length)
    span_length_m: float  # horizontal distance between the ends
    chord_length_m: float  # straight 3D distance between the ends
    conductor_length_m: float  # arc length between the ends
    sag_max_m: float  # largest vertical distance from the chord to the wire
    sag_max_at_m: float  # where, from the first end (horizontal)
    sag_midspan_m: float  # vertical distance from the chord to the wire at mid-span
    lowest_point: list[float]
    clearance_vertical_m: float  # smallest height of the wire above the ground surface
    clearance_vertical_at_m: float  # where, from the first end
    clearance_vertical_point: list[float]
    clearance_3d_m: float  # smallest 3D distance from the wire to the ground surface
    clearance_3d_at_m: float
    clearance_3d_point: list[float]
    ground_source: str  # "sparse points" or "dense cloud"
    kind: str = "conductor"  # or "shield" (see :func:`assign_kinds`)
    flagged: list[Stretch] = field(default_factory=list)  # closer than min_clearance_m

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def _ground_grid(ground: GroundModel, poly: F64, half_width: float, step: float) -> F64:
    """Ground surface points in a band around the wire's plan track."""
    d = poly[-1, :2] - poly[0, :2]
    length = float(np.linalg.norm(d))
    along = d / max(length, 1e-12)
    across = np.array([-along[1], along[0]])
    s = np.arange(-half_width, length + half_width + step, step)
    c = np.arange(-half_width, half_width + step, step)
    ss, cc = np.meshgrid(s, c)
    xy = poly[0, :2] + ss.reshape(-1, 1) * along + cc.reshape(-1, 1) * across
    return np.c_[xy, ground.height(xy)]


def _stretches(s: F64, clear: F64, poly: F64, limit: float) -> list[Stretch]:
    low = clear < limit
    out = []
    k = 0
    while k < len(low):
        if not low[k]:
            k += 1
            continue
        j = k
        while j + 1 < len(low) and low[j + 1]:
            j += 1
        m = k + int(np.argmin(clear[k : j + 1]))
        out.append(Stretch(float(s[k]), float(s[j]), float(clear[m]), poly[m].tolist()))
        k = j + 1
    return out


def measure_wire(
    wire: FittedWire,
    ground: GroundModel,
    ground_source: str = "sparse points",
    min_clearance_m: float | None = None,
    step: float = 0.1,
    band_m: float = 15.0,
) -> WireMeasures:
    """Sag, lengths and clearance of one fitted wire over a ground surface."""
    lo, hi = wire.s_range
    n = max(int(np.ceil((hi - lo) / step)) + 1, 3)
    s_plane = np.linspace(lo, hi, n)
    poly = wire.points(s_plane)
    s = s_plane - lo  # from the first end
    z = poly[:, 2]
    chord = z[0] + (z[-1] - z[0]) * s / max(s[-1], 1e-12)
    below_chord = chord - z
    k_sag = int(np.argmax(below_chord))
    mid = float(np.interp(0.5 * s[-1], s, below_chord))
    ends = poly[[0, -1]]
    clear_v = z - ground.height(poly[:, :2])
    k_v = int(np.argmin(clear_v))
    surface = _ground_grid(ground, poly, band_m, 0.25)
    d3, _ = cKDTree(surface).query(poly)
    d3 = np.minimum(d3, np.maximum(clear_v, 0.0))  # the grid is 0.25 m: never above vertical
    k_3 = int(np.argmin(d3))
    return WireMeasures(
        wire_id=wire.wire_id,
        catenary_a_m=float(wire.catenary_a),
        span_length_m=float(s[-1]),
        chord_length_m=float(np.linalg.norm(ends[1] - ends[0])),
        conductor_length_m=float(np.linalg.norm(np.diff(poly, axis=0), axis=1).sum()),
        sag_max_m=float(below_chord[k_sag]),
        sag_max_at_m=float(s[k_sag]),
        sag_midspan_m=mid,
        lowest_point=wire.lowest_point().tolist(),
        clearance_vertical_m=float(clear_v[k_v]),
        clearance_vertical_at_m=float(s[k_v]),
        clearance_vertical_point=poly[k_v].tolist(),
        clearance_3d_m=float(d3[k_3]),
        clearance_3d_at_m=float(s[k_3]),
        clearance_3d_point=poly[k_3].tolist(),
        ground_source=ground_source,
        flagged=_stretches(s, clear_v, poly, min_clearance_m) if min_clearance_m else [],
    )


def assign_kinds(
    measures: Sequence[WireMeasures],
    min_gap_m: float = 4.0,
    spans: Sequence[Hashable] | None = None,
) -> None:
    """Mark shield (earth) wires: the one or two wires that run clearly above all the others
    (at least ``min_gap_m`` above the next), when the wires below them are whole three-phase
    circuits (a multiple of three). Phase conductors hang from cross-arms below the tower
    peak that carries the shield wires; but when the shields were not found, the top phases
    of a double circuit are just as clearly above the rest (the package's demo: two of six
    conductors 5 m above the others), and an energised conductor reported as an earth wire
    is the worse mistake: then every wire stays a conductor.

    ``spans``: the span of each wire (e.g. (line, span)); the wires of each span are judged
    on their own (over the whole survey, only the one or two highest wires of all its spans
    could be shields: shared multispan seed 3 reported none of its six)."""
    if spans is not None:
        for key in dict.fromkeys(spans):
            assign_kinds([m for m, s in zip(measures, spans, strict=True) if s == key], min_gap_m)
        return
    heights = np.array([m.clearance_vertical_m for m in measures])
    if len(heights) < 4:
        return
    order = np.argsort(heights)[::-1]
    for top in (1, 2):
        gap = heights[order[top - 1]] - heights[order[top]]
        below = len(heights) - top
        if gap >= min_gap_m and below >= 3 and below % 3 == 0:
            for k in order[:top]:
                measures[k].kind = "shield"
            return


CSV_COLUMNS = (
    "wire_id",
    "kind",
    "catenary_a_m",
    "span_length_m",
    "chord_length_m",
    "conductor_length_m",
    "sag_max_m",
    "sag_max_at_m",
    "sag_midspan_m",
    "lowest_x",
    "lowest_y",
    "lowest_z",
    "clearance_vertical_m",
    "clearance_vertical_at_m",
    "clearance_3d_m",
    "clearance_3d_at_m",
    "flagged_stretches",
    "flagged_length_m",
    "ground_source",
)
SUPPORT_COLUMNS = (
    "views",
    "strips",
    "crossing_views",
    "hit_rate",
    "confidence",
    "geometry",
    "traced_share",
    "confirming_strips",
    "advice",
    "found_by",
)
COVERAGE_COLUMNS = (
    "measured_share",
    "gaps",
    "longest_gap_m",
    "flight_limited_gap_m",
    "pairs_vs_traced_m",
    "sag_max_at_measured",
)


def measures_csv(
    measures: Sequence[WireMeasures],
    supports: Sequence[WireSupport] | None = None,
    coverage: Sequence[WireCoverage] | None = None,
    placement: Sequence[WireSpan] | None = None,
) -> str:
    """One row per wire (the columns of :data:`CSV_COLUMNS`, then with ``supports`` those of
    :data:`SUPPORT_COLUMNS`, with ``coverage`` those of :data:`COVERAGE_COLUMNS`: the gaps
    listed in ``wires.json``, their summed length that the images cannot measure, how far
    the pairs' points lie from the traced ones, whether the wire was measured where it sags
    most: ``no``, its sag there comes from its curve continued),
    millimetre precision."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(
        CSV_COLUMNS
        + (SUPPORT_COLUMNS if supports is not None else ())
        + (COVERAGE_COLUMNS if coverage is not None else ())
        + (SPAN_COLUMNS if placement is not None else ())
    )
    for k, m in enumerate(measures):
        row: list[Any] = [m.wire_id, m.kind]
        row += [
            f"{v:.3f}"
            for v in (
                m.catenary_a_m,
                m.span_length_m,
                m.chord_length_m,
                m.conductor_length_m,
                m.sag_max_m,
                m.sag_max_at_m,
                m.sag_midspan_m,
                *m.lowest_point,
                m.clearance_vertical_m,
                m.clearance_vertical_at_m,
                m.clearance_3d_m,
                m.clearance_3d_at_m,
            )
        ]
        row += [len(m.flagged), f"{sum(f.s_end_m - f.s_start_m for f in m.flagged):.3f}"]
        row.append(m.ground_source)
        if supports is not None:
            sup = supports[k]
            row += [sup.views, sup.strips, sup.crossing_views, f"{sup.hit_rate:.3f}"]
            row += ["" if sup.confidence is None else f"{sup.confidence:.4f}", sup.geometry]
            row.append("" if sup.traced_share is None else f"{sup.traced_share:.3f}")
            row.append(sup.confirming_strips)
            row.append(sup.advice or "")
            row.append(sup.found_by)
        if coverage is not None:
            cov = coverage[k]
            row += [f"{cov.measured_share:.3f}", len(cov.gaps), f"{cov.longest_gap_m:.3f}"]
            row.append(f"{sum(g.length_m for g in cov.gaps if g.flight_limited):.3f}")
            row.append("" if cov.disagreement_m is None else f"{cov.disagreement_m:.3f}")
            row.append("yes" if cov.measured_at(m.sag_max_at_m) else "no")
        if placement is not None:
            pl = placement[k]
            row += [pl.line, pl.span]
            row += ["" if sid is None else sid for sid in pl.supports]
            row.append(pl.conductor)
        writer.writerow(row)
    return buf.getvalue()
