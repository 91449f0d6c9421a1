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
import subprocess
import sys
from pathlib import Path

import yaml

from core.errors import VolbenchError

ROOT = Path(__file__).resolve().parent.parent


def _parse_options(pairs):
    """``["step_factor=0.5", "ert=true"]`` → ``{"step_factor": 0.5, "ert": True}`` (YAML scalars)."""
    options = {}
    for pair in pairs or ():
        if "=" not in pair:
            raise VolbenchError(f"--option {pair!r}: expected NAME=VALUE")
        name, value = pair.split("=", 1)
        try:
            options[name] = yaml.safe_load(value)
        except yaml.YAMLError as exc:
            raise VolbenchError(f"--option {pair!r}: cannot parse the value ({exc})") from None
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
    """Refuse bad output file names before any work starts (not after minutes of rendering)."""
    for flag, path, suffix in (("--output", args.output, ".png"), ("--exr", args.exr, ".exr")):
        if path is None:
            continue
        if Path(path).suffix.lower() != suffix:
            raise VolbenchError(f"{flag} {path}: expected a {suffix} file name")
        parent = Path(path).parent
        if not parent.is_dir():
            raise VolbenchError(f"{flag} {path}: folder {parent} does not exist")


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
    from reports.imageio import write_exr, write_png

    _check_output_paths(args)
    scene = _scene_from_args(args)
    with renderers.get(args.backend, **_parse_options(args.option)) as renderer:
        result = measure(renderer, scene, warmup=args.warmup, repeat=args.repeat, progress=True)
    write_png(args.output, result.image)
    if args.exr:
        write_exr(args.exr, result.image)
    print(f"wrote {args.output}" + (f" and {args.exr}" if args.exr else ""))
    for stage, seconds in result.timings.items():
        print(f"  time {stage:12s} {seconds:10.4f} s (min {result.timings_min[stage]:.4f}, max {result.timings_max[stage]:.4f})")
    for name, value in result.counters.items():
        print(f"  count {name:11s} {value}")


def cmd_compare(args):
    from reports.metrics import compare_files

    if args.diff is not None and Path(args.diff).suffix.lower() not in (".png", ".exr"):
        raise VolbenchError(f"--diff {args.diff}: expected a .png or .exr file name")
    values = compare_files(args.reference, args.test, diff_path=args.diff)
    print(json.dumps(values, indent=1, default=str))


PACKAGES = ("core", "datasets", "renderers", "reports", "pipeline")
"""The project's packages: every job of the workflow imports some of them."""


def compile_packages():
    """Write the bytecode of :data:`PACKAGES` where it is missing or stale.

    Every Snakemake job is a fresh interpreter that imports these modules; where Python may not
    write bytecode itself (``PYTHONDONTWRITEBYTECODE``, a read-only checkout) each job would compile
    them again, about 0.2 s a job.
    """
    import compileall

    for package in PACKAGES:
        compileall.compile_dir(ROOT / package, quiet=1)


def cmd_run(args):
    profile = Path(args.profile)
    if not profile.suffix:
        profile = ROOT / "config" / f"{args.profile}.yaml"
    if not profile.exists():
        raise VolbenchError(f"profile {args.profile!r}: no file {profile}; see config/ for the profiles")
    compile_packages()
    command = [sys.executable, "-m", "snakemake", "--snakefile", str(ROOT / "Snakefile"),
               "--directory", str(ROOT), "--configfile", str(profile.resolve()),
               "--cores", str(args.cores), "--rerun-incomplete",
               # The greedy scheduler: the default (an integer program solved after every job) only
               # pays where temporary files must be deleted early, and this workflow has none; with
               # hundreds of small jobs its solves take CPU from the timed render beside it.
               "--scheduler", "greedy",
               # A rate limit that never binds, checked every 10 s. Under the default (100/1s),
               # Snakemake 9 ends every scheduler pass that leaves jobs waiting by starting a timer
               # for another pass a timespan later, and every finished job adds a pass, so these
               # timers multiply: with render jobs waiting for the cores all run long, the smoke
               # profile's main Snakemake made ~100 passes a second by its end (64 000 timer threads)
               # and took half a core from the renders. Ten seconds make a tenth of the passes; the
               # timers are not daemon threads, so Snakemake exits up to one timespan after its last
               # job (a day's timespan kept it alive for a day).
               "--max-jobs-per-timespan", "1000000/10s"]
    if args.dry_run:
        command.append("--dry-run")
    extra = list(args.snakemake_args)
    items = [f"experiments={json.dumps(args.experiment)}"] if args.experiment else []
    items += [f"{key}={value}" for key, value in (("results", args.results), ("cache", args.cache)) if value]
    if items:
        # Snakemake keeps only the last --config, so ours joins the user's when there is one.
        if "--config" in extra:
            at = extra.index("--config") + 1
            extra[at:at] = items
        else:
            extra += ["--config", *items]
    command += extra
    print("volbench:", " ".join(command), flush=True)
    completed = subprocess.run(command)
    if completed.returncode == 0 and not args.dry_run:
        results = args.results or yaml.safe_load(profile.read_text()).get("results", "results")
        print(f"volbench: report at {(ROOT / results / 'report' / 'index.html')}")
    return completed.returncode


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


if __name__ == "__main__":
    sys.exit(main())
