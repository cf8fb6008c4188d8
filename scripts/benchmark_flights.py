#!/usr/bin/env python
"""The reconstruction over a matrix of flights × grounds × seeds, on two synthetic generators.

Generators:

- ``package``: this package's renderer, ``colmap_powerline.synthetic.generate_span`` (flights
  corridor, along4, grid, across; grounds vegetation, bare_soil, mixed), scored with
  ``colmap_powerline.evaluate.evaluate`` against ``truth/wires.json``.
- ``shared``: the independent generator in ``--shared_path`` (``render_scene.py``, run from
  its own folder, never copied), scored with its own ``score.py``. Its presets fix the ground
  of each flight (``bench_scene.PRESETS`` has no ground override on the command line), so a
  (flight, ground) cell runs the preset of that flight and ground when there is one, else the
  flight's only preset; the mapping is printed and each row names its preset and true ground:

  ======== ========================================== ==================
  flight   presets (ground)                           shared flight
  ======== ========================================== ==================
  corridor corridor (vegetation)                      3 strips along, 75 %
  along4   mixed, vegetation, soil (= bare_soil)      4 strips along, 68 %
  grid     grid (mixed)                               strips at 35°
  across   cross (mixed)                              3 strips across
  multispan multispan (mixed; 4 spans, angle tower)   3 strips along each leg
  twolines twolines (line of towers + line of poles)  area survey at 35°
  ======== ========================================== ==================

The two survey layouts (``multispan``, ``twolines``; shared generator only: the package
renders one span) add to their row: the spans the output numbers against the true ones, the
least complete span, and the supports: true towers and poles matched by a support found
within 0.5 m in plan and 1 m in height (its highest attachment against the tower's top), how
many were found, the worst plan and height errors, and the time per span.

Every cell renders its scene at ``--scale`` (cached under ``--work_path`` and reused), runs
``colmap-powerline reconstruct --image_path SCENE/images --input_path SCENE/sparse/0`` in a
subprocess with a timeout (a non-zero exit is a row with its one-line message), scores the
output and caches the row (``--rerun`` runs the reconstruction again). One job at a time.

Columns: wires found (completeness ≥ 50 %) / true wires; conductor completeness min–max and
length-weighted; each shield wire's completeness; median distance of all output points to the
nearest true wire; share of points farther than 30 cm; ghosts (package: a fitted wire whose
polyline lies mostly > 30 cm from every true wire; shared: a wire label whose points are
mostly > 30 cm from every true wire); purity (share of each label's inliers on its dominant
true wire, inlier-weighted); reconstruction wall time, and that time over the decode floor
(every image of the scene decoded once, one after another).

    python scripts/benchmark_flights.py                                   # the whole matrix
    python scripts/benchmark_flights.py --generators shared --flights corridor --seeds 3
    python scripts/benchmark_flights.py --generators package --flights corridor \\
        --grounds vegetation --seeds 3 --json flights.json
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

FLIGHTS = ("corridor", "along4", "grid", "across", "multispan", "twolines")
# Survey layouts of several spans (the shared generator's; the package renders one span).
LAYOUTS = ("multispan", "twolines")
GROUNDS = ("vegetation", "bare_soil", "mixed")
GENERATORS = ("package", "shared")
# The shared generator's flight kinds and ground names, in this package's terms.
SHARED_FLIGHTS = {"corridor3": "corridor", "parallel": "along4", "grid": "grid", "cross": "across"}
SHARED_GROUNDS = {"soil": "bare_soil"}
CLI = [sys.executable, "-m", "colmap_powerline.cli"]


@dataclass
class Cell:
    generator: str
    flight: str
    ground: str  # the ground actually rendered
    seed: int
    preset: str | None = None  # shared generator only
    requested: list[str] = field(default_factory=list)  # the (flight × ground) cells it stands for

    @property
    def name(self) -> str:
        if self.generator == "package":
            return f"{self.ground}_{self.flight}"
        return f"{self.preset}"


# ---------------------------------------------------------------- the matrix


def shared_presets(shared_path: Path) -> dict[str, tuple[str, str]]:
    """preset → (flight, ground) of the shared generator's single-span presets, read from
    its bench_scene.PRESETS (in a subprocess, from its own folder)."""
    code = (
        "import json, bench_scene\n"
        "print(json.dumps({k: [v['flight'], v['terrain']] for k, v in "
        "bench_scene.PRESETS.items() if 'layout' not in v}))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=shared_path, capture_output=True, text=True, check=True
    )
    presets = {}
    for name, (flight, ground) in json.loads(out.stdout).items():
        if flight in SHARED_FLIGHTS:
            presets[name] = (SHARED_FLIGHTS[flight], SHARED_GROUNDS.get(ground, ground))
    return presets


def plan_cells(args: argparse.Namespace) -> list[Cell]:
    cells: list[Cell] = []
    for generator in args.generators:
        if generator == "package":
            for flight in [f for f in args.flights if f not in LAYOUTS]:
                for ground in args.grounds:
                    for seed in args.seeds:
                        cells.append(Cell("package", flight, ground, seed))
            continue
        presets = shared_presets(args.shared_path)
        chosen: dict[tuple[str, int], Cell] = {}
        for flight in [f for f in args.flights if f in LAYOUTS]:
            for seed in args.seeds:  # the layout fixes its ground (mixed)
                cells.append(Cell("shared", flight, "mixed", seed, flight, [flight]))
        for flight in [f for f in args.flights if f not in LAYOUTS]:
            options = {g: p for p, (f, g) in presets.items() if f == flight}
            if not options:
                print(f"shared: no preset flies {flight}; skipped")
                continue
            for ground in args.grounds:
                if ground in options:
                    preset, note = options[ground], ""
                else:
                    real, preset = next(iter(options.items()))
                    note = f" (the preset's ground is {real}: the ground cannot be overridden)"
                print(f"shared: {flight} × {ground} → preset {preset}{note}")
                for seed in args.seeds:
                    cell = chosen.get((preset, seed))
                    if cell is None:
                        f, g = presets[preset]
                        cell = chosen[(preset, seed)] = Cell("shared", f, g, seed, preset)
                        cells.append(cell)
                    cell.requested.append(f"{flight}×{ground}")
    return cells


# ---------------------------------------------------------------- rendering


def render(cell: Cell, args: argparse.Namespace) -> Path:
    """The cell's scene folder, rendered now unless cached."""
    if cell.generator == "package":
        # Same layout as scripts/benchmark.py, so that both reuse each other's renders.
        scene = args.work_path / "spans" / f"{cell.name}_s{args.scale:g}_seed{cell.seed}"
        if (scene / "truth" / "wires.json").exists():
            return scene
        from colmap_powerline.synthetic import SyntheticSpanOptions, generate_span

        t0 = time.perf_counter()
        opts = SyntheticSpanOptions(
            scale=args.scale,
            background=cell.ground,
            flight=cell.flight,
            seed=cell.seed,
            show_progress=False,
        )
        generate_span(scene, opts)
        print(f"  rendered {scene} in {time.perf_counter() - t0:.0f} s", flush=True)
        return scene
    scene = args.work_path / "shared" / f"{cell.preset}_s{args.scale:g}_seed{cell.seed}"
    if (scene / "gt" / "render_log.json").exists():
        return scene
    tmp = scene.with_name(scene.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.parent.mkdir(parents=True, exist_ok=True)
    cmd = [
        sys.executable,
        "render_scene.py",
        str(tmp.resolve()),
        "--preset",
        str(cell.preset),
        "--seed",
        str(cell.seed),
        "--scale",
        f"{args.scale:g}",
        "--jobs",
        "1",
    ]
    t0 = time.perf_counter()
    with open(tmp.with_suffix(".log"), "w") as log:
        subprocess.run(
            cmd,
            cwd=args.shared_path,
            stdout=log,
            stderr=subprocess.STDOUT,
            timeout=args.timeout,
            check=True,
        )
    shutil.rmtree(scene, ignore_errors=True)
    os.replace(tmp, scene)
    print(f"  rendered {scene} in {time.perf_counter() - t0:.0f} s", flush=True)
    return scene


# ---------------------------------------------------------------- reconstruction


def one_line(stderr: str) -> str:
    """The error line of a failed run: the CLI's own message, else the last line."""
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("colmap-powerline: error:")]
    return (errors or lines or ["(no message)"])[-1]


def reconstruct(scene: Path, out: Path, timeout: float) -> tuple[int | str, str, float]:
    """(exit status or "timeout", one-line message, wall time) of the CLI on a scene."""
    shutil.rmtree(out, ignore_errors=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    cmd = [
        *CLI,
        "--quiet",
        "reconstruct",
        "--image_path",
        str(scene / "images"),
        "--input_path",
        str(scene / "sparse" / "0"),
        "--output_path",
        str(out),
    ]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as exc:
        stderr = exc.stderr.decode() if isinstance(exc.stderr, bytes) else exc.stderr or ""
        out.with_suffix(".log").write_text(stderr)
        return "timeout", f"no result after {timeout:g} s", time.perf_counter() - t0
    elapsed = time.perf_counter() - t0
    out.with_suffix(".log").write_text(proc.stdout + proc.stderr)
    if proc.returncode:
        message = one_line(proc.stderr)
    else:  # the CLI's summary: "N wires from M verified points (P pairs) → OUT"
        message = next((ln for ln in proc.stdout.splitlines() if ln.strip()), "")
    return proc.returncode, message, elapsed


def decode_floor(paths: Iterable[Path]) -> float:
    """Seconds to decode the images ``paths`` once, one after another: the floor of a run
    that reads them (here every image of the scene: the run itself reads only those that
    see the wires; ``benchmark.py`` passes the run's own list)."""
    t0 = time.perf_counter()
    for path in paths:
        cv2.imread(str(path), cv2.IMREAD_COLOR)
    return time.perf_counter() - t0


# ---------------------------------------------------------------- scoring


@dataclass
class _JsonWire:
    """A fitted wire read back from wires.json, as evaluate() needs it."""

    wire_id: int
    origin: np.ndarray
    direction: np.ndarray
    a: float | None
    s0: float
    z0: float
    s_range: tuple[float, float]
    sag_m: float

    @classmethod
    def from_json(cls, d: dict) -> _JsonWire:
        cat = d["catenary"]
        return cls(
            int(d["id"]),
            np.asarray(d["plane"]["origin"], np.float64),
            np.asarray(d["plane"]["direction"], np.float64),
            None if cat["a"] is None else float(cat["a"]),
            float(cat["s0"]),
            float(cat["z0"]),
            (float(d["s_range"][0]), float(d["s_range"][1])),
            float(d["sag_m"]) if d.get("sag_m") is not None else float("nan"),
        )

    def points(self, s: Any) -> np.ndarray:
        s = np.asarray(s, np.float64).reshape(-1)
        if self.a is None or not math.isfinite(self.a):
            z = np.full(len(s), self.z0)
        else:
            z = self.z0 + self.a * (np.cosh((s - self.s0) / self.a) - 1)
        return np.c_[self.origin + s[:, None] * self.direction, z]

    def polyline(self, step: float = 0.1) -> np.ndarray:
        lo, hi = self.s_range
        return self.points(np.linspace(lo, hi, max(int(np.ceil((hi - lo) / step)) + 1, 2)))

    def sag(self) -> float:
        return self.sag_m


def _purity(labels: np.ndarray, nearest: np.ndarray, inlier: np.ndarray) -> float | None:
    total = hits = 0
    for lab in np.unique(labels[labels >= 0]):
        m = (labels == lab) & inlier
        if m.any():
            hits += int(np.bincount(nearest[m]).max())
            total += int(m.sum())
    return hits / total if total else None


def score_package(scene: Path, out: Path) -> dict[str, Any]:
    from colmap_powerline.evaluate import distance_to_polyline, evaluate
    from colmap_powerline.export import read_point_cloud
    from colmap_powerline.synthetic import load_true_wires

    truth = load_true_wires(scene / "truth" / "wires.json")
    pts, _, labels = read_point_cloud(out / "wire_points.ply")
    if labels is None:
        labels = np.full(len(pts), -1, np.int32)
    fitted = [_JsonWire.from_json(d) for d in json.loads((out / "wires.json").read_text())["wires"]]
    ev = evaluate(pts, fitted, truth)
    wires = [
        {
            "kind": s.kind,
            "completeness": s.completeness,
            "found": s.found,
            "length_m": max(t.length_m - 4.0, 0.0),
        }
        for s, t in zip(ev.wires, truth, strict=True)
    ]
    median = purity = None
    if len(pts):
        dist = np.stack([distance_to_polyline(pts, t.polyline(0.02)) for t in truth])
        dmin, nearest = dist.min(axis=0), dist.argmin(axis=0)
        median = float(np.median(dmin))
        purity = _purity(labels, nearest, dmin <= 0.30)
    return {
        "wires": wires,
        "num_points": len(pts),
        "num_fitted": len(fitted),
        "median_m": median,
        "outlier_share": ev.outlier_share if len(pts) else None,
        "ghosts": ev.ghost_wires,
        "purity": purity,
    }


def score_shared(scene: Path, out: Path, shared_path: Path) -> dict[str, Any]:
    result = out.parent / "score.json"
    cmd = [
        sys.executable,
        "score.py",
        str(scene.resolve()),
        str((out / "wire_points.ply").resolve()),
        "--json",
        str(result.resolve()),
    ]
    proc = subprocess.run(cmd, cwd=shared_path, capture_output=True, text=True)
    if proc.returncode:
        raise RuntimeError(f"score.py failed: {one_line(proc.stderr)}")
    r = json.loads(result.read_text())
    wires = [
        {
            "kind": "shield" if w["kind"] == "shield" else "conductor",
            "completeness": w["completeness"],
            "found": w["found"],
            "length_m": w["evaluated_length_m"],
        }
        for w in r["completeness"]["per_wire"]
    ]
    labels = r.get("labels") or {}
    ghosts = sum(1 for v in (labels.get("per_label") or {}).values() if v["outlier_fraction"] > 0.5)
    doc = json.loads((out / "wires.json").read_text())
    fitted = doc["wires"]
    spans = r["completeness"].get("per_span")
    layout = {}
    if spans:
        layout = {
            "span_min": min(v["completeness"] for v in spans),
            "spans_true": len(spans),
            "spans_found": len({(w.get("line"), w.get("span")) for w in fitted}),
            **score_supports(
                doc.get("supports", []),
                json.loads((scene / "gt" / "wires.json").read_text())["scene"]["towers"],
            ),
        }
    return {
        "wires": wires,
        "num_points": r["n_points"],
        "num_fitted": len(fitted),
        "median_m": r["accuracy"]["median_m"],
        "outlier_share": r["accuracy"]["outlier_fraction"],
        "ghosts": ghosts,
        "purity": labels.get("purity_weighted"),
        **layout,
    }


def score_supports(
    found: Sequence[dict[str, Any]], towers: Sequence[dict[str, Any]]
) -> dict[str, Any]:
    """The true towers and poles (each with its ``base`` and ``top_z``) matched by supports
    found: the nearest in plan, within 0.5 m in plan and 1 m in height (its highest
    attachment against the tower's top)."""
    plan, height, ok = [], [], 0
    for t in towers:
        if not found:
            break
        d = [math.dist(f["position"][:2], t["base"][:2]) for f in found]
        k = int(np.argmin(d))
        dz = found[k]["top_z"] - t["top_z"]
        plan.append(d[k])
        height.append(dz)
        ok += d[k] <= 0.5 and abs(dz) <= 1.0
    return {
        "supports_true": len(towers),
        "supports_found": len(found),
        "supports_right": ok,
        "support_plan_max_m": max(plan) if plan else None,
        "support_height_max_m": max(abs(h) for h in height) if height else None,
    }


def summarise(metrics: dict[str, Any]) -> dict[str, Any]:
    """The row's columns from per-wire scores."""
    wires = metrics.pop("wires")
    cond = [w for w in wires if w["kind"] == "conductor"]
    length = sum(w["length_m"] for w in cond)
    return {
        **metrics,
        "wires_found": sum(w["found"] for w in wires),
        "true_wires": len(wires),
        "conductor_min": min((w["completeness"] for w in cond), default=None),
        "conductor_max": max((w["completeness"] for w in cond), default=None),
        "conductor_weighted": (
            sum(w["completeness"] * w["length_m"] for w in cond) / length if length else None
        ),
        "shields": [w["completeness"] for w in wires if w["kind"] == "shield"],
    }


# ---------------------------------------------------------------- rows


def run_cell(cell: Cell, args: argparse.Namespace) -> dict[str, Any]:
    run_dir = (
        args.work_path
        / "flights"
        / cell.generator
        / (f"{cell.name}_s{args.scale:g}_seed{cell.seed}")
    )
    row_path = run_dir / "row.json"
    if row_path.exists() and not args.rerun:
        row = json.loads(row_path.read_text())
        row.update(cached=True, requested=cell.requested)
        return row
    row: dict[str, Any] = {
        "generator": cell.generator,
        "flight": cell.flight,
        "ground": cell.ground,
        "preset": cell.preset,
        "requested": cell.requested,
        "seed": cell.seed,
        "scale": args.scale,
    }
    try:
        scene = render(cell, args)
    except (subprocess.SubprocessError, OSError, ValueError) as exc:
        return {**row, "exit": "render", "message": f"render failed: {exc}", "time_s": None}
    row["scene"] = str(scene)
    row["images"] = len(list((scene / "images").iterdir()))
    out = run_dir / "out"
    status, message, elapsed = reconstruct(scene, out, args.timeout)
    row.update({"exit": status, "message": message, "time_s": elapsed, "output": str(out)})
    row["decode_s"] = decode_floor(sorted((scene / "images").iterdir()))
    if status == 0:
        try:
            metrics = (
                score_package(scene, out)
                if cell.generator == "package"
                else score_shared(scene, out, args.shared_path)
            )
            row.update(summarise(metrics))
        except (OSError, RuntimeError, KeyError, ValueError) as exc:
            row.update({"exit": "score", "message": f"scoring failed: {exc}"})
    run_dir.mkdir(parents=True, exist_ok=True)
    row_path.write_text(json.dumps(row, indent=1))
    return row


def _pct(v: float | None) -> str:
    return "–" if v is None else f"{100 * v:.1f}"


def markdown(rows: Sequence[dict[str, Any]]) -> str:
    head = (
        "| generator | flight | ground (preset) | seed | images | exit | wires found "
        "| conductors complete % (min–max, weighted) | shields % | median cm "
        "| outliers > 30 cm % | ghosts | purity % | time s | × decode |"
    )
    lines = [head, "|" + "---|" * head.count(" | ") + "---|"]
    for r in rows:
        ground = r["ground"] + (f" ({r['preset']})" if r.get("preset") else "")
        ok = r["exit"] == 0
        message = r["message"] if len(r["message"]) <= 110 else r["message"][:109] + "…"
        exit_text = "0" if ok else f"{r['exit']}: {message}"
        if ok:
            cond = (
                f"{_pct(r['conductor_min'])}–{_pct(r['conductor_max'])}, "
                f"{_pct(r['conductor_weighted'])}"
            )
            cols = [
                f"{r['wires_found']}/{r['true_wires']}",
                cond,
                ", ".join(_pct(v) for v in r["shields"]) or "–",
                "–" if r["median_m"] is None else f"{100 * r['median_m']:.1f}",
                _pct(r["outlier_share"]),
                str(r["ghosts"]),
                _pct(r["purity"]),
            ]
        else:
            cols = ["–"] * 7
        if ok and r.get("spans_true"):
            cols[1] += (
                f"; spans {r['spans_found']}/{r['spans_true']}, each ≥ {_pct(r['span_min'])}"
                f" ({r['time_s'] / r['spans_true']:.0f} s per span); "
                f"supports {r['supports_right']}/{r['supports_true']} right "
                f"({r['supports_found']} found; worst {r['support_plan_max_m']:.2f} m in plan, "
                f"{r['support_height_max_m']:.2f} m in height)"
            )
        time_text = "–" if r.get("time_s") is None else f"{r['time_s']:.0f}"
        floor = r.get("decode_s")
        ratio = "–" if r.get("time_s") is None or not floor else f"{r['time_s'] / floor:.1f}"
        lines.append(
            f"| {r['generator']} | {r['flight']} | {ground} | {r['seed']} | "
            f"{r.get('images', '–')} | {exit_text} | "
            + " | ".join(cols)
            + f" | {time_text} | {ratio} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--generators", nargs="+", choices=GENERATORS, default=list(GENERATORS))
    parser.add_argument("--flights", nargs="+", choices=FLIGHTS, default=list(FLIGHTS))
    parser.add_argument(
        "--grounds",
        nargs="+",
        choices=[*GROUNDS, "soil"],
        default=list(GROUNDS),
        help="soil = bare_soil",
    )
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    parser.add_argument("--scale", type=float, default=0.5, help="image scale (default 0.5)")
    parser.add_argument(
        "--work_path",
        type=Path,
        default=Path("bench_work"),
        help="renders and results, cached (default %(default)s)",
    )
    parser.add_argument(
        "--shared_path",
        type=Path,
        default=Path("/work/shared/scenes"),
        help="folder of the shared generator (render_scene.py, score.py)",
    )
    parser.add_argument(
        "--timeout", type=float, default=1800.0, help="seconds per render and per reconstruction"
    )
    parser.add_argument("--rerun", action="store_true", help="run cached reconstructions again")
    parser.add_argument("--json", type=Path, help="write all rows to this file")
    args = parser.parse_args(argv)
    args.grounds = list(dict.fromkeys(SHARED_GROUNDS.get(g, g) for g in args.grounds))
    args.shared_path = args.shared_path.resolve()
    logging.basicConfig(level=logging.WARNING)

    cells = plan_cells(args)
    rows = []
    for k, cell in enumerate(cells):
        preset = f", preset {cell.preset}" if cell.preset else ""
        print(
            f"[{k + 1}/{len(cells)}] {cell.generator}: {cell.flight} × {cell.ground}{preset}, "
            f"seed {cell.seed}",
            flush=True,
        )
        row = run_cell(cell, args)
        rows.append(row)
        cached = " (cached)" if row.get("cached") else ""
        print(f"  exit {row['exit']}: {row['message']}{cached}", flush=True)
    print()
    print(markdown(rows))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
