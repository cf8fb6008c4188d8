"""The pipeline's options and results: what :func:`colmap_powerline.reconstruct` takes and
gives, and what one corridor's reconstruction gives, as types of their own (the report and
the output step read them without importing the pipeline)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from .clearance import GroundModel, WireMeasures
from .coverage import WireCoverage
from .detect import DetectOptions
from .georef import Georeference
from .options import check_limits
from .pairs import ImagePair, PairsOptions, WireCorridor
from .rectify import RectifyOptions
from .scene import Scene
from .sfm import SfmOptions
from .spans import LineSupport, SpanOptions, WireSpan
from .support import SupportOptions, WireSupport
from .trace import TraceOptions
from .triangulate import Primitives, TriangulateOptions
from .verify import VerifiedPoints, VerifyOptions
from .wires import FittedWire, WiresOptions


@dataclass(kw_only=True)
class ReconstructionOptions:
    pairs: PairsOptions = field(default_factory=PairsOptions)
    rectify: RectifyOptions = field(default_factory=RectifyOptions)
    detect: DetectOptions = field(default_factory=DetectOptions)
    triangulate: TriangulateOptions = field(default_factory=TriangulateOptions)
    verify: VerifyOptions = field(default_factory=VerifyOptions)
    wires: WiresOptions = field(default_factory=WiresOptions)
    support: SupportOptions = field(default_factory=SupportOptions)
    trace: TraceOptions = field(default_factory=TraceOptions)
    spans: SpanOptions = field(default_factory=SpanOptions)
    sfm: SfmOptions = field(default_factory=SfmOptions)  # used when no model is given
    skip_bad_images: bool = field(
        default=False,
        metadata={"help": "skip missing or undecodable images with a warning instead of stopping"},
    )
    min_clearance_m: float | None = field(
        default=None,
        metadata={
            "help": "flag the wire stretches that come closer than this to the ground (vertically)"
        },
    )
    tile_footprints: float = field(
        default=4.0,
        metadata={
            "help": "a line longer than this many image footprints (along the line, at the "
            "wires' height) is reconstructed in tiles about this long, each a task that "
            "reads only the images that see it"
        },
    )
    show_progress: bool = True  # progress bars on the loops over pairs and images (--quiet)

    LIMITS: ClassVar[dict[str, str]] = {"min_clearance_m": ">= 0", "tile_footprints": ">= 1"}

    def __post_init__(self) -> None:
        check_limits(self)


@dataclass(kw_only=True)
class OutputOptions:
    """What :func:`colmap_powerline.write_outputs` writes besides wires.json, wires.csv,
    supports.csv, wires.ply and wire_points.ply (the algorithm does not read these, except
    the dense cloud's ground for the clearance)."""

    dense_path: Path | None = field(
        default=None,
        metadata={
            "help": "dense cloud (fused.ply): its ground for the clearance; the wires are "
            "merged into it as OUTPUT/merged.ply"
        },
    )
    output_crs: str | None = field(
        default=None,
        metadata={
            "help": "write coordinates in a projected CRS: 'utm' (the zone of the site) or "
            "'EPSG:…'; needs a model georeferenced from GPS"
        },
    )
    las: bool = field(
        default=False,
        metadata={"help": "also write wires.las (LAS 1.4; and merged.las with --dense_path)"},
    )
    report: bool = field(
        default=False, metadata={"help": "also write OUTPUT/report/ (figures + HTML)"}
    )
    debug: bool = field(
        default=False,
        metadata={"help": "also write primitives.ply (every candidate before verification)"},
    )


@dataclass(eq=False)
class ReconstructionResult:
    scene: Scene
    corridor: WireCorridor
    pairs: list[ImagePair]
    primitives: list[Primitives]
    verified: VerifiedPoints
    wires: list[FittedWire]
    labels: npt.NDArray[np.int64]  # (N,) wire id of each verified point, -1 for none
    timings_s: dict[str, float]
    decoded: list[Path]  # every image file decoded, in order (repeats included)
    measures: list[WireMeasures]  # sag and clearance of each wire
    supports: list[WireSupport]  # how well the views support each wire
    georeference: Georeference | None  # how the model is in metres (None: it is not)
    outputs: dict[str, Path] = field(default_factory=dict)
    coverage: list[WireCoverage] = field(default_factory=list)  # where each wire was
    # measured, and why not elsewhere
    placement: list[WireSpan] = field(default_factory=list)  # each wire's line and span
    line_supports: list[LineSupport] = field(default_factory=list)  # towers and poles
    corridors: list[WireCorridor] = field(default_factory=list)  # every line's (or leg's)
    ground: GroundModel | None = None  # the ground the clearance was measured from
    ground_from: Path | None = None  # the dense cloud it came from (None: sparse points)
    options: ReconstructionOptions | None = None  # the options it ran with
    image_path: Path | None = None  # where its images were read
    input_path: Path | None = None  # the model it started from


def sag_from_curve(result: ReconstructionResult, k: int) -> bool:
    """Whether wire ``k`` of ``result`` was not measured where it sags most (its sag there
    comes from its curve continued; :meth:`WireCoverage.measured_at`)."""
    cov = result.coverage
    return k < len(cov) and not cov[k].measured_at(result.measures[k].sag_max_at_m)


@dataclass(eq=False)
class CorridorResult:
    """What one corridor's pairs measured: :func:`reconstruct_corridor`."""

    corridor: WireCorridor
    pairs: list[ImagePair]
    primitives: list[Primitives]
    verified: VerifiedPoints
    wires: list[FittedWire]
    supports: list[WireSupport]
    decoded: list[Path]  # every image file decoded, in order (repeats included)
    n_candidates: int  # wires hypothesised before the views judged them
    on_ground: int  # of those, how many lay on the ground
    legs: list[int] = field(default_factory=list)  # (merged) the corridor of each wire
    corridors: list[WireCorridor] = field(default_factory=list)  # (merged) every corridor
