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
from .synthetic import Background, FlightPattern, SyntheticSpanOptions

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
        "--flight", type=FlightPattern, choices=list(FlightPattern), default=FlightPattern.ACROSS
    )
    p.add_argument("--seed", type=int, default=0)


def _synthetic_options(args: argparse.Namespace) -> SyntheticSpanOptions:
    return SyntheticSpanOptions(
        scale=args.scale,
        background=args.background,
        flight=args.flight,
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
    from .pipeline import ReconstructionOptions, reconstruct
    from .synthetic import generate_span, load_true_wires

    out = Path(args.output_path)
    span_dir = out / f"span_{args.background}_{args.flight}_s{args.scale:g}_seed{args.seed}"
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
    )
    t_run = time.perf_counter() - t0
    truth = load_true_wires(span_dir / "truth" / "wires.json")
    ev = evaluate(result.verified.pts_in_world, result.wires, truth)  # type: ignore[arg-type]
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
    print("\ntargets: " + ", ".join(f"{k} {'ok' if v else 'MISSED'}" for k, v in targets.items()))
    return 0


def _parse_bool(text: str) -> bool:
    if text.lower() in ("1", "true", "yes", "on"):
        return True
    if text.lower() in ("0", "false", "no", "off"):
        return False
    raise argparse.ArgumentTypeError(f"{text!r} is not a boolean (use true or false)")


def _add_option_flags(p: argparse.ArgumentParser, options_cls: type) -> None:
    """One ``--stage.field`` flag per field of each stage's options (COLMAP's Section.option)."""
    for stage in dataclasses.fields(options_cls):
        stage_cls = typing.get_type_hints(options_cls)[stage.name]
        if not dataclasses.is_dataclass(stage_cls):
            continue
        group = p.add_argument_group(f"{stage.name} options")
        hints = typing.get_type_hints(stage_cls)
        default_obj = stage_cls()  # type: ignore[operator]
        for f in dataclasses.fields(stage_cls):
            hint = hints[f.name]
            optional = isinstance(hint, types.UnionType) and type(None) in typing.get_args(hint)
            base = (
                next(a for a in typing.get_args(hint) if a is not type(None)) if optional else hint
            )
            default = getattr(default_obj, f.name)
            kwargs: dict[str, Any] = {
                "default": argparse.SUPPRESS,
                "dest": f"{stage.name}.{f.name}",
                "help": f"(default {default})",
            }
            if base is bool:
                kwargs["type"] = _parse_bool
            elif isinstance(base, type) and issubclass(base, enum.Enum):
                kwargs.update(type=base, choices=list(base))
            elif base in (int, float, str):
                kwargs["type"] = base
            else:
                continue
            if optional:
                inner = kwargs["type"]
                kwargs["type"] = lambda t, inner=inner: None if t.lower() == "none" else inner(t)
            group.add_argument(f"--{stage.name}.{f.name}", **kwargs)


def _reconstruction_options(args: argparse.Namespace) -> Any:
    from .pipeline import ReconstructionOptions

    options = ReconstructionOptions(show_progress=not args.quiet, debug=args.debug)
    for key, value in vars(args).items():
        if "." in key:
            stage, name = key.split(".", 1)
            setattr(getattr(options, stage), name, value)
    if args.wire_azimuth_deg is not None:
        options.pairs.wire_azimuth_deg = args.wire_azimuth_deg
    return options


def _cmd_reconstruct(args: argparse.Namespace) -> int:
    from .pipeline import reconstruct

    if args.input_path is None:
        raise InputError("--input_path is required (running SfM first is not available yet)")
    result = reconstruct(
        args.image_path, args.input_path, args.output_path, _reconstruction_options(args)
    )
    print(
        f"{len(result.wires)} wires from {len(result.verified)} verified points "
        f"({len(result.pairs)} pairs) → {args.output_path}"
    )
    for w in result.wires:
        lo = w.lowest_point()
        print(
            f"  wire {w.wire_id}: {w.s_range[1] - w.s_range[0]:.1f} long, sag {w.sag():.2f}, "
            f"lowest z {lo[2]:.2f}, {len(w.point_indices)} points, rms {w.rms_residual:.3f}"
        )
    return 0


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

    rec = sub.add_parser("reconstruct", help="reconstruct the wires from a COLMAP model + images")
    rec.add_argument("--image_path", type=Path, required=True)
    rec.add_argument("--input_path", type=Path, help="COLMAP sparse model (binary or text)")
    rec.add_argument("--output_path", type=Path, required=True)
    rec.add_argument(
        "--wire_azimuth_deg",
        type=float,
        default=None,
        help="the wires' direction, degrees clockwise from north (+y); "
        "default: estimated from the images",
    )
    rec.add_argument("--debug", action="store_true", help="also write primitives.ply")
    from .pipeline import ReconstructionOptions

    _add_option_flags(rec, ReconstructionOptions)
    rec.set_defaults(func=_cmd_reconstruct)

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
    try:
        return int(args.func(args))
    except (InputError, FileExistsError, ValueError) as exc:
        print(f"colmap-powerline: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
