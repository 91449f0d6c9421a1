"""The ``volbench`` command line: list, render, compare, run.

Examples
--------
::

    volbench list
    volbench render ct_skull --preset bone --size 128 --output skull.png --exr skull.exr
    volbench render scene.yaml --backend reference --option step_factor=0.5
    volbench compare reference.exr test.exr --diff diff.png
    volbench run --profile default            # the whole pipeline, through Snakemake
    volbench run --experiment volbench-convergence --dry-run
    volbench run --profile full --cores 32 -- --workflow-profile config/profiles/slurm   # a SLURM cluster
"""

import argparse
import json
import sys
from pathlib import Path

from core.errors import VolbenchError



def _parse_options(pairs):
    """``["step_factor=0.5", "ert=true"]`` → ``{"step_factor": 0.5, "ert": True}`` (YAML scalars, read strictly).

    An option given twice is an error, not the last one silently winning.
    """
    from core.yaml_io import parse_yaml

    options = {}
    for pair in pairs or ():
        name, _, value = pair.partition("=")
        if not name or "=" not in pair:
            raise VolbenchError(f"--option {pair!r}: expected NAME=VALUE")
        if name in options:
            raise VolbenchError(f"--option {name}: given twice ({name}={options[name]!r} and {pair!r}); keep one")
        options[name] = parse_yaml(value, what=f"--option {pair!r}")
    return options


def cmd_list(args):
    import datasets
    import renderers
    from pipeline import experiments

    if args.what in ("all", "backends"):
        print("backends:")
        for info in renderers.available():
            status = "available" if info.available else f"unavailable: {info.reason}"
            print(f"  {info.name:16s} {status}")
            if info.description:
                print(f"  {'':16s} {info.description}")
    if args.what in ("all", "datasets"):
        print("datasets:")
        for name in datasets.names():
            spec = datasets.get(name)
            print(f"  {name:16s} {spec.kind:8s} presets: {', '.join(spec.presets)} (default {spec.default_preset})")
    if args.what in ("all", "experiments"):
        print("experiments:")
        for name, experiment in experiments.all_experiments().items():
            print(f"  {name:28s} {experiment.title}")


SCENE_FILE_FLAGS = {"image": "width/height", "mode": "mode", "shading": "shading: {model: ...}",
                    "preset": "preset (per volume)"}
"""Flags that describe a scene built from a data-set name; a scene file sets these itself."""

DATASET_DEFAULTS = {"image": 256, "mode": "dvr", "shading": "phong"}


def _check_output_paths(args):
    """Refuse output files that cannot be written before any work starts (not after minutes of rendering)."""
    from reports.imageio import check_output_path

    for flag, path, suffix in (("--output", args.output, ".png"), ("--exr", args.exr, ".exr")):
        if path is None:
            continue
        if Path(path).suffix.lower() != suffix:
            raise VolbenchError(f"{flag} {path}: expected a {suffix} file name")
        check_output_path(path, name=f"{flag} {path}")


def _scene_from_args(args):
    from pipeline.scene_io import build_scene, load_scene

    camera = {k: v for k, v in (("azimuth", args.azimuth), ("elevation", args.elevation),
                                  ("projection", args.projection)) if v is not None}
    if args.scene.endswith((".yaml", ".yml")):
        # A scene file is the whole description: flags it would ignore are errors, not no-ops.
        given = [flag for flag in SCENE_FILE_FLAGS if getattr(args, flag) is not None]
        if given:
            raise VolbenchError(
                f"{args.scene}: {', '.join('--' + flag for flag in given)} "
                f"{'does' if len(given) == 1 else 'do'} not apply to a scene file; set "
                f"{', '.join(SCENE_FILE_FLAGS[flag] for flag in given)} in the YAML instead")
        scene = load_scene(args.scene, size=args.size)
        return scene.with_camera(**camera) if camera else scene
    options = {flag: default if getattr(args, flag) is None else getattr(args, flag)
               for flag, default in DATASET_DEFAULTS.items()}
    volume = {"dataset": args.scene}
    if args.preset:
        volume["preset"] = args.preset
    if args.size:
        volume["size"] = args.size
    spec = {"name": args.scene, "width": options["image"], "height": options["image"], "mode": options["mode"],
            "shading": {"model": options["shading"]}, "camera": {"azimuth": 30.0, "elevation": 20.0, **camera},
            "volumes": [volume]}
    return build_scene(spec, size=args.size)


def cmd_render(args):
    import renderers
    from pipeline.timing import measure
    from reports.imageio import write_images

    _check_output_paths(args)
    options = _parse_options(args.option)
    scene = _scene_from_args(args)
    with renderers.get(args.backend, **options) as renderer:
        # The backend's limits (its memory, its work) before the progress bar and the warm-up frames.
        renderer.check(scene)
        result = measure(renderer, scene, warmup=args.warmup, repeat=args.repeat, progress=True)
    write_images(result.image, [args.output, args.exr])
    print(f"wrote {args.output}" + (f" and {args.exr}" if args.exr else ""))
    for stage, seconds in result.timings.items():
        # The cold frame and preprocessing are timed once; the frames' stages have extremes.
        spread = (f"(min {result.timings_min[stage]:.4f}, max {result.timings_max[stage]:.4f})"
                  if stage in result.timings_min else "(once)")
        print(f"  time {stage:12s} {seconds:10.4f} s {spread}")
    for name, value in result.counters.items():
        print(f"  count {name:11s} {value}")


def cmd_compare(args):
    import warnings

    from reports.imageio import check_output_path
    from reports.metrics import compare_files

    if args.diff is not None:
        if Path(args.diff).suffix.lower() not in (".png", ".exr"):
            raise VolbenchError(f"--diff {args.diff}: expected a .png or .exr file name")
        check_output_path(args.diff, name=f"--diff {args.diff}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        values = compare_files(args.reference, args.test, diff_path=args.diff)
    for warning in caught:
        print(f"volbench: warning: {warning.message}", file=sys.stderr)
    print(json.dumps(values, indent=1, default=str))


def cmd_run(args):
    from pipeline.launch import run

    return run(args)


def build_parser():
    parser = argparse.ArgumentParser(prog="volbench", description="Volume-rendering reproducibility suite and benchmark harness.")
    commands = parser.add_subparsers(dest="command", required=True)

    p = commands.add_parser("list", help="backends (with availability), data sets, experiments")
    p.add_argument("what", nargs="?", default="all", choices=("all", "backends", "datasets", "experiments"))
    p.set_defaults(func=cmd_list)

    p = commands.add_parser("render", help="render one data set or scene file with one backend")
    p.add_argument("scene", help="a data set name (volbench list datasets) or a scene YAML file")
    p.add_argument("--backend", default="reference")
    p.add_argument("--option", action="append", metavar="NAME=VALUE", help="backend option (repeatable)")
    p.add_argument("--preset", help="classification preset of the data set (not for scene files)")
    p.add_argument("--size", type=int, help="phantom size (voxels along the longest axis); a scene file's "
                   "phantoms without their own size use it; real scans refuse it")
    p.add_argument("--image", type=int, help="image width and height (default 256; not for scene files)")
    p.add_argument("--mode", choices=("dvr", "mip", "iso"), help="default dvr (not for scene files)")
    p.add_argument("--shading", choices=("none", "phong"), help="default phong (not for scene files)")
    p.add_argument("--projection", choices=("orthographic", "perspective"))
    p.add_argument("--azimuth", type=float)
    p.add_argument("--elevation", type=float)
    p.add_argument("--warmup", type=int, default=1)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--output", default="render.png", help="PNG for people (must end in .png)")
    p.add_argument("--exr", help="also write the exact float image (must end in .exr)")
    p.set_defaults(func=cmd_render)

    p = commands.add_parser("compare", help="metrics and a difference image for two images")
    p.add_argument("reference")
    p.add_argument("test")
    p.add_argument("--diff", help="write the contrast-enhanced difference image here")
    p.set_defaults(func=cmd_compare)

    p = commands.add_parser("run", help="run experiments through Snakemake")
    p.add_argument("--profile", default="default", help="smoke, default, full, or a YAML path")
    p.add_argument("--experiment", action="append", help="only this experiment (repeatable)")
    p.add_argument("--cores", type=int, default=2, help="cores of this machine; on a cluster (a workflow "
                   "profile or --executor after '--'), the cores each render job takes on its node")
    p.add_argument("--results", help="output folder instead of the profile's `results` (relative to the project)")
    p.add_argument("--cache", help="phantom cache folder instead of the profile's `cache`")
    p.add_argument("--dry-run", "-n", action="store_true")
    p.add_argument("snakemake_args", nargs="*", help="passed to snakemake after '--' "
                   "(e.g. --workflow-profile config/profiles/slurm)")
    p.set_defaults(func=cmd_run)
    return parser


def main(argv=None):
    args = build_parser().parse_args(argv)
    try:
        return args.func(args) or 0
    except VolbenchError as exc:
        print(f"volbench: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        # Ctrl-C is the user's choice, not a fault: no traceback; 130 = 128 + SIGINT, as a shell reports it.
        print("volbench: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
