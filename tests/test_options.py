"""Backend options declared once (renderers.base.options): every backend's table agrees with its
signature, docs, validation and ``options`` record; the records are those of the code before the
tables (so runs.csv's ``option_*`` columns do not change); the shared world step."""

import inspect
import re

import numpy as np
import pytest
import trimesh

import renderers
from core.camera import Camera
from core.errors import BackendUnavailableError, InputError
from core.mesh import Mesh, MeshInstance, SurfaceMaterial
from core.scene import Scene, VolumeInstance
from core.transfer import TransferFunction
from core.volume import Volume
from renderers.base import Capabilities, Option, RenderResult, Renderer, world_step
from renderers.base.interface import GEOMETRY_FEATURES
from renderers.base.options import document

NUMBA_THREADS, VTK_THREADS = object(), object()
"""Stand-ins for the machine's thread counts, which shearwarp's ``workers`` and vtk-cpu's
``effective_threads`` record."""

EXPECTED_OPTIONS = {
    # backend: (options with defaults, then what each quality_sweep entry changes in them), generated
    # from the constructors before the option tables (HEAD 1b800a1), values and types as recorded.
    "reference": ({"step_factor": 0.25, "step": None, "classification": "post", "depth": False,
                   "max_samples": 100000000000.0, "effective_step": None},
                  [{"step_factor": 1.0}, {"step_factor": 0.5}, {}, {"step_factor": 0.125}]),
    "shearwarp": ({"rle": True, "early_termination": True, "opaque_threshold": 0.95, "min_opacity": 0.05,
                   "opacity_correction": True, "shading": "lut", "workers": NUMBA_THREADS,
                   "schedule": "round-robin-steal", "task_size": 8, "union": "path-compression",
                   "classification": "rle", "octree_rle_build": False, "octree_threshold": 4, "octree_base_size": 4},
                  [{}, {"early_termination": False}, {"rle": False, "early_termination": False},
                   {"opaque_threshold": 0.99}, {"opaque_threshold": 0.999, "min_opacity": 0.0}]),
    "volpack": ({"mode": "rle", "opaque_threshold": 0.95, "min_opacity": 0.05, "octree_base_node_size": 4,
                 "octree_threshold": 4},
                [{}, {"opaque_threshold": 0.99, "min_opacity": 0.01}, {"opaque_threshold": 1.0, "min_opacity": 0.0}]),
    "vtk-gpu": ({"step_factor": 0.25, "early_termination": True, "depth_pass": False, "lens_method": "label-map",
                 "effective_step": None},
                [{"step_factor": 1.0}, {"step_factor": 0.5}, {}]),
    "vtk-cpu": ({"step_factor": 0.25, "threads": None, "readback": "raycast", "effective_step": None,
                 "effective_threads": VTK_THREADS},
                [{"step_factor": 1.0}, {"step_factor": 0.5}, {}]),
    "gl-raycast": ({"variant": "rc-b", "step_factor": 0.5, "samples_per_pass": 8, "opaque_threshold": 0.95,
                    "block_size": 8, "min_opacity": 0.0, "iso_hit": "exact", "iso_refine": 6, "occluder": 0.0,
                    "lens_method": "segments", "region_order": "back-to-front", "timing": "auto",
                    "effective_step": None, "effective_timing": None},
                   [{"step_factor": 1.0}, {}, {"step_factor": 0.25}, {"opaque_threshold": 0.8},
                    {"opaque_threshold": 1.0}, {"samples_per_pass": 2}, {"samples_per_pass": 32}, {"block_size": 16},
                    {"iso_hit": "sampled", "step_factor": 1.0}, {"iso_hit": "sampled"},
                    {"iso_hit": "sampled", "step_factor": 0.25}, {"iso_hit": "sampled", "iso_refine": 0}]),
    "gl-slicer": ({"step_factor": 0.5, "order": "back-to-front", "count_contributing": True, "timing": "auto",
                   "effective_step": None, "effective_timing": None},
                  [{"step_factor": 1.0}, {}, {"step_factor": 0.25}]),
    "gl-isbvr": ({"step_factor": 1.0, "order": "back-to-front", "zinit": "ess+ert", "surfaces": "reduced",
                  "phi_t_node": 8, "phi_p_node": 2, "depth_offset": 1.0, "shader": "volume", "extra_taps": 0,
                  "opaque_threshold": 0.99, "count_fragments": True, "timing": "auto", "effective_step": None, "effective_timing": None},
                 [{}, {"step_factor": 0.5}, {"step_factor": 0.25}]),
    "cl-tiled": ({"step_factor": 0.5, "depth_cap": 63, "fragments": "local", "opaque_threshold": 0.99,
                  "empty_space": "hull", "brick_size": 8, "min_opacity": 0.0, "triangle_order": "scene",
                  "media": "analytic", "coverage": "bitmask", "stop_after": "composite", "device": None,
                  "effective_step": None},
                 [{"step_factor": 1.0}, {}, {"step_factor": 0.25}]),
    "gl-peel": ({"step_factor": 0.5, "opaque_threshold": 0.99, "max_layers": 256, "peeling": "front",
                 "timing": "auto", "effective_step": None, "effective_timing": None},
                [{"step_factor": 1.0}, {}, {"step_factor": 0.25}, {"opaque_threshold": 1.0}]),
}


def backend(name, **options):
    """``renderers.get(name, **options)``, or a skip where the backend cannot run here."""
    try:
        return renderers.get(name, **options)
    except BackendUnavailableError as exc:
        pytest.skip(str(exc))


def importable(name):
    """The backend's class, or a skip where its module cannot be imported here."""
    try:
        return renderers.backend_class(name)
    except BackendUnavailableError as exc:
        pytest.skip(str(exc))


def machine_values(name):
    """The values the stand-ins take on this machine."""
    if name == "shearwarp":
        import numba

        return {NUMBA_THREADS: numba.config.NUMBA_NUM_THREADS}
    if name == "vtk-cpu":
        from renderers.vtk import common

        return {VTK_THREADS: common.vtk_modules().vtkMultiThreader.GetGlobalDefaultNumberOfThreads()}
    return {}


def typed(options):
    """``[(key, type, value)]``: the record's order, and 4 and 4.0 told apart (runs.csv prints them apart)."""
    return [(key, type(value).__name__, value) for key, value in options.items()]


def test_every_registered_backend_has_an_expectation():
    assert sorted(EXPECTED_OPTIONS) == sorted(renderers.names())


@pytest.mark.parametrize("name", sorted(EXPECTED_OPTIONS))
def test_options_records_are_those_before_the_tables(name):
    defaults, sweep_changes = EXPECTED_OPTIONS[name]
    here = machine_values(name)
    defaults = {key: here.get(value, value) for key, value in defaults.items()}
    cls = importable(name)
    assert len(cls.quality_sweep) == len(sweep_changes)
    for options, changes in zip(({}, *cls.quality_sweep), ({}, *sweep_changes)):
        with backend(name, **options) as renderer:
            assert typed(renderer.options) == typed({**defaults, **changes}), options


# -- every backend's table agrees with its signature, docs, validation and record --------------------

def parameters_section(docstring):
    """``{name: entry text}`` of the numpydoc Parameters section of ``docstring``."""
    match = re.search(r"^Parameters\n-+\n(.*?)(?=^\S[^\n]*\n-+\n|\Z)", inspect.cleandoc(docstring), re.S | re.M)
    assert match, "no Parameters section"
    entries = re.split(r"^(?=\S)", match.group(1), flags=re.M)
    return {entry.split(" : ")[0]: entry.strip() for entry in entries if entry.strip()}


def bad_values(option):
    """Values outside the option's declared type, range or choices."""
    if option.type is bool:
        return ["yes", 1]
    if option.choices:
        return ["no-such-choice", 1]
    if option.type is str:
        return [5]
    values = ["many"]
    if option.low is not None:
        values.append(option.low if option.low_open else option.low - 1)
    if option.high is not None:
        values.append(option.high if option.high_open else option.high + 1)
    if option.type is int:
        values.append(option.low + 0.5)
    return values


@pytest.mark.parametrize("name", renderers.names())
def test_declared_options_signature_docs_validation_and_record_agree(name):
    cls = importable(name)
    table = cls.option_table
    names = [option.name for option in table]
    assert names and len(set(names)) == len(names)

    parameters = inspect.signature(cls).parameters.values()
    assert [(p.name, p.kind, p.default) for p in parameters] == [
        (option.name, inspect.Parameter.KEYWORD_ONLY, option.default) for option in table]
    assert renderers.option_names(cls) == names

    documented = parameters_section(cls.__doc__)
    assert list(documented) == names
    for option in table:
        assert documented[option.name] == option.numpydoc()
        for value in bad_values(option):
            with pytest.raises(InputError, match=rf"^{re.escape(name)} option {option.name}: "):
                cls(**{option.name: value})

    with pytest.raises(InputError, match=rf"unknown option no_such_option; valid options: {', '.join(names)}$"):
        renderers.get(name, no_such_option=1)
    with backend(name) as renderer:
        recorded = [option for option in table if option.recorded]
        assert list(renderer.options)[:len(recorded)] == [option.name for option in recorded]
        for option in recorded:
            assert renderer.options[option.name] == getattr(renderer, option.holder)
        assert all(key.startswith("effective_") for key in list(renderer.options)[len(recorded):])


ALL_OF = {"projections": {"orthographic", "perspective"}, "modes": {"dvr", "mip", "iso"},
          "shading": {"none", "phong"}}


def unsupported(capabilities):
    """The features a backend lacks (or has only in part), which its ``reasons`` must explain."""
    for feature, value in capabilities.as_dict().items():
        if feature in ALL_OF:
            lacking = set(value) != ALL_OF[feature]
        elif feature == "max_volumes":
            lacking = value == 1
        else:  # an eye inside a volume has a general reason (Capabilities.missing)
            lacking = value is False and feature != "camera_inside_volume"
        if lacking:
            yield feature


@pytest.mark.parametrize("name", renderers.names())
def test_capabilities_give_every_unsupported_feature_a_reason(name):
    capabilities = importable(name).capabilities
    for feature in unsupported(capabilities):
        # A backend without meshes lacks what builds on them for the meshes' reason.
        explained_by = "meshes" if feature in GEOMETRY_FEATURES and not capabilities.meshes else feature
        assert capabilities.reasons.get(explained_by), feature


# -- the machinery, on a backend of its own -----------------------------------------------------------

class Toy(Renderer):
    """A backend for the option machinery.

    Notes
    -----
    Renders nothing.
    """

    name = "toy"
    capabilities = Capabilities()
    option_table = (
        Option("level", int, 2, "How much.", low=1, high=9),
        Option("mode", str, "a", "Which way.", choices=("a", "b")),
        Option("trace", bool, False, "Kept out of the record.", recorded=False),
        Option("render", float, 0.5, "Held where a method cannot shadow it.", low=0, high=1, high_open=True,
               attribute="render_fraction"),
    )

    def _render(self, scene):
        return RenderResult(np.zeros((1, 1, 4), np.float32), {"total": 0.0})


def test_the_table_makes_constructor_attributes_record_and_docs():
    toy = Toy(level=3, trace=True)
    assert (toy.level, toy.mode, toy.trace, toy.render_fraction) == (3, "a", True, 0.5)
    assert toy.options == {"level": 3, "mode": "a", "render": 0.5}
    assert str(inspect.signature(Toy)) == "(*, level=2, mode='a', trace=False, render=0.5)"
    doc = Toy.__doc__
    section = doc.index("Parameters\n----------\nlevel : int, optional\n")
    assert doc.index("A backend for") < section < doc.index("Notes")
    assert "mode : {\"a\", \"b\"}, optional\n    Which way. Default ``'a'``." in doc
    assert "level : int, optional\n    How much. Range 1 to 9. Default ``2``." in doc
    assert "Range [0, 1). Default ``0.5``." in doc
    with pytest.raises(InputError, match=r"^toy option level: expected an integer from 1 to 9, got 10$"):
        Toy(level=10)
    with pytest.raises(InputError, match=r"^backend 'toy': unknown options lvl, tracing; valid options: level, mode, "
                                         r"trace, render$"):
        Toy(lvl=1, tracing=True)


def test_a_sweep_setting_of_another_modes_option_is_left_out_of_that_modes_sweep():
    class Swept(Toy):
        option_table = (*Toy.option_table, Option("iso_only", int, 0, "Iso-surfaces only.", low=0,
                                                  modes=frozenset({"iso"})))
        quality_sweep = ({"level": 1}, {"level": 1, "iso_only": 2}, {"iso_only": 3})

    assert Swept.quality_sweep_for("dvr") == ({"level": 1},)
    assert Swept.quality_sweep_for("iso") == Swept.quality_sweep
    assert Toy.quality_sweep_for("mip") == ({},)


def test_a_docstring_without_sections_gets_the_parameters_at_the_end():
    assert document("One line.", Toy.option_table[:1]) == (
        "One line.\n\nParameters\n----------\nlevel : int, optional\n    How much. Range 1 to 9. Default ``2``.")


def test_a_subclass_with_its_own_init_and_no_table_keeps_its_own_signature():
    class Scripted(Renderer):
        def __init__(self, frames):
            self.frames = frames

        def _render(self, scene):
            raise AssertionError

    class Bare(Renderer):
        def _render(self, scene):
            raise AssertionError

    assert renderers.option_names(Scripted) == ["frames"]
    assert renderers.option_names(Bare) == []


# -- the shared world step ------------------------------------------------------------------------------

def scaled_scene(copies=1):
    """Volumes of spacing (1, 2, 1.5) scaled by 0.5: the smallest world voxel edge is 0.5, the object one 1."""
    volume = Volume(np.linspace(0, 255, 8 ** 3).reshape(8, 8, 8).astype(np.uint8), spacing=(1.0, 2.0, 1.5))
    transform = np.diag([0.5, 0.5, 0.5, 1.0])
    transform[:3, 3] = -0.25 * np.asarray(volume.extent)
    instance = VolumeInstance(volume, TransferFunction.ramp(0.2, 0.8), transform=transform)
    return Scene([instance] * copies, camera=Camera(view_height=8.0), width=8, height=8)


def test_world_step_is_the_factor_times_the_smallest_world_voxel_edge():
    assert world_step(scaled_scene(), 0.25) == 0.125
    box = trimesh.creation.box(extents=(1, 1, 1))
    only_a_mesh = Scene(meshes=[MeshInstance(Mesh(box.vertices, box.faces), surface=SurfaceMaterial())])
    assert world_step(only_a_mesh, 0.25) is None


@pytest.mark.parametrize("name, copies", [("reference", 1), ("gl-raycast", 1), ("gl-slicer", 1), ("gl-isbvr", 1), ("gl-peel", 2),
                                          ("cl-tiled", 2), ("vtk-gpu", 2)])
def test_backends_that_step_in_world_space_use_the_shared_step(name, copies):
    scene = scaled_scene(copies)
    with backend(name, step_factor=0.5) as renderer:
        renderer.render(scene)
        assert renderer.options["effective_step"] == world_step(scene, 0.5) == 0.25
