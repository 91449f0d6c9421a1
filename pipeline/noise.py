"""Can machine noise flip a verdict? The same experiments run quiet, then beside a CPU hog, verdicts compared.

``scripts/noise-check`` (``python -m pipeline.noise``) runs ``volbench run`` twice on this machine, into
two results folders: first as it is, then with ``--hog`` processes spinning on the CPU (started before,
stopped after). A claim's verdict may become *inconclusive* under load (its interval widens, or it rests
on views the harness found disturbed: :func:`pipeline.experiments.kit.verdicts.rests_on_disturbed`), but
no claim may go from holds to fails or back: that is the harness's promise that noise does not decide
a verdict. The comparison is written to ``<prefix>-verdicts.csv``. Then (``--quiet-runs 2``, the default) a
second quiet run: its verdicts against the first quiet run's (``<prefix>-replication.csv``) say whether two
runs of volbench agree, with the share of claims, and of timing claims, whose verdict is the same.

Exit status: 1 when a claim flipped under load, 3 when only the two quiet runs disagree on a decided
verdict (a process-to-process spread that one run's intervals do not cover), 2 when a run did not finish.

    scripts/noise-check --profile default --paper lacroute1995 --paper kruger2003
    scripts/noise-check --profile smoke --experiment lacroute1995-volpack   (CI's version)
"""

import argparse
import contextlib
import multiprocessing
import os
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

from core.errors import InputError
from pipeline.compare import agreement_words, interval_agreement, interval_words, intervals_apart, verdict_changes
from pipeline.experiments.kit.verdicts import TIMED_KINDS

ROOT = Path(__file__).resolve().parent.parent


def _spin(stop):
    while not stop.is_set():
        for _ in range(100_000):
            pass


@contextlib.contextmanager
def cpu_hog(processes=1):
    """``processes`` busy processes for the duration of the ``with`` block (each takes one core)."""
    context = multiprocessing.get_context("spawn")
    stop = context.Event()
    hogs = [context.Process(target=_spin, args=(stop,), daemon=True, name=f"volbench cpu hog {i}")
            for i in range(processes)]
    for hog in hogs:
        hog.start()
    try:
        yield hogs
    finally:
        stop.set()
        for hog in hogs:
            hog.join(5)
            if hog.is_alive():
                hog.kill()


def flips(quiet, loaded):
    """The claims of two ``claims.csv`` tables compared: one row per claim, with ``change``.

    ``change`` is ``"same"``, ``"flipped"`` (holds ↔ fails: a failure of the harness), ``"inconclusive under
    load"``, ``"decided under load"`` (inconclusive quiet, holds or fails loaded: allowed, the loaded run
    took other frames) or ``"other"`` (blocked, not measured): :func:`pipeline.compare.verdict_changes`.
    """
    table = verdict_changes(quiet, loaded).rename(columns={
        "verdict_a": "verdict_quiet", "measured_a": "measured_quiet",
        "verdict_b": "verdict_loaded", "measured_b": "measured_loaded"})
    table["change"] = table.change.replace({"to inconclusive": "inconclusive under load",
                                            "from inconclusive": "decided under load"})
    return table


def _volbench_run(profile, selection, results, cores):
    command = [sys.executable, "-m", "pipeline.cli", "run", "--profile", profile, "--results", str(results),
               "--cores", str(cores), *[arg for name in selection for arg in ("--experiment", name)]]
    print("noise-check:", " ".join(command), flush=True)
    return subprocess.run(command, cwd=ROOT).returncode


def experiments_of(papers, names, profile):
    """The experiment names to run: ``names`` and every experiment of ``papers`` the profile selects."""
    from pipeline.experiments import Profile, selected
    from pipeline.launch import _profile_file

    chosen = list(names)
    if papers:
        known = selected(Profile.load(_profile_file(profile)))
        for paper in papers:
            found = [e.name for e in known if e.paper == paper]
            if not found:
                raise InputError(f"--paper {paper!r}: no experiment of that paper in profile {profile!r}; "
                                 f"papers: {', '.join(sorted({e.paper for e in known}))}")
            chosen += found
    if not chosen:
        raise InputError("name what to run: --paper P or --experiment E (repeatable)")
    return list(dict.fromkeys(chosen))


def main(argv=None):
    parser = argparse.ArgumentParser(prog="scripts/noise-check", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--profile", default="default", help="profile name or YAML file (default: default)")
    parser.add_argument("--paper", action="append", default=[], help="run every experiment of this paper")
    parser.add_argument("--experiment", action="append", default=[], help="run this experiment")
    parser.add_argument("--hog", type=int, default=1, help="busy processes during the loaded run (default 1)")
    parser.add_argument("--cores", type=int, default=os.cpu_count() or 1, help="cores for Snakemake")
    parser.add_argument("--prefix", default="results/noise",
                        help="results folders <prefix>-quiet, <prefix>-loaded, <prefix>-quiet-again")
    parser.add_argument("--quiet-runs", type=int, choices=(1, 2), default=2,
                        help="2 (default): a second quiet run after the loaded one, its verdicts compared with the "
                             "first's (do two quiet runs agree?)")
    args = parser.parse_args(argv)
    if args.hog < 1:
        parser.error(f"--hog {args.hog}: at least one busy process (the loaded run needs a load)")
    selection = experiments_of(args.paper, args.experiment, args.profile)
    prefix = ROOT / args.prefix if not Path(args.prefix).is_absolute() else Path(args.prefix)
    quiet, loaded, again = (Path(f"{prefix}-{name}") for name in ("quiet", "loaded", "quiet-again"))
    started = time.monotonic()
    if _volbench_run(args.profile, selection, quiet, args.cores):
        print("noise-check: the quiet run did not finish", file=sys.stderr)
        return 2
    with cpu_hog(args.hog):
        status = _volbench_run(args.profile, selection, loaded, args.cores)
    if status:
        print("noise-check: the loaded run did not finish", file=sys.stderr)
        return 2
    if args.quiet_runs == 2 and _volbench_run(args.profile, selection, again, args.cores):
        print("noise-check: the second quiet run did not finish", file=sys.stderr)
        return 2
    claims = {folder: pd.read_csv(folder / "claims.csv") for folder in (quiet, loaded, again) if folder.exists()}
    table = flips(claims[quiet], claims[loaded])
    table = table[table.experiment.isin(selection)]
    out = Path(f"{prefix}-verdicts.csv")
    table.to_csv(out, index=False)
    counts = table.change.value_counts().to_dict()
    print(f"noise-check: {len(table)} claims of {len(selection)} experiments, quiet then beside {args.hog} busy "
          f"process{'es' if args.hog != 1 else ''}, in {time.monotonic() - started:.0f} s: "
          + ", ".join(f"{n} {change}" for change, n in sorted(counts.items())) + f" ({out})")
    for _, row in table[table.change != "same"].iterrows():
        print(f"  {row.experiment} {row.claim}: {row.verdict_quiet} ({row.measured_quiet}) → "
              f"{row.verdict_loaded} ({row.measured_loaded}) [{row.change}]")
    replicated = args.quiet_runs == 1 or _replication(claims[quiet], claims[again], selection,
                                                      Path(f"{prefix}-replication.csv"))
    if counts.get("flipped"):
        return 1
    return 0 if replicated else 3


def _replication(first, second, selection, out):
    """Print how the two quiet runs' verdicts agree (written to ``out``); ``False`` when one flipped."""
    table = verdict_changes(first, second)
    table = table[table.experiment.isin(selection)]
    table.to_csv(out, index=False)
    kinds = first.set_index(["experiment", "claim"]).get("kind", pd.Series(dtype=str))
    timing = {key for key, kind in kinds.items() if kind in TIMED_KINDS}
    print(f"noise-check: two quiet runs: {agreement_words(table, timing=timing)} ({out})")
    for row in table[table.change != "same"].itertuples():
        print(f"  {row.experiment} {row.claim}: {row.verdict_a} ({row.measured_a}) → {row.verdict_b} "
              f"({row.measured_b}) [{row.change}]")
    agreement = interval_agreement(first[first.experiment.isin(selection)], second, timing=timing)
    if not agreement.empty:
        print(f"noise-check: two quiet runs' intervals: {interval_words(agreement)}")
        for line in intervals_apart(agreement, "the first", "the second"):
            print(f"  {line}")
    return not (table.change == "flipped").any()


if __name__ == "__main__":
    sys.exit(main())
