"""The experiment registry: every paper and every experiment, by name.

Each paper is a package ``pipeline/experiments/<paper id>/`` whose ``PAPER``
(:class:`~pipeline.experiments.kit.model.Paper`) says what it needs and lists its experiments;
:data:`PAPER_PACKAGES` names them in report order. Experiment names follow
``<first author><year>-<what>`` (``volbench-...`` for our own studies).
"""

import importlib

import renderers

from core.errors import BackendUnavailableError, InputError
from pipeline.experiments.kit.model import PAPERS, Claim, ClaimResult, Experiment, Profile, Run

PAPER_PACKAGES = ("volbench", "lacroute1995", "kruger2003", "xue2005", "ropinski2005", "kainz2009")
"""The papers, in report order (ids of :data:`core.papers.PAPERS`)."""

__all__ = ["PAPERS", "Claim", "ClaimResult", "Experiment", "Profile", "Run", "all_experiments", "check_settings", "get",
           "papers", "plan", "selected"]


def papers():
    """``{paper id: Paper}`` in report order."""
    return {name: importlib.import_module(f"pipeline.experiments.{name}").PAPER for name in PAPER_PACKAGES}


def all_experiments():
    """``{name: Experiment instance}``: every paper's experiments, papers in report order."""
    return {cls.name: cls() for paper in papers().values() for cls in paper.experiments}


def get(name):
    registry = all_experiments()
    if name not in registry:
        raise InputError(f"unknown experiment {name!r}; known: {', '.join(registry)}")
    return registry[name]


def check_settings(profile, registry=None):
    """Raise :class:`InputError` for a profile setting no experiment reads (a typo).

    Every key of ``profile.settings`` must name a registered experiment, and every key under it
    one of that experiment's :attr:`~pipeline.experiments.kit.model.Experiment.settings`.
    """
    registry = all_experiments() if registry is None else registry
    for name, values in profile.settings.items():
        if name not in registry:
            raise InputError(f"profile {profile.name!r} settings: unknown experiment {name!r}; "
                             f"known: {', '.join(registry)}")
        if not isinstance(values, dict):
            raise InputError(f"profile {profile.name!r} settings.{name}: expected a mapping, got {values!r}")
        unknown = set(values) - set(registry[name].settings)
        if unknown:
            raise InputError(f"profile {profile.name!r} settings.{name}: unknown keys {sorted(unknown)}; "
                             f"allowed: {sorted(registry[name].settings)}")


def selected(profile):
    """The experiments a profile runs, in registry order (its settings checked first)."""
    registry = all_experiments()
    check_settings(profile, registry)
    if profile.experiments == "all":
        return list(registry.values())
    unknown = [name for name in profile.experiments if name not in registry]
    if unknown:
        raise InputError(f"profile {profile.name!r}: unknown experiments {unknown}; known: {', '.join(registry)}")
    return [registry[name] for name in registry if name in profile.experiments]


def plan(profile):
    """Every run of the profile, ``{"experiment/run": Run}``; checks references resolve."""
    runs = {}
    for experiment in selected(profile):
        for run in experiment.runs(profile):
            if run.key in runs:
                raise InputError(f"experiment {experiment.name}: duplicate run id {run.id!r}")
            runs[run.key] = run
    for run in runs.values():
        if run.reference is not None and f"{run.experiment}/{run.reference}" not in runs:
            raise InputError(f"run {run.key}: reference run {run.reference!r} is not planned")
    return runs


def stack_parts(members):
    """The runs of one interleave group as the parts its job times in processes of their own: one part per OpenGL
    stack its backends render through (:func:`graphics_stack`), in the order the group names them; the runs of no
    stack join the part of most runs, so that the most pairs alternate round by round.

    Two stacks' contexts in one process rendered every image of both empty (vtk-gpu beside a moderngl backend,
    measured on llvmpipe), so their frames cannot alternate round by round; the job alternates their processes
    instead (:func:`pipeline.jobs.render`), and their intervals pair runs by process only where they shared one
    (:func:`pipeline.experiments.kit.intervals.row_draws`). A group of one stack is one part.
    """
    parts = {}
    for run in members:
        parts.setdefault(graphics_stack(run.backend), []).append(run)
    stackless = parts.pop(None, [])
    if not parts:
        return [stackless]
    largest = max(parts, key=lambda stack: len(parts[stack]))
    parts[largest] = [run for run in members if run in stackless or run in parts[largest]]
    return list(parts.values())


def graphics_stack(backend):
    """The OpenGL stack ``backend`` renders through (:attr:`renderers.base.Renderer.graphics_stack`), or None."""
    try:
        return renderers.backend_class(backend).graphics_stack
    except BackendUnavailableError:  # not importable here: its runs are skipped, they render nothing
        return None
