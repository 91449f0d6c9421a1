"""The backend registry: string names → renderer classes, imported only when asked for.

Like vispy's backend table, each entry is ``"module:Class"``; importing ``renderers`` imports
no backend, and a backend whose optional dependency is missing is reported by
:func:`available` instead of breaking the others.

>>> import renderers
>>> backend = renderers.get("reference", step_factor=0.25)   # doctest: +SKIP
>>> result = backend.render(scene)                            # doctest: +SKIP
"""

import importlib
import inspect
from dataclasses import dataclass

from core.errors import BackendUnavailableError, InputError

BACKENDS = {
    "reference": "renderers.reference:ReferenceRenderer",
    "shearwarp": "renderers.shearwarp.renderer:ShearWarpRenderer",
    "volpack": "renderers.volpack.renderer:VolPackRenderer",
    "vtk-gpu": "renderers.vtk.gpu:VtkGpuRenderer",
    "vtk-cpu": "renderers.vtk.cpu:VtkCpuRenderer",
    "gl-raycast": "renderers.gl.raycast:GLRaycastRenderer",
    "gl-slicer": "renderers.gl.slicer:GLSlicerRenderer",
    "gl-isbvr": "renderers.gl.isbvr:GLIsbvrRenderer",
    "cl-tiled": "renderers.cl.tiled:ClTiledRenderer",
    "gl-peel": "renderers.gl.peeling:GLPeelRenderer",
}


@dataclass(frozen=True)
class BackendInfo:
    """One row of :func:`available`."""

    name: str
    available: bool
    reason: str
    description: str
    capabilities: object | None


def names():
    """Registered backend names, in registry order."""
    return list(BACKENDS)


def backend_class(name):
    """Import and return the class registered as ``name``."""
    if name not in BACKENDS:
        raise InputError(f"unknown backend {name!r}; registered backends: {', '.join(BACKENDS)}")
    module_name, class_name = BACKENDS[name].split(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise BackendUnavailableError(f"backend {name!r} cannot be imported: {exc}") from exc
    return getattr(module, class_name)


def backend_module(name):
    """Dotted module path implementing ``name`` (the pipeline tracks its files for reruns)."""
    if name not in BACKENDS:
        raise InputError(f"unknown backend {name!r}; registered backends: {', '.join(BACKENDS)}")
    return BACKENDS[name].split(":")[0]


def get(name, **options):
    """Instantiate backend ``name`` with keyword ``options``.

    Raises
    ------
    InputError
        Unknown name or bad option.
    BackendUnavailableError
        The backend cannot run here (the message says why).
    """
    cls = backend_class(name)
    check_options(name, cls, options)
    ok, reason = cls.probe()
    if not ok:
        raise BackendUnavailableError(f"backend {name!r} is not available here: {reason}")
    return cls(**options)


def option_names(cls):
    """The keyword options a backend class's constructor takes (``None``: it accepts any).

    Read from the signature, which a backend's ``option_table`` declares, in the table's order.
    """
    parameters = list(inspect.signature(cls).parameters.values())
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters):
        return None
    return [p.name for p in parameters if p.kind in (inspect.Parameter.KEYWORD_ONLY,
                                                     inspect.Parameter.POSITIONAL_OR_KEYWORD)]


def check_options(name, cls, options):
    """Raise :class:`InputError` for an option the backend does not take, listing the valid ones.

    Checked against the constructor's signature (a backend's ``option_table``) before the backend
    is built, so a typo (``stepfactor``) is a clear error, the same one the constructor gives.
    """
    from renderers.base.options import check_known  # here, so that importing the registry stays light

    valid = option_names(cls)
    if valid is not None:
        check_known(name, options, valid)


def available():
    """Every registered backend with whether it can run here and, if not, why."""
    rows = []
    for name in BACKENDS:
        try:
            cls = backend_class(name)
        except BackendUnavailableError as exc:
            rows.append(BackendInfo(name, False, str(exc), "", None))
            continue
        ok, reason = cls.probe()
        rows.append(BackendInfo(name, ok, reason, cls.description, cls.capabilities))
    return rows
