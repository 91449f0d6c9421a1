"""The experiment registry: every experiment of every paper, by name.

Names follow ``<first author><year>-<what>`` (``volbench-...`` for our own studies). Each paper's
module adds its experiments to :data:`MODULES`.
"""

import importlib

from core.errors import InputError
from pipeline.experiments.base import PAPERS, Claim, ClaimResult, Experiment, Profile, Run

MODULES = ("pipeline.experiments.volbench",)

__all__ = ["PAPERS", "Claim", "ClaimResult", "Experiment", "Profile", "Run", "all_experiments", "get", "plan"]


def all_experiments():
    """``{name: Experiment instance}`` in registry order."""
    registry = {}
    for module_name in MODULES:
        for cls in importlib.import_module(module_name).EXPERIMENTS:
            registry[cls.name] = cls()
    return registry


def get(name):
    registry = all_experiments()
    if name not in registry:
        raise InputError(f"unknown experiment {name!r}; known: {', '.join(registry)}")
    return registry[name]


def selected(profile):
    """The experiments a profile runs, in registry order."""
    registry = all_experiments()
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
