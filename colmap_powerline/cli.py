"""The ``colmap-powerline`` command: parses flags, builds typed options, calls the library."""

from __future__ import annotations

import argparse
import dataclasses
import enum
import logging
import sys
import time
import types
import typing
from pathlib import Path
from typing import Any

from .errors import InputError
from .georef import GeoreferenceOptions
from .options import OptionError
from .sfm import SfmOptions
from .synthetic import Background, FlightPattern, Layout, SyntheticSpanOptions

if typing.TYPE_CHECKING:
    from .results import ReconstructionResult

logger = logging.getLogger("colmap_powerline")


def _add_synthetic_flags(p: argparse.ArgumentParser, default_scale: float) -> None:
    p.add_argument(
        "--scale",
        type=float,
        default=default_scale,
        help="image size relative to the 12 MP camera (default %(default)s)",
    )
    p.add_argument(
        "--background", type=Background, choices=list(Background), default=Background.VEGETATION
    )
    p.add_argument(
        "--flight",
        type=FlightPattern,
        choices=list(FlightPattern),
        default=FlightPattern.CORRIDOR,
        help="corridor: 3 strips along the line, the middle one over it; along4: 4 strips "
        "along it, the line between the middle two; grid: an area survey whose strips cross "
        "the line at --grid_angle_deg; across: strips across the line (default %(default)s)",
    )
    p.add_argument(
        "--grid_angle_deg",
        type=float,
        default=SyntheticSpanOptions.grid_angle_deg,
        help="flight grid: angle between the strips and the line (default %(default)s)",
    )
    p.add_argument(
        "--layout",
        type=Layout,
        choices=list(Layout),
        default=Layout.SPAN,
        help="span: one span between two towers; angle: two spans turning by --turn_deg at "
        "an angle tower (flights corridor, along4: strips along each leg); crossing: the span "
        "and a pole line crossing it at --crossing_deg (flight grid); branch: the crossing, "
        "the pole line going on past its second pole and a two-wire line leaving that pole at "
        "--branch_deg (flight grid); parallel: the span and a pole line parallel to it "
        "--parallel_offset_m across (flight grid) (default %(default)s)",
    )
    p.add_argument("--turn_deg", type=float, default=SyntheticSpanOptions.turn_deg)
    p.add_argument("--crossing_deg", type=float, default=SyntheticSpanOptions.crossing_deg)
    p.add_argument("--branch_deg", type=float, default=SyntheticSpanOptions.branch_deg)
    p.add_argument(
        "--parallel_offset_m", type=float, default=SyntheticSpanOptions.parallel_offset_m
    )
    p.add_argument("--seed", type=int, default=0)


def _synthetic_options(args: argparse.Namespace) -> SyntheticSpanOptions:
    return SyntheticSpanOptions(
        scale=args.scale,
        background=args.background,
        flight=args.flight,
        grid_angle_deg=args.grid_angle_deg,
        layout=args.layout,
        turn_deg=args.turn_deg,
        crossing_deg=args.crossing_deg,
        branch_deg=args.branch_deg,
        parallel_offset_m=args.parallel_offset_m,
        seed=args.seed,
        show_progress=not args.quiet,
    )


def _cmd_synthetic(args: argparse.Namespace) -> int:
    from .synthetic import generate_span

    paths = generate_span(args.output_path, _synthetic_options(args))
    print(f"wrote {paths.root}: images/, sparse_gt/, sparse/0/, truth/")
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from .evaluate import evaluate
    from .pipeline import reconstruct
    from .results import OutputOptions, ReconstructionOptions
    from .scene import load_scene
    from .synthetic import generate_span, load_true_wires

    out = Path(args.output_path)
    flight = str(args.flight)
    if args.flight is FlightPattern.GRID:
        flight += f"{args.grid_angle_deg:g}"
    span_dir = out / f"span_{args.background}_{flight}_s{args.scale:g}_seed{args.seed}"
    t0 = time.perf_counter()
    if (span_dir / "truth" / "wires.json").exists():
        logger.info("reusing the synthetic span in %s", span_dir)
    else:
        generate_span(span_dir, _synthetic_options(args))
    t_render = time.perf_counter() - t0
    t0 = time.perf_counter()
    result = reconstruct(
        span_dir / "images",
        span_dir / "sparse" / "0",
        out / "result",
        ReconstructionOptions(show_progress=not args.quiet),
        OutputOptions(report=True, las=True),
    )
    t_run = time.perf_counter() - t0
    truth = load_true_wires(span_dir / "truth" / "wires.json")
    reported = result.verified.pts_in_world[result.labels >= 0]  # wire_points.ply
    # Where the flight can measure each wire: judged from the true poses (sparse_gt).
    true_views = load_scene(span_dir / "sparse_gt", span_dir / "images", check_images=False)
    ev = evaluate(reported, result.wires, truth, true_views.images)  # type: ignore[arg-type]
    print(
        f"\nsynthetic span: {span_dir} (rendered in {t_render:.0f} s; "
        f"{len(result.scene)} images, {args.background}, flight {args.flight})"
    )
    print(
        f"reconstruction: {out / 'result'} in {t_run:.0f} s — {len(result.pairs)} pairs, "
        f"{sum(len(p) for p in result.primitives)} primitives, {len(result.verified)} verified "
        f"points, {len(result.wires)} wires"
    )
    print("\naccuracy against the true wires:")
    print(ev.summary_table())
    targets = ev.meets_targets()
    print(
        "\ntargets (on the wires the flight measures): "
        + ", ".join(f"{k} {'ok' if v else 'MISSED'}" for k, v in targets.items())
    )
    print("\nsag and clearance (wires.csv):")
    for k, (w, m) in enumerate(zip(result.wires, result.measures, strict=True)):
        print(
            f"  wire {w.wire_id} ({m.kind}): span {m.span_length_m:.1f} m, sag {m.sag_max_m:.2f} m"
            f"{_sag_from(result, k)}, clearance {m.clearance_vertical_m:.2f} m"
        )
    print(f"report: {result.outputs.get('report')}")
    return 0


def _sag_from(result: ReconstructionResult, k: int) -> str:
    """Said after wire ``k``'s sag where the wire was not measured where it sags most."""
    from .results import sag_from_curve

    if not sag_from_curve(result, k):
        return ""
    share = result.coverage[k].measured_share
    return f" (from its curve: measured along {100 * share:.0f} % of the span)"


def _parse_bool(text: str) -> bool:
    if text.lower() in ("1", "true", "yes", "on"):
        return True
    if text.lower() in ("0", "false", "no", "off"):
        return False
    raise argparse.ArgumentTypeError(f"{text!r} is not a boolean (use true or false)")


def _flag_kwargs(hint: Any, default: Any, dest: str, help_text: str) -> dict[str, Any] | None:
    """argparse keywords for one option field from its type (None: not a command-line type)."""
    optional = isinstance(hint, types.UnionType) and type(None) in typing.get_args(hint)
    base = next(a for a in typing.get_args(hint) if a is not type(None)) if optional else hint
    kwargs: dict[str, Any] = {"default": argparse.SUPPRESS, "dest": dest, "help": help_text}
    if base is bool:
        kwargs["type"] = _parse_bool
    elif isinstance(base, type) and issubclass(base, enum.Enum):
        kwargs.update(type=base, choices=list(base))
    elif base in (int, float, str, Path):
        kwargs["type"] = base
    else:
        return None
    if optional:
        inner = kwargs["type"]
        kwargs["type"] = lambda t, inner=inner: None if t.lower() == "none" else inner(t)
    return kwargs


def _add_option_flags(p: argparse.ArgumentParser, options_cls: type) -> None:
    """The flags of an options dataclass: ``--field`` for each of its own values (a flag of
    its own for a yes/no that is off by default: ``--las``), ``--stage.field`` for each field
    of each stage's options (COLMAP's Section.option)."""
    hints = typing.get_type_hints(options_cls)
    default_obj = options_cls()
    for f in dataclasses.fields(options_cls):
        if f.name == "show_progress":  # set by --quiet
            continue
        hint = hints[f.name]
        if dataclasses.is_dataclass(hint):
            _add_stage_flags(p, f.name, hint)
            continue
        default = getattr(default_obj, f.name)
        help_text = f.metadata.get("help", "")
        if hint is bool and default is False:
            p.add_argument(
                f"--{f.name}", action="store_true", default=argparse.SUPPRESS, help=help_text
            )
            continue
        kwargs = _flag_kwargs(hint, default, f.name, f"{help_text} (default {default})".strip())
        if kwargs is not None:
            p.add_argument(f"--{f.name}", **kwargs)


def _add_stage_flags(p: argparse.ArgumentParser, stage: str, stage_cls: type) -> None:
    group = p.add_argument_group(f"{stage} options")
    hints = typing.get_type_hints(stage_cls)
    default_obj = stage_cls()
    for f in dataclasses.fields(stage_cls):
        if f.name == "show_progress":
            continue
        default = getattr(default_obj, f.name)
        kwargs = _flag_kwargs(hints[f.name], default, f"{stage}.{f.name}", f"(default {default})")
        if kwargs is not None:
            group.add_argument(f"--{stage}.{f.name}", **kwargs)


def _options_from_flags(args: argparse.Namespace, options_cls: type, **given: Any) -> Any:
    """``options_cls`` built from the flags (defaults where none was given), each stage
    constructed with its values so that its checks run; a value out of range is an
    :class:`OptionError` naming the flag."""
    flags = vars(args)
    kwargs = dict(given)
    for f in dataclasses.fields(options_cls):
        if f.name in kwargs or f.name == "show_progress":
            continue
        stage_cls = typing.get_type_hints(options_cls)[f.name]
        if isinstance(stage_cls, type) and dataclasses.is_dataclass(stage_cls):
            values = {k.split(".", 1)[1]: v for k, v in flags.items() if k.startswith(f"{f.name}.")}
            try:
                kwargs[f.name] = stage_cls(**values)
            except OptionError as e:
                raise e.within(f"--{f.name}") from None
        elif f.name in flags:
            kwargs[f.name] = flags[f.name]
    try:
        return options_cls(**kwargs)
    except OptionError as e:
        raise OptionError(f"--{e.name}", e.value, e.expected) from None


def _reconstruction_options(args: argparse.Namespace) -> Any:
    from .results import ReconstructionOptions

    options = _options_from_flags(args, ReconstructionOptions, show_progress=not args.quiet)
    sfm = options.sfm
    return dataclasses.replace(
        options, sfm=dataclasses.replace(sfm, georeference=_georef_options(args))
    )


def _output_options(args: argparse.Namespace) -> Any:
    from .results import OutputOptions

    return _options_from_flags(args, OutputOptions)


def _add_georef_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("georeferencing (SfM models; default: EXIF GPS when present)")
    g.add_argument(
        "--origin_wgs84",
        type=_lat_lon_alt,
        default=None,
        metavar="LAT,LON,ALT",
        help="origin of the local east-north-up frame (default: the cameras' mean "
        "latitude/longitude at altitude 0)",
    )
    g.add_argument(
        "--ref_images_path",
        type=Path,
        default=None,
        help="known camera positions, one 'image_name X Y Z' per line (like COLMAP's "
        "model_aligner); they win over EXIF GPS",
    )
    g.add_argument(
        "--ref_is_gps", type=_parse_bool, default=False, help="the file holds 'name lat lon alt'"
    )
    g.add_argument(
        "--scale_m_per_unit",
        type=float,
        default=None,
        help="known scale for images without GPS (metres per model unit)",
    )
    g.add_argument(
        "--alignment_max_error",
        type=float,
        default=GeoreferenceOptions().max_error_m,
        help="metres: cameras farther than this from their position are outliers",
    )
    g.add_argument("--use_gps", type=_parse_bool, default=True, help="align to EXIF GPS")


def _lat_lon_alt(text: str) -> tuple[float, float, float]:
    try:
        lat, lon, alt = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected LAT,LON,ALT") from None
    return lat, lon, alt


# Each georeferencing flag and the GeoreferenceOptions field it sets.
_GEOREF_FLAGS = {
    "use_gps": "use_gps",
    "origin_wgs84": "origin_wgs84",
    "alignment_max_error": "max_error_m",
    "ref_images_path": "ref_images_path",
    "ref_is_gps": "ref_is_gps",
    "scale_m_per_unit": "scale_m_per_unit",
}


def _georef_flags_given(args: argparse.Namespace) -> list[str]:
    """The georeferencing flags given a value other than their default."""
    default = GeoreferenceOptions()
    return [
        f"--{flag}"
        for flag, name in _GEOREF_FLAGS.items()
        if getattr(args, flag) != getattr(default, name)
    ]


def _georef_options(args: argparse.Namespace) -> GeoreferenceOptions:
    try:
        return GeoreferenceOptions(
            **{name: getattr(args, flag) for flag, name in _GEOREF_FLAGS.items()}
        )
    except OptionError as e:
        flag = next(f for f, n in _GEOREF_FLAGS.items() if n == e.name)
        raise OptionError(f"--{flag}", e.value, e.expected) from None


def _cmd_sfm(args: argparse.Namespace) -> int:
    from .sfm import run_sfm

    options = dataclasses.replace(_reconstruction_options(args).sfm, show_progress=not args.quiet)
    result = run_sfm(args.image_path, args.output_path, options, args.skip_bad_images)
    print(f"wrote {result.model_path}\n{result.summary()}")
    return 0


def _cmd_fill(args: argparse.Namespace) -> int:
    from .dense import fill

    r = fill(
        args.dense_path,
        args.wires_path,
        args.output_path,
        include_measured=args.include_measured,
        drop_stray=args.drop_stray,
        las=args.las,
        dense_frame=args.dense_frame,
    )
    dropped = f", {r.num_dropped} stray points dropped" if args.drop_stray else ""
    las = f" and {r.las_path}" if r.las_path else ""
    print(
        f"{r.num_dense} dense points ({r.num_ground} ground{dropped}) + {r.num_wire_points} "
        f"wire points → {r.output_path}{las}"
    )
    return 0


def _cmd_reconstruct(args: argparse.Namespace) -> int:
    from .pipeline import reconstruct
    from .tasks import ExecutionOptions

    if args.image_path is None and args.input_path is None:
        raise InputError("give --image_path (and --input_path, or SfM runs first)")
    options, outputs = _reconstruction_options(args), _output_options(args)  # ranges first
    execution = _options_from_flags(args, ExecutionOptions)
    if args.input_path is not None:
        # The georeferencing flags act when SfM runs; a given model is used as it is.
        given = _georef_flags_given(args) + [f"--{k}" for k in vars(args) if k.startswith("sfm.")]
        if given:
            raise InputError(
                f"{' '.join(given)}: {'acts' if len(given) == 1 else 'act'} only when SfM "
                "runs (without --input_path); the model "
                f"{args.input_path} is used as it is (georeference it with `colmap-powerline "
                "sfm` or COLMAP's model_aligner)"
            )
    result = reconstruct(
        args.image_path, args.input_path, args.output_path, options, outputs, execution
    )
    units = "m" if result.georeference is not None else " units"
    print(
        f"{len(result.wires)} wires from {len(result.verified)} verified points "
        f"({len(result.pairs)} pairs) → {args.output_path}"
    )
    for k, (w, m) in enumerate(zip(result.wires, result.measures, strict=True)):
        flag = f", {len(m.flagged)} stretches below the limit" if m.flagged else ""
        print(
            f"  wire {w.wire_id}: span {m.span_length_m:.1f}{units}, sag {m.sag_max_m:.2f}{units}"
            f"{_sag_from(result, k)} (mid-span {m.sag_midspan_m:.2f}), "
            f"lowest z {m.lowest_point[2]:.2f}{units}, "
            f"clearance {m.clearance_vertical_m:.2f}{units} vertical / "
            f"{m.clearance_3d_m:.2f}{units} 3D, {len(w.point_indices)} points, "
            f"rms {w.rms_residual:.3f}{units}{flag}"
        )
    if result.options is not None and result.options.min_clearance_m is not None:
        n = sum(1 for m in result.measures if m.flagged)
        print(
            f"clearance: {n} of {len(result.measures)} wires come closer than "
            f"{result.options.min_clearance_m:g}{units} to the ground"
        )
    return 0


@dataclasses.dataclass(kw_only=True)
class _SfmOnly:
    """The option sections the ``sfm`` command takes."""

    sfm: SfmOptions = dataclasses.field(default_factory=SfmOptions)


def _add_common_input_flags(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--skip_bad_images",
        action="store_true",
        help="skip missing or undecodable images with a warning instead of stopping",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="colmap-powerline",
        description="Reconstruct power-line conductors in 3D from drone images and a COLMAP model.",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bars, warnings only")
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="render a synthetic span and run on it")
    demo.add_argument("--output_path", type=Path, default=Path("demo_out"))
    _add_synthetic_flags(demo, default_scale=0.5)
    demo.set_defaults(func=_cmd_demo)

    from .results import OutputOptions, ReconstructionOptions
    from .tasks import ExecutionOptions

    sfm = sub.add_parser("sfm", help="orient the images with pycolmap SfM (+ georeferencing)")
    sfm.add_argument("--image_path", type=Path, required=True)
    sfm.add_argument("--output_path", type=Path, required=True, help="model folder to write")
    _add_common_input_flags(sfm)
    _add_georef_flags(sfm)
    _add_option_flags(sfm, _SfmOnly)
    sfm.set_defaults(func=_cmd_sfm)

    rec = sub.add_parser("reconstruct", help="reconstruct the wires from a COLMAP model + images")
    rec.add_argument(
        "--image_path",
        type=Path,
        help="the images (default: images/ of an undistorted workspace given as --input_path)",
    )
    rec.add_argument(
        "--input_path",
        type=Path,
        help="COLMAP sparse model (binary or text) or undistorted workspace (dense/); "
        "without it SfM runs first and writes OUTPUT/sparse",
    )
    rec.add_argument("--output_path", type=Path, required=True)
    _add_georef_flags(rec)
    _add_option_flags(rec, ReconstructionOptions)
    _add_option_flags(rec, OutputOptions)
    _add_option_flags(rec, ExecutionOptions)
    rec.set_defaults(func=_cmd_reconstruct)

    fl = sub.add_parser("fill", help="merge the wires into a dense cloud (PLY, and LAS)")
    fl.add_argument("--dense_path", type=Path, required=True, help="dense PLY (fused.ply)")
    fl.add_argument("--wires_path", type=Path, required=True, help="wires.json of reconstruct")
    fl.add_argument("--output_path", type=Path, required=True, help="merged PLY to write")
    fl.add_argument(
        "--include_measured", action="store_true", help="add the measured wire points too"
    )
    fl.add_argument(
        "--drop_stray",
        action="store_true",
        help="drop dense points in a 1 m halo around the wires but not on them (reported)",
    )
    fl.add_argument("--las", action="store_true", help="also write LAS 1.4 beside the PLY")
    fl.add_argument(
        "--dense_frame",
        choices=("model", "wires"),
        default="model",
        help="the dense cloud's frame: the COLMAP model's (converted to the wires' CRS when "
        "they were written with --output_crs) or already the wires' own",
    )
    fl.set_defaults(func=_cmd_fill)

    syn = sub.add_parser("synthetic", help="render a synthetic span with known wires")
    syn.add_argument("--output_path", type=Path, required=True)
    _add_synthetic_flags(syn, default_scale=1.0)
    syn.set_defaults(func=_cmd_synthetic)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.WARNING if args.quiet else logging.INFO,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
        datefmt="%H:%M:%S",
    )
    import pycolmap

    # COLMAP's own log (glog) is thousands of lines per run; keep its warnings only.
    pycolmap.logging.minloglevel = 1 if not args.quiet else 2
    # The tool's own input errors (files, values, options) are one line; anything else is a
    # bug and keeps its traceback.
    try:
        return int(args.func(args))
    except (InputError, FileExistsError) as exc:
        print(f"colmap-powerline: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
