#!/usr/bin/env python
"""Render a synthetic power-line span with known wires (every SyntheticSpanOptions field is a flag).

python scripts/make_synthetic_span.py --output_path spans/veg --scale 0.5 --background mixed
python scripts/make_synthetic_span.py --output_path spans/grid --flight grid --grid_angle_deg 35
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
from enum import StrEnum
from pathlib import Path

from colmap_powerline.synthetic import SyntheticSpanOptions, generate_span


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--output_path", type=Path, required=True)
    defaults = SyntheticSpanOptions()
    for f in dataclasses.fields(SyntheticSpanOptions):
        value = getattr(defaults, f.name)
        if isinstance(value, bool):
            parser.add_argument(
                f"--{f.name}",
                type=lambda s: s.lower() in ("1", "true", "yes"),
                default=value,
                help=f"(default {value})",
            )
        elif value is None:  # side_overlap: None picks the flight pattern's own default
            parser.add_argument(
                f"--{f.name}", type=float, default=None, help="(default: per --flight)"
            )
        elif isinstance(value, StrEnum):
            parser.add_argument(
                f"--{f.name}",
                type=type(value),
                choices=list(type(value)),
                default=value,
                help=f"(default {value})",
            )
        else:
            parser.add_argument(
                f"--{f.name}", type=type(value), default=value, help=f"(default {value})"
            )
    args = vars(parser.parse_args(argv))
    output_path = args.pop("output_path")
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s", datefmt="%H:%M:%S")
    paths = generate_span(output_path, SyntheticSpanOptions(**args))
    print(paths)


if __name__ == "__main__":
    main()
