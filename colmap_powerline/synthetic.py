"""Synthetic drone flights over one span of a double-circuit power line, with exact truth.

The scene is built in a local east-north-up frame (metres) whose origin is a configurable
WGS84 position: terrain with relief and a multi-scale texture (presets: vegetation, bare
soil, mixed with a road), two lattice towers, six phase conductors and one or two shield
wires hanging as true catenaries, and their shadows. A DJI-Phantom-4-like camera (12 MP,
f = 3.6 mm, 1.58 µm pixels, OPENCV lens distortion) flies nadir strips over it as one
serpentine (:class:`FlightPattern`): a 3- or 4-strip corridor mission along the line, an area
survey whose strips cross the line at an angle, or strips across the line.

:func:`generate_span` writes ``images/`` (JPEG with EXIF GPS), ``sparse_gt/`` (the true
COLMAP model), ``sparse/0/`` (the same model as a bundle adjustment would leave it),
``truth/wires.json``, ``truth/terrain.npz`` and ``truth/scene.json``.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
import time
import warnings
from dataclasses import asdict, dataclass, field
from enum import StrEnum
from functools import cached_property
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import pycolmap
from PIL import ExifTags, Image
from scipy import ndimage
from tqdm import tqdm

from .errors import InputError
from .geometry import across_of, plan_axes
from .render import draw_thin_polyline, fbm, periodic_noise, remap
from .scene import SceneImage, cam_from_img

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]
F32 = npt.NDArray[np.float32]

# DJI Phantom 4 (FC330): 4000 x 3000 px, f = 3.6 mm, 1.58 um pixels. Brown coefficients of
# the order published for this lens; the principal point is slightly off-centre.
FULL_WIDTH_PX, FULL_HEIGHT_PX = 4000, 3000
FOCAL_MM, PIXEL_PITCH_MM = 3.6, 0.00158
DISTORTION_K1_K2_P1_P2 = (-0.0128, 0.0121, 0.00032, -0.00041)
PRINCIPAL_OFFSET_PX = (11.7, -8.3)  # at full resolution


class Background(StrEnum):
    VEGETATION = "vegetation"  # meadow and tree clumps: good wire contrast
    BARE_SOIL = "bare_soil"  # light soil: poor wire contrast
    MIXED = "mixed"  # meadow, a soil field and a road with white markings


class FlightPattern(StrEnum):
    """How the drone's strips lie relative to the line (all flown as one serpentine)."""

    CORRIDOR = "corridor"  # 3 strips along the line, the middle one over it
    ALONG4 = "along4"  # 4 strips along the line, which runs between the two middle ones
    GRID = "grid"  # an area survey: strips at grid_angle_deg to the line, ±60 m across it
    ACROSS = "across"  # strips perpendicular to the line (consecutive images cross them)

    @classmethod
    def _missing_(cls, value: object) -> FlightPattern | None:
        if value == "along":  # the name of "corridor" before along4 and grid existed
            warnings.warn(
                "flight pattern 'along' is deprecated: use 'corridor'",
                DeprecationWarning,
                stacklevel=2,
            )
            return cls.CORRIDOR
        return None


class Layout(StrEnum):
    """What hangs over the ground."""

    SPAN = "span"  # one span of a double circuit between two lattice towers
    ANGLE = "angle"  # two spans, the line turning by turn_deg at the middle (angle) tower;
    # the flight's strips follow each leg (corridor or along4)
    CROSSING = "crossing"  # the span, and a single-circuit line on two poles crossing it
    # at crossing_deg, lower down; an area survey (grid) covers both
    BRANCH = "branch"  # the crossing, its pole line going on for a 25 m span past its second
    # pole, and a two-wire line leaving that pole (a junction) at branch_deg to it, 30 m to
    # a pole of its own; an area survey (grid) covers all three
    PARALLEL = "parallel"  # the span, and a single-circuit pole line parallel to it
    # parallel_offset_m across, lower down, on three poles 45 m apart; an area survey
    # (grid) covers both


# Side overlap of each flight pattern when SyntheticSpanOptions.side_overlap is None.
DEFAULT_SIDE_OVERLAP = {
    FlightPattern.CORRIDOR: 0.65,
    FlightPattern.ALONG4: 0.68,  # a usual 4-strip corridor mission
    FlightPattern.GRID: 0.65,
    FlightPattern.ACROSS: 0.65,
}
GRID_HALF_WIDTH_M = 60.0  # the grid survey covers this far across the line on each side


@dataclass(kw_only=True)
class SyntheticSpanOptions:
    seed: int = 0  # everything is deterministic given the seed
    scale: float = 1.0  # image size relative to 4000 x 3000 px (0.25 → 1000 x 750)
    background: Background = Background.VEGETATION
    flight: FlightPattern = FlightPattern.ACROSS
    span_m: float = 100.0  # horizontal distance between the towers
    num_spans: int = 1  # layout "span": spans in a straight line (a corridor of towers)
    layout: Layout = Layout.SPAN
    turn_deg: float = 25.0  # layout "angle": the line's turn at the angle tower
    crossing_deg: float = 70.0  # layout "crossing": the pole line's angle to the span
    branch_deg: float = 75.0  # layout "branch": the branch line's angle to the pole line
    parallel_offset_m: float = 28.0  # layout "parallel": the pole line's offset across
    line_azimuth_deg: float = 35.0  # direction tower A → B, clockwise from north
    height_above_wires_m: float = 45.0  # flying height above the highest wire
    forward_overlap: float = 0.8
    side_overlap: float | None = None  # None: the flight's default (DEFAULT_SIDE_OVERLAP)
    grid_angle_deg: float = 35.0  # flight "grid": angle between the strips and the line
    num_shield_wires: int = 2  # 1 or 2
    position_jitter_m: float = 0.4  # deviation of the drone from its planned position (1σ)
    attitude_jitter_deg: float = 1.5  # roll/pitch/yaw deviation from nadir (1σ)
    gps_sigma_horizontal_m: float = 1.5  # consumer GNSS noise written to EXIF (1σ)
    gps_sigma_vertical_m: float = 3.0
    origin_lat_deg: float = 35.1595  # WGS84 position of the local frame's origin
    origin_lon_deg: float = 126.8526
    origin_alt_m: float = 40.0
    sun_azimuth_deg: float = 155.0
    sun_elevation_deg: float = 55.0
    jpeg_quality: int = 92
    write_perturbed_model: bool = True  # also write sparse/0 as a bundle adjustment leaves it
    num_ground_points: int = 5000  # sparse points on the terrain
    show_progress: bool = True

    def __post_init__(self) -> None:
        if not 0.05 <= self.scale <= 1.0:
            raise InputError(f"{self.scale=} but expected 0.05 ≤ scale ≤ 1")
        if self.num_shield_wires not in (1, 2):
            raise InputError(f"{self.num_shield_wires=} but expected 1 or 2")
        self.background = Background(self.background)
        self.flight = FlightPattern(self.flight)
        self.layout = Layout(self.layout)
        legs = (FlightPattern.CORRIDOR, FlightPattern.ALONG4)
        if self.layout is Layout.ANGLE and self.flight not in legs:
            raise InputError(
                f"layout angle is flown along its legs: flight {self.flight.value!r} but "
                "expected corridor or along4"
            )
        if (
            self.layout in (Layout.CROSSING, Layout.BRANCH, Layout.PARALLEL)
            and self.flight is not FlightPattern.GRID
        ):
            raise InputError(
                f"layout {self.layout.value} is an area survey: flight {self.flight.value!r} but "
                "expected grid"
            )
        if not 1 <= self.num_spans <= 20:
            raise InputError(f"{self.num_spans=} but expected 1 ≤ num_spans ≤ 20")
        if self.num_spans > 1 and self.layout is not Layout.SPAN:
            raise InputError(
                f"{self.num_spans=} but layout {self.layout.value!r} has its own spans"
            )
        if not 0.0 < self.turn_deg <= 60.0:
            raise InputError(f"{self.turn_deg=} but expected 0 < turn_deg ≤ 60")
        if not 20.0 <= self.crossing_deg <= 90.0:
            raise InputError(f"{self.crossing_deg=} but expected 20 ≤ crossing_deg ≤ 90")
        if not 20.0 <= self.branch_deg <= 160.0:
            raise InputError(f"{self.branch_deg=} but expected 20 ≤ branch_deg ≤ 160")
        if not 12.0 <= abs(self.parallel_offset_m) <= 0.8 * GRID_HALF_WIDTH_M:
            raise InputError(
                f"{self.parallel_offset_m=} but expected 12 ≤ |parallel_offset_m| ≤ "
                f"{0.8 * GRID_HALF_WIDTH_M:g} (clear of the towers' arms, inside the survey)"
            )
        if self.side_overlap is not None and not 0.0 <= self.side_overlap < 1.0:
            raise InputError(f"{self.side_overlap=} but expected 0 ≤ side_overlap < 1")

    @property
    def flight_side_overlap(self) -> float:
        """The side overlap flown: ``side_overlap``, or the flight pattern's default."""
        if self.side_overlap is not None:
            return self.side_overlap
        return DEFAULT_SIDE_OVERLAP[self.flight]


@dataclass(frozen=True)
class TrueWire:
    """One wire hanging as a catenary between two attachment points.

    In the wire's vertical plane, with ``s`` the horizontal distance from ``attach_a``:
    ``z(s) = z0 + a * (cosh((s - s0) / a) - 1)``.
    """

    wire_id: int
    kind: str  # "conductor" or "shield"
    attach_a: tuple[float, float, float]
    attach_b: tuple[float, float, float]
    catenary_a_m: float
    diameter_m: float
    line: int = 1  # the line it belongs to (1, 2, …)
    span: int = 1  # its span along that line (1, 2, …)

    @property
    def direction_xy(self) -> F64:
        d = np.subtract(self.attach_b[:2], self.attach_a[:2])
        return d / np.linalg.norm(d)

    @property
    def length_m(self) -> float:
        """Horizontal distance between the attachment points."""
        return float(np.linalg.norm(np.subtract(self.attach_b[:2], self.attach_a[:2])))

    @property
    def s0(self) -> float:
        """Horizontal position of the catenary's vertex, from ``attach_a``."""
        a, length = self.catenary_a_m, self.length_m
        dz = self.attach_b[2] - self.attach_a[2]
        return float(length / 2 - a * np.arcsinh(dz / (2 * a * np.sinh(length / (2 * a)))))

    @property
    def z0(self) -> float:
        """Height of the catenary's vertex."""
        a = self.catenary_a_m
        return float(self.attach_a[2] - a * (np.cosh(self.s0 / a) - 1))

    def z_at(self, s: F64) -> F64:
        a = self.catenary_a_m
        return self.z0 + a * (np.cosh((np.asarray(s) - self.s0) / a) - 1)

    def points(self, s: F64) -> F64:
        """(N,) horizontal distances from ``attach_a`` → (N, 3) points on the wire."""
        s = np.asarray(s, dtype=np.float64)
        xy = np.asarray(self.attach_a[:2]) + s[:, None] * self.direction_xy
        return np.c_[xy, self.z_at(s)]

    def polyline(self, step_m: float = 0.1) -> F64:
        n = int(np.ceil(self.length_m / step_m)) + 1
        return self.points(np.linspace(0.0, self.length_m, n))

    def sag_m(self) -> float:
        """Largest vertical distance between the chord and the wire."""
        s = np.linspace(0.0, self.length_m, 4001)
        chord = self.attach_a[2] + (self.attach_b[2] - self.attach_a[2]) * s / self.length_m
        return float(np.max(chord - self.z_at(s)))

    def to_json(self, polyline_step_m: float = 0.1) -> dict:
        return {
            "id": self.wire_id,
            "kind": self.kind,
            "line": self.line,
            "span": self.span,
            "attach_a": list(self.attach_a),
            "attach_b": list(self.attach_b),
            "catenary": {"a_m": self.catenary_a_m, "s0_m": self.s0, "z0_m": self.z0},
            "plane": {"origin": list(self.attach_a[:2]), "direction": self.direction_xy.tolist()},
            "diameter_m": self.diameter_m,
            "length_m": self.length_m,
            "sag_m": self.sag_m(),
            "polyline": np.round(self.polyline(polyline_step_m), 5).tolist(),
        }

    @classmethod
    def from_json(cls, d: dict) -> TrueWire:
        return cls(
            wire_id=int(d["id"]),
            kind=str(d["kind"]),
            attach_a=tuple(d["attach_a"]),
            attach_b=tuple(d["attach_b"]),
            catenary_a_m=float(d["catenary"]["a_m"]),
            diameter_m=float(d["diameter_m"]),
            line=int(d.get("line", 1)),
            span=int(d.get("span", 1)),
        )


@dataclass(frozen=True, eq=False)
class Terrain:
    """A heightfield: ``z[i, j]`` is the height at ``(x0 + j * res_m, y0 + i * res_m)``."""

    x0: float
    y0: float
    res_m: float
    z: F32

    def height(self, xy: F64) -> F64:
        """(N, 2) plan positions → (N,) heights (bilinear)."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        coords = np.stack([(xy[:, 1] - self.y0) / self.res_m, (xy[:, 0] - self.x0) / self.res_m])
        return ndimage.map_coordinates(self.z.astype(np.float64), coords, order=1, mode="nearest")

    def save(self, path: Path) -> None:
        np.savez_compressed(path, x0=self.x0, y0=self.y0, res_m=self.res_m, z=self.z)

    @classmethod
    def load(cls, path: Path | str) -> Terrain:
        with np.load(path) as f:
            return cls(float(f["x0"]), float(f["y0"]), float(f["res_m"]), f["z"].astype(np.float32))


@dataclass(frozen=True)
class Member:
    """A straight tower member (or insulator string) between two world points."""

    p: tuple[float, float, float]
    q: tuple[float, float, float]
    width_m: float


@dataclass(eq=False)
class SyntheticSpan:
    """The whole synthetic scene, before any file is written."""

    options: SyntheticSpanOptions
    camera: pycolmap.Camera
    views: list[SceneImage]
    wires: list[TrueWire]
    towers: list[list[Member]]
    terrain: Terrain
    sun_in_world: F64  # unit vector towards the sun
    ortho: np.ndarray = field(repr=False)  # (H, W, 4) uint8: radiance RGB + detail amplitude
    strips: list[int] = field(default_factory=list)  # flight strip of each view (0, 1, …)
    supports: list[dict] = field(default_factory=list)  # each tower or pole: line, kind
    # (suspension, angle, pole), position of its base (x, y, z), top_z
    ortho_x0: float = 0.0
    ortho_y0: float = 0.0
    ortho_res_m: float = 0.05
    detail_tiles: list[F32] = field(default_factory=list, repr=False)
    detail_res_m: float = 0.02

    @cached_property
    def _normalized_grid(self) -> tuple[F32, F32]:
        """Normalised camera coordinates of every pixel centre (lens distortion removed)."""
        w, h = self.camera.width, self.camera.height
        u, v = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
        xy = cam_from_img(self.camera, np.c_[u.ravel(), v.ravel()])
        return (
            xy[:, 0].reshape(h, w).astype(np.float32),
            xy[:, 1].reshape(h, w).astype(np.float32),
        )


# ---------------------------------------------------------------- scene geometry


def _line_frame(opts: SyntheticSpanOptions) -> tuple[F64, F64]:
    """Unit vectors along the line (A → B) and across it (to its right), in plan."""
    return plan_axes(opts.line_azimuth_deg)


def _line_half_length(opts: SyntheticSpanOptions) -> float:
    """Half the straight line's length between its end towers (layout "span")."""
    return opts.num_spans * opts.span_m / 2


def _make_terrain(opts: SyntheticSpanOptions, rng: np.random.Generator) -> Terrain:
    # A corridor of several spans gets ground to its ends, and its slope levels off beyond
    # 150 m from the middle (a 3 % slope over a kilometre would bring the far end's wires
    # 30 m nearer the drone, which flies at one height).
    res, half = 1.0, max(260.0, _line_half_length(opts) + 160.0)
    n = int(2 * half / res) + 1
    along, _ = _line_frame(opts)
    x = -half + res * np.arange(n)
    gx, gy = np.meshgrid(x, x)
    s = gx * along[0] + gy * along[1]
    relief = fbm((n, n), rng, [70.0, 28.0, 9.0], [1.0, 0.45, 0.12])
    level = 150.0 if opts.num_spans > 1 else np.inf
    z = 0.03 * np.clip(s, -level, level) + 2.2 * relief
    return Terrain(float(x[0]), float(x[0]), res, z.astype(np.float32))


def _lattice_tower(
    base: F64, along: F64, across: F64, arm_scale: float, num_shield_wires: int
) -> tuple[list[Member], dict[tuple, tuple[float, float, float]]]:
    """A double-circuit lattice tower at ``base`` whose cross-arms run along ``across``
    (``arm_scale`` times their usual length: an angle tower's arms bisect the turn and are
    longer, so that each conductor keeps its offset from the line on both legs); its
    members and the attachment point of each wire."""
    arm_z = (21.0, 26.0, 31.0)  # cross-arm heights above the tower base
    arm_len = (5.0, 5.5, 5.0)  # stacked phases, the middle one 0.5 m further out
    insulator_m = 2.0
    top_z, shield_z = 36.0, 37.0

    def world(s_off: float, c: float, z: float) -> tuple[float, float, float]:
        xy = base[:2] + s_off * along + c * across
        return (float(xy[0]), float(xy[1]), float(base[2] + z))

    members: list[Member] = []
    levels = sorted({0.0, 4.0, 8.0, 12.0, 16.0, 19.0, *arm_z, top_z})

    def half_width(z: float) -> float:
        return 3.6 - 2.4 * min(z / 19.0, 1.0)

    corners = [(1, 1), (1, -1), (-1, -1), (-1, 1)]
    for z1, z2 in zip(levels[:-1], levels[1:], strict=True):
        h1, h2 = half_width(z1), half_width(z2)
        for k, (a, b) in enumerate(corners):
            a2, b2 = corners[(k + 1) % 4]
            members.append(Member(world(a * h1, b * h1, z1), world(a * h2, b * h2, z2), 0.3))
            members.append(Member(world(a * h2, b * h2, z2), world(a2 * h2, b2 * h2, z2), 0.1))
            members.append(Member(world(a * h1, b * h1, z1), world(a2 * h2, b2 * h2, z2), 0.08))
            members.append(Member(world(a2 * h1, b2 * h1, z1), world(a * h2, b * h2, z2), 0.08))
    points: dict[tuple, tuple[float, float, float]] = {}
    hw = half_width(arm_z[0])
    for phase, (z, length) in enumerate(zip(arm_z, arm_len, strict=True)):
        for side in (-1.0, 1.0):
            tip = world(0.0, side * length * arm_scale, z)
            for sa in (-1.0, 1.0):
                members.append(Member(world(sa * hw, side * hw, z), tip, 0.15))
                members.append(Member(world(sa * hw, side * hw, z + 1.8), tip, 0.1))
            low = world(0.0, side * length * arm_scale, z - insulator_m)
            members.append(Member(tip, low, 0.25))
            points[("c", side, phase)] = low
    shield_c = (-3.0, 3.0) if num_shield_wires == 2 else (0.0,)
    for c in shield_c:
        tip = world(0.0, c * arm_scale, shield_z)
        for sa in (-1.0, 1.0):
            members.append(Member(world(sa * hw, np.sign(c) * hw, top_z), tip, 0.12))
        points[("s", c, 0)] = tip
    return members, points


def _pole(
    base: F64, across: F64, arm_z: float = 10.5, top: bool = True
) -> tuple[list[Member], dict[tuple, tuple[float, float, float]]]:
    """A 12 m steel pole of a single-circuit line: two conductors on pin insulators at the
    ends of a cross-arm (±1.2 m, ``arm_z`` up), the third on its top (``top``)."""

    def world(c: float, z: float) -> tuple[float, float, float]:
        xy = base[:2] + c * across
        return (float(xy[0]), float(xy[1]), float(base[2] + z))

    members = [Member(world(0.0, 0.0), world(0.0, 12.0), 0.3)]
    members.append(Member(world(-1.3, arm_z), world(1.3, arm_z), 0.12))
    points = {("p", -1.0, 0): world(-1.2, arm_z + 0.2), ("p", 1.0, 0): world(1.2, arm_z + 0.2)}
    if top:
        points[("p", 0.0, 0)] = world(0.0, 12.2)
    return members, points


def _leg_frames(opts: SyntheticSpanOptions) -> list[tuple[F64, F64, F64]]:
    """Each straight leg of the line: (its middle, along, across) in plan."""
    along, across = _line_frame(opts)
    if opts.layout is not Layout.ANGLE:
        return [(np.zeros(2), along, across)]
    along2, across2 = plan_axes(opts.line_azimuth_deg + opts.turn_deg)
    return [
        (-opts.span_m / 2 * along, along, across),
        (opts.span_m / 2 * along2, along2, across2),
    ]


def _pole_line(
    sites_xy: list[F64],
    across: F64,
    kinds: list[str],
    catenary_a_m: tuple[float, float],
    terrain: Terrain,
    rng: np.random.Generator,
    towers: list[list[Member]],
    wires: list[TrueWire],
    supports: list[dict],
) -> list[F64]:
    """Line 2: a pole at each site (its cross-arm along ``across``, ``kinds`` its support
    kind), appended to ``towers`` and ``supports``, and each conductor's spans between them
    (catenary parameter drawn from ``catenary_a_m``), appended to ``wires``. Returns the
    poles' bases."""
    poles, bases = [], []
    for xy, kind in zip(sites_xy, kinds, strict=True):
        base = np.array([xy[0], xy[1], terrain.height(xy)[0]])
        members, points = _pole(base, across)
        towers.append(members)
        poles.append(points)
        bases.append(base)
        supports.append(
            {"line": 2, "kind": kind, "base": base.tolist(),
             "top_z": max(p[2] for p in points.values())}
        )  # fmt: skip
    for key in poles[0]:
        for k in range(len(poles) - 1):
            wires.append(
                TrueWire(
                    wire_id=len(wires),
                    kind="conductor",
                    attach_a=poles[k][key],
                    attach_b=poles[k + 1][key],
                    catenary_a_m=float(rng.uniform(*catenary_a_m)),
                    diameter_m=0.022,
                    line=2,
                    span=k + 1,
                )
            )
    return bases


def _make_towers_and_wires(
    opts: SyntheticSpanOptions, terrain: Terrain, rng: np.random.Generator
) -> tuple[list[list[Member]], list[TrueWire], list[dict]]:
    """Towers (members), wires and supports of the layout."""
    legs = _leg_frames(opts)
    if opts.layout is Layout.ANGLE:
        (_, along, across), (_, along2, across2) = legs
        half = 0.5 * np.deg2rad(opts.turn_deg)
        bisector = (along + along2) / np.linalg.norm(along + along2)
        sites = [
            (-opts.span_m * along, along, across, 1.0),
            (np.zeros(2), bisector, across_of(bisector), 1.0 / np.cos(half)),
            (opts.span_m * along2, along2, across2, 1.0),
        ]
    else:
        _, along, across = legs[0]
        half = _line_half_length(opts)
        sites = [
            ((-half + k * opts.span_m) * along, along, across, 1.0)
            for k in range(opts.num_spans + 1)
        ]
    towers: list[list[Member]] = []
    attach: list[dict[tuple, tuple[float, float, float]]] = []
    supports: list[dict] = []
    for xy, al, ac, arm_scale in sites:
        base = np.array([xy[0], xy[1], terrain.height(xy)[0]])
        members, points = _lattice_tower(base, al, ac, arm_scale, opts.num_shield_wires)
        towers.append(members)
        attach.append(points)
        supports.append(
            {
                "line": 1,
                "kind": "angle" if arm_scale != 1.0 else "suspension",
                "base": base.tolist(),
                "top_z": max(p[2] for p in points.values()),
            }
        )

    wires: list[TrueWire] = []
    for key in attach[0]:
        kind = "conductor" if key[0] == "c" else "shield"
        a_m = float(rng.uniform(450, 650) if kind == "conductor" else rng.uniform(700, 900))
        for k in range(len(sites) - 1):
            wires.append(
                TrueWire(
                    wire_id=len(wires),
                    kind=kind,
                    attach_a=attach[k][key],
                    attach_b=attach[k + 1][key],
                    catenary_a_m=a_m,
                    # ~2.8 cm ACSR conductors, ~2 cm shield wires: 1.4 px and 1 px at 2 cm GSD.
                    diameter_m=0.028 if kind == "conductor" else 0.02,
                    span=k + 1,
                )
            )
    if opts.layout in (Layout.CROSSING, Layout.BRANCH):
        # A 70 m pole span crossing the first 15 m from its middle, 4-5 m below it; with a
        # branch, the pole line goes on 25 m past its second pole, from which the branch
        # line leaves.
        along_c, across_c = plan_axes(opts.line_azimuth_deg + opts.crossing_deg)
        crossing = 0.15 * opts.span_m * along
        offsets = (-35.0, 35.0, 60.0) if opts.layout is Layout.BRANCH else (-35.0, 35.0)
        kinds = ["pole"] * len(offsets)
        if opts.layout is Layout.BRANCH:
            kinds[1] = "junction"
        pole_xy = _pole_line(
            [crossing + off * along_c for off in offsets], across_c, kinds, (400, 600),
            terrain, rng, towers, wires, supports,
        )  # fmt: skip  # 1.0-1.5 m of sag (70 m)
        if opts.layout is Layout.BRANCH:
            # Two conductors on a cross-arm of their own, a metre under the pole line's,
            # to a pole 30 m away.
            along_b, across_b = plan_axes(
                opts.line_azimuth_deg + opts.crossing_deg + opts.branch_deg
            )
            base_j = pole_xy[1]
            arm_z = 9.5
            towers[-2].append(
                Member(
                    tuple(float(v) for v in np.r_[base_j[:2] - 1.3 * across_b, base_j[2] + arm_z]),
                    tuple(float(v) for v in np.r_[base_j[:2] + 1.3 * across_b, base_j[2] + arm_z]),
                    0.12,
                )
            )
            xy = base_j[:2] + 30.0 * along_b
            base = np.array([xy[0], xy[1], terrain.height(xy)[0]])
            members, points = _pole(base, across_b, arm_z=arm_z, top=False)
            towers.append(members)
            supports.append(
                {
                    "line": 3,
                    "kind": "pole",
                    "base": base.tolist(),
                    "top_z": max(p[2] for p in points.values()),
                }  # fmt: skip
            )
            for c in (-1.0, 1.0):
                a_xy = base_j[:2] + 1.2 * c * across_b
                wires.append(
                    TrueWire(
                        wire_id=len(wires),
                        kind="conductor",
                        attach_a=(float(a_xy[0]), float(a_xy[1]), float(base_j[2] + arm_z + 0.2)),
                        attach_b=points[("p", c, 0)],
                        catenary_a_m=float(rng.uniform(300, 450)),  # 0.25-0.4 m of sag
                        diameter_m=0.022,
                        line=3,
                    )
                )
    if opts.layout is Layout.PARALLEL:
        # A distribution line beside the tower line, on three poles 45 m apart (two spans),
        # the middle one abreast of the span's middle; 0.6-0.8 m of sag.
        _pole_line(
            [off * along + opts.parallel_offset_m * across for off in (-45.0, 0.0, 45.0)],
            across, ["pole"] * 3, (300, 450), terrain, rng, towers, wires, supports,
        )  # fmt: skip
    return towers, wires, supports


def make_camera(scale: float) -> pycolmap.Camera:
    """The 12 MP drone camera (OPENCV model), resized by ``scale``."""
    w, h = round(FULL_WIDTH_PX * scale), round(FULL_HEIGHT_PX * scale)
    f = FOCAL_MM / PIXEL_PITCH_MM * (w / FULL_WIDTH_PX)
    cx = w / 2 + PRINCIPAL_OFFSET_PX[0] * scale
    cy = h / 2 + PRINCIPAL_OFFSET_PX[1] * scale
    return pycolmap.Camera(
        model="OPENCV",
        width=w,
        height=h,
        params=[f, f, cx, cy, *DISTORTION_K1_K2_P1_P2],
        camera_id=1,
    )


def _rotation_nadir(heading_xy: F64, rng: np.random.Generator, jitter_deg: float) -> F64:
    """cam_from_world rotation of a nadir camera whose image top points along ``heading``."""
    heading = np.array([heading_xy[0], heading_xy[1], 0.0])
    z_cam = np.array([0.0, 0.0, -1.0])
    y_cam = -heading
    x_cam = np.cross(y_cam, z_cam)
    rot = np.stack([x_cam, y_cam, z_cam])  # rows: camera axes in world
    angles = np.deg2rad(rng.normal(0.0, jitter_deg, 3))
    jitter, _ = cv2.Rodrigues(angles)
    return jitter @ rot


def _plan_strips(
    opts: SyntheticSpanOptions, fp_across: float, fp_along: float
) -> list[tuple[F64, F64, F64, float, list[float]]]:
    """The flight's strips, per leg of the line: (middle, direction, offset direction, half
    length, offsets) in plan.

    Strip ``k`` of a leg runs through ``middle + offsets[k] * offset_dir`` from
    ``-half_length`` to ``+half_length`` along its direction; image x runs across the strip.
    A line turning at an angle tower is flown leg by leg (each leg's strips run a quarter
    footprint past its towers, so the legs overlap at the angle tower).
    """
    spacing = (1 - opts.flight_side_overlap) * fp_across
    legs = _leg_frames(opts)
    half_span = opts.span_m / 2 if opts.layout is Layout.ANGLE else _line_half_length(opts)
    if opts.flight is FlightPattern.CORRIDOR:
        return [(m, al, ac, half_span + 0.25 * fp_along, [-spacing, 0.0, spacing])
                for m, al, ac in legs]  # fmt: skip
    if opts.flight is FlightPattern.ALONG4:
        offsets = [(k - 1.5) * spacing for k in range(4)]
        return [(m, al, ac, half_span + 0.25 * fp_along, offsets) for m, al, ac in legs]
    _, along, across = legs[0]
    if opts.flight is FlightPattern.GRID:
        # Cover the span plus a margin along the line and ±GRID_HALF_WIDTH_M across it.
        ga = np.deg2rad(opts.grid_angle_deg)
        strip_dir = np.cos(ga) * along + np.sin(ga) * across
        off_dir = -np.sin(ga) * along + np.cos(ga) * across
        hu, hv = half_span + 0.25 * fp_along, GRID_HALF_WIDTH_M
        corners = np.array([[a * hu, c * hv] for a in (-1, 1) for c in (-1, 1)])
        corners_xy = corners[:, :1] * along + corners[:, 1:] * across
        half_length = float(np.abs(corners_xy @ strip_dir).max())
        half_width = float(np.abs(corners_xy @ off_dir).max())
        n_strips = int(np.ceil(2 * half_width / spacing)) + 1
        offsets = list((np.arange(n_strips) - (n_strips - 1) / 2) * spacing)
        return [(np.zeros(2), strip_dir, off_dir, half_length, offsets)]
    n_strips = int(np.ceil((2 * half_span + 0.2 * fp_across) / spacing)) + 1
    offsets = list((np.arange(n_strips) - (n_strips - 1) / 2) * spacing)
    return [(np.zeros(2), across, along, 0.6 * fp_along, offsets)]


def _plan_flight(
    opts: SyntheticSpanOptions,
    camera: pycolmap.Camera,
    wires: list[TrueWire],
    terrain: Terrain,
    rng: np.random.Generator,
) -> tuple[list[SceneImage], list[int]]:
    """The views of the flight and the strip each belongs to."""
    z_cam = max(max(w.attach_a[2], w.attach_b[2]) for w in wires) + opts.height_above_wires_m
    ground_z = float(np.mean(terrain.height(np.zeros((1, 2)))))
    gsd = (z_cam - ground_z) / camera.mean_focal_length()
    fp_across = camera.width * gsd  # image x runs across the strip
    fp_along = camera.height * gsd
    base = (1 - opts.forward_overlap) * fp_along
    views: list[SceneImage] = []
    strips: list[int] = []
    k = -1
    for middle, strip_dir, strip_off_dir, extent, offsets in _plan_strips(
        opts, fp_across, fp_along
    ):
        n = int(np.ceil(2 * extent / base)) + 1
        positions = np.linspace(-extent, extent, n)
        for off in offsets:
            k += 1
            views += _fly_strip(
                opts, camera, rng, k, middle + off * strip_off_dir, strip_dir, positions,
                z_cam, len(views),
            )  # fmt: skip
            strips += [k] * (len(views) - len(strips))
    return views, strips


def _fly_strip(
    opts: SyntheticSpanOptions,
    camera: pycolmap.Camera,
    rng: np.random.Generator,
    k: int,
    through: F64,
    strip_dir: F64,
    positions: F64,
    z_cam: float,
    first: int,
) -> list[SceneImage]:
    """The views of strip ``k`` (serpentine: every other strip flown backwards)."""
    views: list[SceneImage] = []
    sign = 1.0 if k % 2 == 0 else -1.0
    for p in positions[:: int(sign)]:
        xy = through + p * strip_dir + rng.normal(0, opts.position_jitter_m, 2)
        center = np.array([xy[0], xy[1], z_cam + rng.normal(0, opts.position_jitter_m / 2)])
        rot = _rotation_nadir(sign * strip_dir, rng, opts.attitude_jitter_deg)
        name = f"DJI_{first + len(views) + 1:04d}.JPG"
        views.append(
            SceneImage(
                image_id=first + len(views) + 1,
                name=name,
                path=Path(name),
                camera=camera,
                rot_cam_from_world=rot,
                t_cam_from_world=-rot @ center,
            )
        )
    return views


# ---------------------------------------------------------------- ground texture


def _ground_domain(views: list[SceneImage], z: float) -> tuple[float, float, float, float]:
    pts = []
    for v in views:
        w, h = v.width, v.height
        uv = np.array(
            [[0, 0], [w, 0], [0, h], [w, h], [w / 2, 0], [w / 2, h], [0, h / 2], [w, h / 2]],
            dtype=np.float64,
        )
        rays = v.rays_in_world(uv)
        c = v.center_in_world
        t = (z - c[2]) / rays[:, 2]
        pts.append(c[:2] + t[:, None] * rays[:, :2])
    pts_arr = np.concatenate(pts)
    lo, hi = pts_arr.min(axis=0) - 15.0, pts_arr.max(axis=0) + 15.0
    return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


def _albedo(
    opts: SyntheticSpanOptions,
    shape: tuple[int, int],
    res: float,
    gx: F32,
    gy: F32,
    rng: np.random.Generator,
) -> tuple[F32, F32]:
    """Ground colour (H, W, 3) in 0..255 and the fine-detail amplitude (H, W)."""
    h, w = shape
    px = 1.0 / res  # pixels per metre

    def mix(a: F32, b: F32, t: F32) -> F32:
        t = np.clip(t, 0, 1)[..., None]
        return a * (1 - t) + b * t

    def meadow() -> tuple[F32, F32]:
        g = fbm(shape, rng, [25 * px, 6 * px, 1.5 * px], [1.0, 0.6, 0.35])
        dry = fbm(shape, rng, [40 * px, 10 * px], [1.0, 0.5])
        light, dark = np.array([96, 128, 58], np.float32), np.array([52, 84, 36], np.float32)
        col = mix(
            np.broadcast_to(dark, (h, w, 3)), np.broadcast_to(light, (h, w, 3)), 0.5 + 0.22 * g
        )
        col = mix(
            col, np.broadcast_to(np.array([128, 122, 78], np.float32), (h, w, 3)), (dry - 1.2) * 1.5
        )
        trees = fbm(shape, rng, [14 * px, 5 * px], [1.0, 0.5])
        crowns = fbm(shape, rng, [1.2 * px, 0.4 * px], [1.0, 0.5])
        canopy = np.clip((trees - 1.35) * 4, 0, 1)
        tree_col = mix(
            np.broadcast_to(np.array([30, 52, 28], np.float32), (h, w, 3)),
            np.broadcast_to(np.array([66, 96, 48], np.float32), (h, w, 3)),
            0.5 + 0.35 * crowns,
        )
        col = mix(col, tree_col, canopy)
        return col.astype(np.float32), (0.16 + 0.08 * canopy).astype(np.float32)

    def soil() -> tuple[F32, F32]:
        g = fbm(shape, rng, [30 * px, 8 * px, 2 * px], [1.0, 0.5, 0.3])
        col = mix(
            np.broadcast_to(np.array([132, 114, 92], np.float32), (h, w, 3)),
            np.broadcast_to(np.array([168, 148, 118], np.float32), (h, w, 3)),
            0.6 + 0.2 * g,
        )
        return col.astype(np.float32), np.full(shape, 0.07, np.float32)

    if opts.background is Background.VEGETATION:
        return meadow()
    if opts.background is Background.BARE_SOIL:
        return soil()
    col, amp = meadow()
    scol, samp = soil()
    field_mask = np.clip((fbm(shape, rng, [60 * px], [1.0]) - 0.2) * 2, 0, 1)
    col = mix(col, scol, field_mask)
    amp = amp * (1 - field_mask) + samp * field_mask
    # A 7 m road crossing under the span at 60° to the line, with white edge lines and a
    # dashed centre line: strong linear look-alikes.
    along, _ = _line_frame(opts)
    ang = np.arctan2(along[1], along[0]) + np.deg2rad(60)
    rd, rn = np.array([np.cos(ang), np.sin(ang)]), np.array([-np.sin(ang), np.cos(ang)])
    rel_x, rel_y = gx - 18.0 * along[0], gy - 18.0 * along[1]
    dn = rel_x * rn[0] + rel_y * rn[1]
    dl = rel_x * rd[0] + rel_y * rd[1]
    road = np.clip(3.9 - np.abs(dn), 0, 1) / 1.0
    asphalt = 84 + 5 * fbm(shape, rng, [3 * px], [1.0])
    col = mix(col, np.stack([asphalt, asphalt, asphalt + 4], -1), road)
    amp = amp * (1 - road) + 0.05 * road
    line_w = 0.15
    edge = np.clip((line_w / 2 - np.abs(np.abs(dn) - 3.3)) / res + 0.5, 0, 1)
    dash = (np.mod(dl, 9.0) < 3.0).astype(np.float32)
    centre = np.clip((line_w / 2 - np.abs(dn)) / res + 0.5, 0, 1) * dash
    white = np.maximum(edge, centre)
    col = mix(col, np.broadcast_to(np.array([225, 225, 220], np.float32), (h, w, 3)), white)
    return col.astype(np.float32), amp.astype(np.float32)


def _bake_ortho(
    span: SyntheticSpan, domain: tuple[float, float, float, float], rng: np.random.Generator
) -> None:
    """Ground radiance raster: albedo x hill shading x cast shadows of towers and wires."""
    opts, terrain, sun = span.options, span.terrain, span.sun_in_world
    gsd = span.views[0].gsd_at_depth(span.views[0].center_in_world[2] - terrain.z.mean())
    res = float(1.5 * gsd)
    x0, y0, x1, y1 = domain
    w, h = int((x1 - x0) / res) + 1, int((y1 - y0) / res) + 1
    if max(w, h) >= 32000:
        raise InputError(f"ground raster of {w}x{h} px is too large for OpenCV; reduce the scene")
    gx, gy = np.meshgrid(
        x0 + res * np.arange(w, dtype=np.float32), y0 + res * np.arange(h, dtype=np.float32)
    )
    albedo, amp = _albedo(opts, (h, w), res, gx, gy, rng)

    # Hill shading from the heightfield normals, normalised so flat ground is 1.
    zr = terrain.z.astype(np.float64)
    dzdy, dzdx = np.gradient(zr, terrain.res_m)
    normal = np.stack([-dzdx, -dzdy, np.ones_like(zr)], -1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    lit = normal @ sun
    shade = ((0.35 + 0.65 * np.clip(lit, 0, 1)) / (0.35 + 0.65 * sun[2])).astype(np.float32)
    shade_o = remap(
        shade,
        (gx - terrain.x0) / np.float32(terrain.res_m),
        (gy - terrain.y0) / np.float32(terrain.res_m),
    )

    # Cast shadows, drawn in the raster: tower members and wires projected along the sun.
    shadow = np.zeros((h, w), np.uint8)

    def on_ground(pts: F64) -> F64:
        out = pts.copy()
        for _ in range(4):
            zg = terrain.height(out[:, :2])
            t = (pts[:, 2] - zg) / sun[2]
            out[:, :2] = pts[:, :2] - t[:, None] * sun[:2]
        return out

    def to_px(pts: F64) -> npt.NDArray[np.int32]:
        return np.round(((pts[:, :2] - [x0, y0]) / res) * 16).astype(np.int32)

    for members in span.towers:
        p = on_ground(np.array([m.p for m in members]))
        q = on_ground(np.array([m.q for m in members]))
        for a, b, m in zip(to_px(p), to_px(q), members, strict=True):
            cv2.line(
                shadow, tuple(a), tuple(b), 140, max(1, round(m.width_m / res)), cv2.LINE_AA, 4
            )
    for wire in span.wires:
        pts = wire.polyline(0.5)
        g = on_ground(pts)
        dist = np.linalg.norm(pts - g, axis=1).mean()
        penumbra = wire.diameter_m + dist * 0.0093  # the sun's disc is 0.53° wide
        strength = int(140 * min(1.0, wire.diameter_m / penumbra))
        cv2.polylines(
            shadow, [to_px(g)], False, strength, max(1, round(penumbra / res)), cv2.LINE_AA, 4
        )
    shadow_f = 1.0 - cv2.GaussianBlur(shadow, (0, 0), 0.7).astype(np.float32) / 255.0
    radiance = albedo * (shade_o * shadow_f)[..., None]
    span.ortho = np.dstack([np.clip(radiance, 0, 255), np.clip(amp * 255, 0, 255)]).astype(np.uint8)
    span.ortho_x0, span.ortho_y0, span.ortho_res_m = x0, y0, res
    span.detail_res_m = float(0.8 * gsd)
    span.detail_tiles = [periodic_noise(1024, rng, 1.3), periodic_noise(1024, rng, 1.0)]


def build_span(opts: SyntheticSpanOptions) -> SyntheticSpan:
    """Build the scene geometry, flight and ground texture (no files written)."""
    rng = np.random.default_rng(opts.seed)
    terrain = _make_terrain(opts, rng)
    towers, wires, supports = _make_towers_and_wires(opts, terrain, rng)
    camera = make_camera(opts.scale)
    views, strips = _plan_flight(opts, camera, wires, terrain, rng)
    az, el = np.deg2rad(opts.sun_azimuth_deg), np.deg2rad(opts.sun_elevation_deg)
    sun = np.array([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)])
    span = SyntheticSpan(
        opts,
        camera,
        views,
        wires,
        towers,
        terrain,
        sun,
        ortho=np.zeros(0),
        strips=strips,
        supports=supports,
    )
    domain = _ground_domain(views, float(terrain.z.mean()))
    _bake_ortho(span, domain, rng)
    return span


# ---------------------------------------------------------------- image rendering


def render_image(span: SyntheticSpan, view: SceneImage, rng: np.random.Generator) -> np.ndarray:
    """Render one (H, W, 3) uint8 RGB image of the span as seen by ``view``."""
    xn, yn = span._normalized_grid
    rot = view.rot_cam_from_world.astype(np.float32)
    c = view.center_in_world
    # Unnormalised ray directions in the world: R^T (x, y, 1).
    dx = xn * rot[0, 0] + yn * rot[1, 0] + rot[2, 0]
    dy = xn * rot[0, 1] + yn * rot[1, 1] + rot[2, 1]
    dz = xn * rot[0, 2] + yn * rot[1, 2] + rot[2, 2]
    terrain = span.terrain
    t = (np.float32(c[2] - terrain.z.mean())) / -dz
    hres = np.float32(terrain.res_m)
    for _ in range(5):  # fixed point: the ray's height meets the terrain's height
        mx = (np.float32(c[0] - terrain.x0) + t * dx) / hres
        my = (np.float32(c[1] - terrain.y0) + t * dy) / hres
        zg = remap(terrain.z, mx, my)
        t = (np.float32(c[2]) - zg) / -dz
    gx = np.float32(c[0]) + t * dx
    gy = np.float32(c[1]) + t * dy
    del dx, dy, dz, mx, my, zg, t
    ores = np.float32(span.ortho_res_m)
    ground = remap(
        span.ortho, (gx - np.float32(span.ortho_x0)) / ores, (gy - np.float32(span.ortho_y0)) / ores
    ).astype(np.float32)
    dres = np.float32(span.detail_res_m)
    d1 = remap(span.detail_tiles[0], gx / dres, gy / dres, wrap=True)
    cr, sr = np.float32(np.cos(0.65)), np.float32(np.sin(0.65))
    d2 = remap(
        span.detail_tiles[1],
        (cr * gx - sr * gy) / (dres * np.float32(1.37)),
        (sr * gx + cr * gy) / (dres * np.float32(1.37)),
        wrap=True,
    )
    detail = 1.0 + (ground[..., 3] / 255.0) * (0.6 * d1 + 0.5 * d2)
    img = ground[..., :3] * np.clip(detail, 0.2, 2.0)[..., None]
    del gx, gy, d1, d2, detail, ground

    # Towers (galvanised steel lattice) as anti-aliased lines.
    f = view.focal_px
    tower_alpha = np.zeros(img.shape[:2], np.uint8)
    for members in span.towers:
        for m in members:
            pts = np.linspace(m.p, m.q, 12)
            uv, depth, _ = view.project(pts)
            if not np.isfinite(uv).all() or (depth <= 0).any():
                continue
            width = max(1, round(m.width_m * f / float(depth.mean())))
            cv2.polylines(
                tower_alpha,
                [np.round((uv - 0.5) * 16).astype(np.int32)],
                False,
                255,
                width,
                cv2.LINE_AA,
                4,
            )
    a = tower_alpha.astype(np.float32)[..., None] / 255.0
    img = img * (1 - a) + np.array([158, 160, 158], np.float32) * a

    # Wires with exact sub-pixel coverage; the brightness drifts slowly along each wire.
    for kind, colour in (("conductor", (188, 190, 186)), ("shield", (122, 124, 122))):
        alpha = np.zeros(img.shape[:2], np.float32)
        for wire in span.wires:
            if wire.kind != kind:
                continue
            gsd_wire = float(view.gsd_at_depth(view.center_in_world[2] - wire.z0))
            n = int(wire.length_m / (0.4 * gsd_wire)) + 2
            s = np.linspace(0.0, wire.length_m, n)
            uv, depth, _ = view.project(wire.points(s))
            width_px = wire.diameter_m * f / np.maximum(depth, 1e-6)
            shimmer = 0.85 + 0.15 * np.sin(s / 7.0 + wire.wire_id)
            draw_thin_polyline(alpha, uv, width_px, shimmer)
        a = alpha[..., None]
        img = img * (1 - a) + np.array(colour, np.float32) * a

    # Camera: vignetting, optics blur, shot and read noise; JPEG is applied when saving.
    h, w = img.shape[:2]
    r2 = ((np.arange(w, dtype=np.float32) - w / 2) ** 2)[None, :] + (
        (np.arange(h, dtype=np.float32) - h / 2) ** 2
    )[:, None]
    img *= (1.0 - 0.18 * r2 / np.float32((w / 2) ** 2 + (h / 2) ** 2))[..., None]
    img = np.asarray(cv2.GaussianBlur(img, (0, 0), 0.55), np.float32)
    noise = rng.standard_normal(img.shape, dtype=np.float32)
    img += noise * np.sqrt(1.5 + 0.04 * np.clip(img, 0, None))
    return np.clip(img + 0.5, 0, 255).astype(np.uint8)


# ---------------------------------------------------------------- files


def _gps_exif(
    lat: float, lon: float, alt: float, index: int, camera: pycolmap.Camera
) -> Image.Exif:
    def dms(v: float) -> tuple[float, float, float]:
        v = abs(v)
        d = int(v)
        m = int((v - d) * 60)
        return (float(d), float(m), round((v - d - m / 60) * 3600, 6))

    exif = Image.Exif()
    exif[ExifTags.Base.Make] = "DJI"
    exif[ExifTags.Base.Model] = "FC330"
    exif[ExifTags.Base.DateTime] = f"2026:05:14 10:{index // 30:02d}:{(2 * index) % 60:02d}"
    sub = exif.get_ifd(ExifTags.IFD.Exif)
    sub[ExifTags.Base.FocalLength] = FOCAL_MM
    sub[ExifTags.Base.FocalLengthIn35mmFilm] = 20
    sub[ExifTags.Base.ExifImageWidth] = int(camera.width)
    sub[ExifTags.Base.ExifImageHeight] = int(camera.height)
    exif[ExifTags.IFD.GPSInfo] = {
        ExifTags.GPS.GPSVersionID: b"\x02\x03\x00\x00",
        ExifTags.GPS.GPSLatitudeRef: "N" if lat >= 0 else "S",
        ExifTags.GPS.GPSLatitude: dms(lat),
        ExifTags.GPS.GPSLongitudeRef: "E" if lon >= 0 else "W",
        ExifTags.GPS.GPSLongitude: dms(lon),
        ExifTags.GPS.GPSAltitudeRef: b"\x00" if alt >= 0 else b"\x01",
        ExifTags.GPS.GPSAltitude: round(abs(alt), 3),
    }
    return exif


def read_exif_gps(path: Path | str) -> tuple[float, float, float] | None:
    """(lat_deg, lon_deg, alt_m) from a JPEG's EXIF, or None when it has no GPS."""
    gps = Image.open(path).getexif().get_ifd(ExifTags.IFD.GPSInfo)
    if ExifTags.GPS.GPSLatitude not in gps or ExifTags.GPS.GPSLongitude not in gps:
        return None

    def deg(dms: tuple, ref: str, neg: str) -> float:
        v = float(dms[0]) + float(dms[1]) / 60 + float(dms[2]) / 3600
        return -v if ref == neg else v

    lat = deg(gps[ExifTags.GPS.GPSLatitude], gps.get(ExifTags.GPS.GPSLatitudeRef, "N"), "S")
    lon = deg(gps[ExifTags.GPS.GPSLongitude], gps.get(ExifTags.GPS.GPSLongitudeRef, "E"), "W")
    alt = float(gps.get(ExifTags.GPS.GPSAltitude, 0.0))
    if gps.get(ExifTags.GPS.GPSAltitudeRef, b"\x00") in (b"\x01", 1):
        alt = -alt
    return lat, lon, alt


def _sparse_points(
    span: SyntheticSpan, rng: np.random.Generator
) -> tuple[F64, npt.NDArray[np.uint8]]:
    """Terrain points (and a few on the towers) that SfM would have reconstructed."""
    x0, y0, res = span.ortho_x0, span.ortho_y0, span.ortho_res_m
    hh, ww = span.ortho.shape[:2]

    def seen_twice(pts: F64) -> F64:
        n_vis = sum(v.project(pts)[2].astype(int) for v in span.views)
        return pts[n_vis >= 2]

    n = span.options.num_ground_points
    xy = np.c_[rng.uniform(x0, x0 + ww * res, 3 * n), rng.uniform(y0, y0 + hh * res, 3 * n)]
    ground = seen_twice(np.c_[xy, span.terrain.height(xy)])[:n]
    tower = []
    for members in span.towers:
        for k in rng.choice(len(members), 60):
            m = members[k]
            tower.append(np.add(m.p, rng.uniform() * np.subtract(m.q, m.p)))
    pts = np.concatenate([ground, seen_twice(np.array(tower))])
    ij = np.clip(((pts[:, [1, 0]] - [y0, x0]) / res).astype(int), 0, [hh - 1, ww - 1])
    return pts, span.ortho[ij[:, 0], ij[:, 1], :3].copy()


def build_reconstruction(
    camera: pycolmap.Camera,
    views: list[SceneImage],
    pts_in_world: F64,
    rgb: npt.NDArray[np.uint8],
    keypoint_noise_px: float = 0.0,
    rng: np.random.Generator | None = None,
    observe_with: list[SceneImage] | None = None,
) -> pycolmap.Reconstruction:
    """A COLMAP model of ``views`` with the points and their tracks.

    Observations are the projections of the points through ``observe_with`` (default:
    ``views``) plus optional keypoint noise, so a model with perturbed ``views`` can be
    built from the true observations.
    """
    rng = rng or np.random.default_rng(0)
    observe_with = observe_with or views
    rec = pycolmap.Reconstruction()
    rec.add_camera_with_trivial_rig(camera)
    tracks = [pycolmap.Track() for _ in range(len(pts_in_world))]
    for view, obs_view in zip(views, observe_with, strict=True):
        uv, _, ok = obs_view.project(pts_in_world)
        idx = np.flatnonzero(ok)
        uv_obs = (
            uv[idx] + rng.normal(0, keypoint_noise_px, (len(idx), 2))
            if keypoint_noise_px
            else uv[idx]
        )
        image = pycolmap.Image(name=view.name, camera_id=camera.camera_id, image_id=view.image_id)
        image.points2D = pycolmap.Point2DList([pycolmap.Point2D(p) for p in uv_obs])
        pose = pycolmap.Rigid3d(pycolmap.Rotation3d(view.rot_cam_from_world), view.t_cam_from_world)
        rec.add_image_with_trivial_frame(image, pose)
        for k, j in enumerate(idx):
            tracks[j].add_element(view.image_id, k)
    for jp, track in enumerate(tracks):
        if track.length() >= 2:
            rec.add_point3D(pts_in_world[jp], track, rgb[jp])
    rec.update_point_3d_errors()
    return rec


def _perturbed_views(
    span: SyntheticSpan, rng: np.random.Generator
) -> tuple[pycolmap.Camera, list[SceneImage]]:
    """Camera and poses as a bundle adjustment leaves them: small, realistic errors."""
    params = np.array(span.camera.params, dtype=np.float64)
    params[0:2] *= 1 + rng.normal(0, 2e-4)
    params[2:4] += rng.normal(0, 0.3 * span.options.scale, 2)
    params[4:6] += rng.normal(0, 1e-4, 2)
    camera = pycolmap.Camera(
        model="OPENCV",
        width=span.camera.width,
        height=span.camera.height,
        params=params.tolist(),
        camera_id=1,
    )
    views = []
    for v in span.views:
        drot, _ = cv2.Rodrigues(rng.normal(0, np.deg2rad(0.004), 3))
        rot = drot @ v.rot_cam_from_world
        center = v.center_in_world + rng.normal(0, 0.01, 3)
        views.append(
            SceneImage(
                image_id=v.image_id,
                name=v.name,
                path=v.path,
                camera=camera,
                rot_cam_from_world=rot,
                t_cam_from_world=-rot @ center,
            )
        )
    return camera, views


def _retriangulate(rec: pycolmap.Reconstruction) -> None:
    """Move every point to the least-squares intersection of its observation rays."""
    for pid, point in rec.points3D.items():
        a, b = np.zeros((3, 3)), np.zeros(3)
        for el in point.track.elements:
            image = rec.image(el.image_id)
            cam = rec.camera(image.camera_id)
            pose = image.cam_from_world()
            rmat = pose.rotation.matrix()
            xy = cam_from_img(cam, np.asarray(image.points2D[el.point2D_idx].xy).reshape(1, 2))[0]
            d = rmat.T @ np.array([xy[0], xy[1], 1.0])
            d /= np.linalg.norm(d)
            c = -rmat.T @ pose.translation
            p = np.eye(3) - np.outer(d, d)
            a += p
            b += p @ c
        rec.point3D(pid).xyz = np.linalg.solve(a, b)
    rec.update_point_3d_errors()


@dataclass(frozen=True)
class SyntheticSpanPaths:
    root: Path
    images: Path
    sparse_gt: Path
    sparse: Path | None
    truth_wires: Path
    terrain: Path


def span_paths(root: Path | str) -> SyntheticSpanPaths:
    root = Path(root)
    sparse = root / "sparse" / "0"
    return SyntheticSpanPaths(
        root,
        root / "images",
        root / "sparse_gt",
        sparse if sparse.is_dir() else None,
        root / "truth" / "wires.json",
        root / "truth" / "terrain.npz",
    )


def load_true_wires(path: Path | str) -> list[TrueWire]:
    with open(path) as f:
        return [TrueWire.from_json(w) for w in json.load(f)["wires"]]


def generate_span(
    output_path: Path | str, options: SyntheticSpanOptions | None = None
) -> SyntheticSpanPaths:
    """Render a synthetic span and write it to ``output_path`` (atomically, as one folder).

    Returns:
        The paths of what was written.
    """
    opts = options or SyntheticSpanOptions()
    output_path = Path(output_path)
    if output_path.exists() and any(output_path.iterdir()):
        raise FileExistsError(f"{output_path}: output folder exists and is not empty")
    t0 = time.perf_counter()
    span = build_span(opts)
    t_build = time.perf_counter() - t0
    output_path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".tmp_span_", dir=output_path.parent))
    try:
        (tmp / "images").mkdir()
        gps = pycolmap.GPSTransform(pycolmap.GPSTransformEllipsoid.WGS84)
        rng_gps = np.random.default_rng(opts.seed + 1)
        t1 = time.perf_counter()
        for k, view in enumerate(
            tqdm(span.views, desc="render", unit="img", disable=not opts.show_progress)
        ):
            img = render_image(span, view, np.random.default_rng([opts.seed, k]))
            noise = rng_gps.normal(
                0, [opts.gps_sigma_horizontal_m] * 2 + [opts.gps_sigma_vertical_m]
            )
            lla = gps.enu_to_ellipsoid(
                (view.center_in_world + noise).reshape(1, 3),
                opts.origin_lat_deg,
                opts.origin_lon_deg,
                opts.origin_alt_m,
            )[0]
            Image.fromarray(img).save(
                tmp / "images" / view.name,
                quality=opts.jpeg_quality,
                exif=_gps_exif(lla[0], lla[1], lla[2], k, span.camera),
            )
        t_render = time.perf_counter() - t1
        rng = np.random.default_rng(opts.seed + 2)
        pts, rgb = _sparse_points(span, rng)
        (tmp / "sparse_gt").mkdir()
        build_reconstruction(span.camera, span.views, pts, rgb).write_binary(tmp / "sparse_gt")
        if opts.write_perturbed_model:
            camera, views = _perturbed_views(span, rng)
            rec = build_reconstruction(
                camera, views, pts, rgb, keypoint_noise_px=0.3, rng=rng, observe_with=span.views
            )
            _retriangulate(rec)
            (tmp / "sparse" / "0").mkdir(parents=True)
            rec.write_binary(tmp / "sparse" / "0")
        (tmp / "truth").mkdir()
        span.terrain.save(tmp / "truth" / "terrain.npz")
        with open(tmp / "truth" / "wires.json", "w") as f:
            json.dump(
                {
                    "frame": "local ENU, metres",
                    "origin_wgs84": [opts.origin_lat_deg, opts.origin_lon_deg, opts.origin_alt_m],
                    "wires": [w.to_json() for w in span.wires],
                    "supports": span.supports,
                },
                f,
            )
        with open(tmp / "truth" / "scene.json", "w") as f:
            json.dump(
                {
                    "options": {
                        k: (str(v) if isinstance(v, StrEnum) else v)
                        for k, v in asdict(opts).items()
                    },
                    "camera": {
                        "model": "OPENCV",
                        "width": span.camera.width,
                        "height": span.camera.height,
                        "params": list(span.camera.params),
                    },
                    "sun_in_world": span.sun_in_world.tolist(),
                    "tower_bases": [[float(c) for c in m[0].p] for m in span.towers],
                    "side_overlap": opts.flight_side_overlap,
                    "num_images": len(span.views),
                    "strips": {v.name: k for v, k in zip(span.views, span.strips, strict=True)},
                    "timing_s": {
                        "build": t_build,
                        "render": t_render,
                        "render_per_image": t_render / len(span.views),
                    },
                },
                f,
                indent=1,
            )
        if output_path.exists():
            output_path.rmdir()
        os.replace(tmp, output_path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    logger.info(
        "synthetic span: %d images of %dx%d px, %d wires, rendered in %.1f s (%.2f s/image) → %s",
        len(span.views),
        span.camera.width,
        span.camera.height,
        len(span.wires),
        t_render,
        t_render / len(span.views),
        output_path,
    )
    return span_paths(output_path)
