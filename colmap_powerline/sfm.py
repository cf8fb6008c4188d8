"""Structure from motion with pycolmap, for flights that come without a COLMAP model.

:func:`run_sfm` extracts SIFT features, matches them with a strategy chosen from the data,
runs COLMAP's incremental mapper with bundle adjustment, keeps the largest model and writes
it as a binary COLMAP model. When the images carry GPS in their EXIF the model is then moved
into a local metric east-north-up frame (:mod:`colmap_powerline.georef`); the frame's origin
and the alignment residuals are written next to the model in ``georef.json``.

Cameras: images are grouped by EXIF make/model and image size, and every group shares one
camera (the drone case: one camera, one lens, every image). The default lens model is
``OPENCV`` (k1, k2, p1, p2), which fits the wide, low-distortion lenses of survey drones;
COLMAP's own default (``SIMPLE_RADIAL``) leaves a visible residual at their image corners.
"""

from __future__ import annotations

import enum
import logging
import tempfile
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np
import pycolmap
from PIL import Image, UnidentifiedImageError
from tqdm import tqdm

from .errors import InputError
from .georef import Georeference, GeoreferenceOptions, georeference_model
from .options import check_limits

logger = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".bmp")


class Matching(enum.StrEnum):
    """How image pairs are chosen for feature matching."""

    AUTO = "auto"  # spatial with GPS, exhaustive for small sets, sequential otherwise
    SPATIAL = "spatial"  # nearest neighbours by EXIF GPS position
    EXHAUSTIVE = "exhaustive"  # every pair
    SEQUENTIAL = "sequential"  # neighbours in file-name order (a flight's capture order)


@dataclass(kw_only=True)
class SfmOptions:
    """Options of :func:`run_sfm` (defaults suit a survey drone flight)."""

    camera_model: str = "OPENCV"  # COLMAP camera model shared by each camera group
    matching: Matching = Matching.AUTO  # pair selection for feature matching
    exhaustive_max_images: int = 60  # AUTO without GPS: exhaustive up to this many images
    spatial_neighbors: int = 25  # spatial matching: nearest images matched with each image
    sequential_overlap: int = 15  # sequential matching: following images matched
    max_image_size: int = 3200  # SIFT runs on images downscaled to this longer side
    max_num_features: int = 8192  # SIFT features per image
    use_gpu: bool = True  # use CUDA when pycolmap was built with it (ignored otherwise)
    num_threads: int = -1  # -1: all cores
    refine_principal_point: bool = True  # drone lenses sit off-centre: a fixed principal
    # point shifts every camera by decimetres, alternately on serpentine strips
    random_seed: int = 0  # makes the mapper repeatable
    georeference: GeoreferenceOptions = field(default_factory=GeoreferenceOptions)
    show_progress: bool = True

    LIMITS: ClassVar[dict[str, str]] = {
        "exhaustive_max_images": ">= 2",
        "spatial_neighbors": ">= 1",
        "sequential_overlap": ">= 1",
        "max_image_size": ">= 100",
        "max_num_features": ">= 100",
        "num_threads": "-1 or >= 1",
        "random_seed": ">= 0",
    }

    def __post_init__(self) -> None:
        check_limits(self)


@dataclass
class SfmResult:
    """What :func:`run_sfm` produced.

    Attributes:
        model_path: the written binary model.
        reconstruction: the model in memory (georeferenced when GPS was available).
        num_images: images found in ``image_path``.
        matching: the matching strategy that ran.
        georeference: how the model was put into metres, or None when it could not be.
        timings_s: seconds per step.
    """

    model_path: Path
    reconstruction: pycolmap.Reconstruction
    num_images: int
    matching: Matching
    georeference: Georeference | None
    timings_s: dict[str, float]

    @property
    def num_registered(self) -> int:
        return self.reconstruction.num_reg_images()

    def summary(self) -> str:
        rec = self.reconstruction
        lines = [
            f"registered {rec.num_reg_images()} / {self.num_images} images, "
            f"{rec.num_points3D()} points, mean reprojection error "
            f"{rec.compute_mean_reprojection_error():.2f} px, mean track length "
            f"{rec.compute_mean_track_length():.1f}",
            "time: "
            + ", ".join(f"{k} {v:.0f} s" for k, v in self.timings_s.items())
            + f" ({self.matching} matching)",
        ]
        if self.georeference is not None:
            lines.append(self.georeference.summary())
        return "\n".join(lines)


def list_images(image_path: Path) -> list[str]:
    """Image names (relative to ``image_path``, sub-folders included), sorted."""
    if not image_path.is_dir():
        raise InputError(f"{image_path}: image folder does not exist")
    names = sorted(
        p.relative_to(image_path).as_posix()
        for p in image_path.rglob("*")
        if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file()
    )
    if not names:
        raise InputError(f"{image_path}: no images (.jpg, .png, .tif) in this folder")
    return names


def _camera_groups(image_path: Path, names: list[str], skip_bad: bool) -> dict[tuple, list[str]]:
    """Images grouped by (make, model, width, height): each group gets one shared camera."""
    groups: dict[tuple, list[str]] = defaultdict(list)
    for name in names:
        try:
            with Image.open(image_path / name) as im:
                exif = im.getexif()
                key = (str(exif.get(0x010F, "")).strip(), str(exif.get(0x0110, "")).strip())
                groups[(*key, *im.size)].append(name)
        except (UnidentifiedImageError, OSError) as e:
            if not skip_bad:
                raise InputError(f"{image_path / name}: not a readable image ({e})") from None
            logger.warning("skipping %s: not a readable image", image_path / name)
    return groups


def _device(use_gpu: bool) -> pycolmap.Device:
    return pycolmap.Device.cuda if use_gpu and pycolmap.has_cuda else pycolmap.Device.cpu


def _extract(
    database_path: Path, image_path: Path, names: list[str], opts: SfmOptions, skip_bad: bool
) -> None:
    groups = _camera_groups(image_path, names, skip_bad)
    extraction = pycolmap.FeatureExtractionOptions()
    extraction.max_image_size = opts.max_image_size
    extraction.num_threads = opts.num_threads
    extraction.sift.max_num_features = opts.max_num_features
    device = _device(opts.use_gpu)
    bar = tqdm(
        total=sum(len(g) for g in groups.values()),
        desc="SIFT features",
        unit="image",
        disable=not opts.show_progress,
    )
    for (make, model, w, h), group in sorted(groups.items()):
        logger.info(
            "camera %s %s %dx%d: %d images, one shared %s camera",
            make or "?",
            model or "?",
            w,
            h,
            len(group),
            opts.camera_model,
        )
        reader = pycolmap.ImageReaderOptions()
        reader.camera_model = opts.camera_model
        # In chunks, for progress; every chunk after the first reuses the group's camera.
        chunk = 8
        for k in range(0, len(group), chunk):
            if k > 0:
                with pycolmap.Database.open(database_path) as db:
                    first = db.read_image_with_name(group[0])
                assert first is not None  # written by the first chunk
                reader.existing_camera_id = first.camera_id
            pycolmap.extract_features(
                database_path,
                image_path,
                image_names=group[k : k + chunk],
                camera_mode=pycolmap.CameraMode.SINGLE,
                reader_options=reader,
                extraction_options=extraction,
                device=device,
            )
            bar.update(len(group[k : k + chunk]))
    bar.close()


def _gps_priors(database_path: Path) -> dict[str, np.ndarray]:
    """EXIF GPS (lat, lon, alt) per image name, as pycolmap stored it while extracting."""
    with pycolmap.Database.open(database_path) as db:
        names = {im.image_id: im.name for im in db.read_all_images()}
        priors = {}
        for prior in db.read_all_pose_priors():
            if (
                prior.has_position()
                and prior.coordinate_system == pycolmap.PosePriorCoordinateSystem.WGS84
                and prior.corr_data_id.id in names
            ):
                priors[names[prior.corr_data_id.id]] = np.asarray(prior.position, float)
    return priors


def _match(database_path: Path, n_images: int, has_gps: bool, opts: SfmOptions) -> Matching:
    strategy = opts.matching
    if strategy == Matching.AUTO:
        if has_gps and n_images > opts.spatial_neighbors + 1:
            strategy = Matching.SPATIAL
        elif has_gps or n_images <= opts.exhaustive_max_images:
            strategy = Matching.EXHAUSTIVE
        else:
            strategy = Matching.SEQUENTIAL
    if strategy == Matching.SPATIAL and not has_gps:
        raise InputError(f"{database_path.parent}: spatial matching needs GPS in the images' EXIF")
    matching = pycolmap.FeatureMatchingOptions()
    matching.num_threads = opts.num_threads
    device = _device(opts.use_gpu)
    logger.info("matching features (%s) ...", strategy)
    if strategy == Matching.SPATIAL:
        pairing = pycolmap.SpatialPairingOptions()
        pairing.max_num_neighbors = opts.spatial_neighbors
        pairing.max_distance = 1e9  # the neighbour count decides, whatever the altitude
        pairing.ignore_z = True
        pycolmap.match_spatial(database_path, matching, pairing, device=device)
    elif strategy == Matching.EXHAUSTIVE:
        pycolmap.match_exhaustive(database_path, matching, device=device)
    else:
        pairing_seq = pycolmap.SequentialPairingOptions()
        pairing_seq.overlap = opts.sequential_overlap
        pycolmap.match_sequential(database_path, matching, pairing_seq, device=device)
    return strategy


def _map(
    database_path: Path, image_path: Path, work: Path, opts: SfmOptions
) -> pycolmap.Reconstruction:
    mapping = pycolmap.IncrementalPipelineOptions()
    mapping.num_threads = opts.num_threads
    mapping.random_seed = opts.random_seed
    mapping.multiple_models = True
    mapping.ba_refine_principal_point = opts.refine_principal_point
    with pycolmap.Database.open(database_path) as db:
        n_images = db.num_images()
    bar = tqdm(total=n_images, desc="mapping", unit="image", disable=not opts.show_progress)
    models = pycolmap.incremental_mapping(
        database_path,
        image_path,
        work / "models",
        mapping,
        next_image_callback=lambda: bar.update(1),
    )
    bar.close()
    if not models:
        raise InputError(
            f"{image_path}: SfM could not register the images (too little overlap or texture)"
        )
    return max(models.values(), key=lambda r: (r.num_reg_images(), r.num_points3D()))


_MODEL_FILES = {
    f"{n}.{e}" for n in ("cameras", "images", "points3D", "rigs", "frames") for e in ("bin", "txt")
} | {"georef.json"}


def _check_output(output_path: Path) -> None:
    """Refuse (before any work) a model folder that holds anything but a previous model."""
    if output_path.is_file():
        raise InputError(f"{output_path}: exists and is a file, not a folder for the model")
    others = [p.name for p in output_path.glob("*") if p.name not in _MODEL_FILES]
    if others:
        raise InputError(
            f"{output_path}: folder holds other files ({', '.join(sorted(others)[:3])}); "
            "give an empty or new folder for the model"
        )


def _replace_model(staged: Path, output_path: Path) -> None:
    """Move a finished model into ``output_path``, replacing only a previous model's files."""
    output_path.mkdir(parents=True, exist_ok=True)
    for old in output_path.iterdir():
        old.unlink()
    for new in staged.iterdir():
        new.rename(output_path / new.name)


def run_sfm(
    image_path: Path | str,
    output_path: Path | str,
    options: SfmOptions | None = None,
    skip_bad_images: bool = False,
) -> SfmResult:
    """Orient the images in ``image_path`` and write a binary COLMAP model to ``output_path``.

    The model is written only once it is complete (a failed run leaves no partial model).
    ``georef.json`` is written next to it when the model was put into metres.
    """
    opts = options or SfmOptions()
    image_path, output_path = Path(image_path), Path(output_path)
    names = list_images(image_path)
    _check_output(output_path)
    timings: dict[str, float] = {}
    output_path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=".sfm-", dir=output_path.parent) as tmp:
        work = Path(tmp)
        db_path = work / "database.db"
        t0 = time.perf_counter()
        logger.info("extracting SIFT features from %d images ...", len(names))
        _extract(db_path, image_path, names, opts, skip_bad_images)
        timings["extraction"] = time.perf_counter() - t0
        priors = _gps_priors(db_path)
        has_gps = len(priors) >= 3
        t0 = time.perf_counter()
        strategy = _match(db_path, len(names), has_gps, opts)
        timings["matching"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        logger.info("incremental mapping and bundle adjustment ...")
        rec = _map(db_path, image_path, work, opts)
        timings["mapping"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        georef = georeference_model(rec, priors, opts.georeference)
        timings["georeferencing"] = time.perf_counter() - t0
        staged = work / "model"
        staged.mkdir()
        rec.write_binary(staged)
        if georef is not None:
            georef.write(staged)
        _replace_model(staged, output_path)
    result = SfmResult(output_path, rec, len(names), strategy, georef, timings)
    logger.info("SfM: %s", result.summary().replace("\n", "; "))
    return result
