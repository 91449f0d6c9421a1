"""Lens volumes (Ropinski et al. 2005) in the OpenGL ray caster: both lens methods against the
reference's lens images per shape and appearance, a lens with the outside appearance as no lens,
the edge cases of where a lens lies, and the refusals."""

import numpy as np
import pytest

import renderers
from core.camera import Camera
from core.errors import InputError, UnsupportedFeatureError
from core.lens import Lens, LensAppearance
from core.mesh import Mesh
from core.scene import Scene, Shading, VolumeInstance
from core.transfer import GradientOpacity, TransferFunction
from core.volume import Volume
from pipeline.scene_io import rotation_matrix
from renderers.gl import context
from renderers.gl import lens as gl_lens
from renderers.gl.raycast import GLRaycastRenderer
from reports.metrics import psnr

GL_OK, GL_REASON = context.probe()
needs_gl = pytest.mark.skipif(not GL_OK, reason=f"no OpenGL 4.3 context through EGL here: {GL_REASON}")

METHODS = ("fused", "per-sample")
SMOOTH = TransferFunction.from_points([(0, 1, 0.5, 0.2, 0), (0.15, 1, 0.5, 0.2, 0), (0.5, 0.3, 0.8, 1, 0.5),
                                       (1, 1, 1, 1, 0.9)], name="smooth")
OTHER = TransferFunction.ramp(0.3, 0.8, color=(0.2, 0.9, 0.4), alpha=0.6)
CLIP = LensAppearance("clip")
APPEARANCES = {"clip": CLIP,
               "dvr, another table, opacity x2": LensAppearance("dvr", transfer_function=OTHER, opacity_scale=2.0)}
CAMERA = Camera(azimuth=30.0, elevation=20.0)
BACK = CAMERA.basis()[2]  # towards the camera


def blob(n=36):
    """A smooth blob with internal structure, zero at the box faces (box [-n/2, n/2]³)."""
    z, y, x = np.meshgrid(*(np.arange(n) + 0.5,) * 3, indexing="ij")
    r = np.sqrt((x - n / 2) ** 2 + (y - n / 2) ** 2 + (z - n / 2) ** 2)
    field = np.clip(1 - r / (0.42 * n), 0, 1)
    field = np.clip(field + 0.15 * np.sin(x / 3 + 1) * np.cos(y / 4 + 2) * (field > 0), 0, 1)
    return Volume((field * 255).astype(np.uint8), name="blob")


VOLUME = blob()


def octahedron(scale):
    vertices = scale * np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    return Mesh(vertices, np.array(faces), name="octahedron")


def prism(sides, radius=8.0, height=10.0):
    """A convex prism over a regular ``sides``-gon: ``4·sides − 4`` triangles."""
    angles = 2 * np.pi * np.arange(sides) / sides
    ring = np.stack([radius * np.cos(angles), radius * np.sin(angles)], axis=1)
    vertices = np.concatenate([np.c_[ring, np.full(sides, -height / 2)], np.c_[ring, np.full(sides, height / 2)]])
    faces = []
    for i in range(sides):
        j = (i + 1) % sides
        faces += [[i, j, sides + j], [i, sides + j, sides + i]]
    faces += [[0, i + 1, i] for i in range(1, sides - 1)] + [[sides, sides + i, sides + i + 1]
                                                              for i in range(1, sides - 1)]
    return Mesh(vertices, np.array(faces), name=f"prism{sides}")


SHAPES = {"sphere": dict(shape="sphere", center=(6.0, 2.0, 0.0), radius=10.0),
          "rotated box": dict(shape="box", center=(0.0, -3.0, 4.0), size=(14.0, 20.0, 10.0),
                              transform=rotation_matrix((1, 2, 3), 35)),
          "octahedron mesh": dict(shape="mesh", center=(-3.0, 1.0, 2.0), mesh=octahedron(18.0))}


def scene_of(lens=None, *, tf=SMOOTH, shading="phong", camera=CAMERA, size=48):
    return Scene((VolumeInstance(VOLUME, tf),), camera=camera, width=size, height=size,
                 shading=Shading(model=shading), lenses=() if lens is None else [lens])


def gl(scene, method="fused", **options):
    # opaque_threshold 1: no early termination, so images compare with the reference closely.
    options = {"variant": "single-pass", "opaque_threshold": 1.0, **options}
    return renderers.get("gl-raycast", lens_method=method, **options).render(scene)


def reference(scene):
    return renderers.get("reference", step_factor=0.5).render(scene).image


# ---------------------------------------------------------------------------------------------
# Options and refusals (no GL needed for the options)


def test_the_lens_method_option():
    assert GLRaycastRenderer().options["lens_method"] == "fused"
    assert GLRaycastRenderer(lens_method="per-sample").options["lens_method"] == "per-sample"
    with pytest.raises(InputError, match="gl-raycast option lens_method"):
        GLRaycastRenderer(lens_method="segments")
    assert GLRaycastRenderer.capabilities.lenses
    assert "single-pass" in GLRaycastRenderer.capabilities.reasons["lenses"]


@pytest.mark.parametrize("backend", ["gl-slicer", "gl-isbvr", "gl-peel"])
def test_the_other_gl_backends_still_refuse_lenses(backend):
    assert not renderers.backend_class(backend).capabilities.lenses


@needs_gl
@pytest.mark.parametrize("variant", ["rc", "rc-a", "rc-b"])
def test_a_multi_pass_variant_refuses_a_lens_naming_itself_and_what_is_to_come(variant):
    with pytest.raises(UnsupportedFeatureError, match=f"variant '{variant}'.*segments.*single-pass"):
        renderers.get("gl-raycast", variant=variant).render(scene_of(Lens(appearance=CLIP, **SHAPES["sphere"])))
    # The same variant without a lens renders.
    assert renderers.get("gl-raycast", variant=variant).render(scene_of()).image[..., 3].max() > 0.5


@needs_gl
@pytest.mark.parametrize("appearance, match", [
    (LensAppearance("mip"), "'mip' lens appearance"),
    (LensAppearance("iso", isovalue=0.5), "'iso' lens appearance"),
    (LensAppearance("dvr", transfer_function=OTHER, gradient_opacity=GradientOpacity.from_points([(0, 0), (1, 1)])),
     "gradient_opacity"),
])
def test_lens_appearances_the_shader_lacks_are_refused(appearance, match):
    with pytest.raises(UnsupportedFeatureError, match=match):
        gl(scene_of(Lens(appearance=appearance, **SHAPES["sphere"])))


@needs_gl
def test_a_mesh_lens_with_more_half_spaces_than_the_shader_holds_is_refused():
    many = prism(gl_lens.MAX_LENS_PLANES // 4 + 2)
    with pytest.raises(UnsupportedFeatureError, match=f"at most {gl_lens.MAX_LENS_PLANES}"):
        gl(scene_of(Lens("mesh", center=(0, 0, 0), mesh=many, appearance=CLIP)))
    fits = prism(gl_lens.MAX_LENS_PLANES // 4)  # exactly MAX_LENS_PLANES faces
    scene = scene_of(Lens("mesh", center=(0, 0, 0), mesh=fits, appearance=CLIP))
    assert psnr(reference(scene), gl(scene).image) >= 40


# ---------------------------------------------------------------------------------------------
# Against the reference


@needs_gl
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("appearance", APPEARANCES)
@pytest.mark.parametrize("shape", SHAPES)
def test_each_shape_and_appearance_matches_the_references_lens_image(shape, appearance, method):
    scene = scene_of(Lens(appearance=APPEARANCES[appearance], **SHAPES[shape]))
    truth = reference(scene)
    plain = reference(scene_of())
    # The lens changes the picture a lot, so matching the lens image is not matching the plain one.
    assert psnr(plain, truth) < 30
    result = gl(scene, method)
    assert psnr(truth, result.image) >= 40
    assert result.info["lens"] == f"{SHAPES[shape]['shape']} {APPEARANCES[appearance].mode}"
    assert result.info["lens_method"] == method


@needs_gl
@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("shape", SHAPES)
def test_a_lens_with_the_outside_appearance_is_no_lens(shape, method, projection):
    camera = Camera(azimuth=30.0, elevation=20.0, projection=projection)
    # A copy of the table (another object, another texture): only its values may matter.
    same = LensAppearance("dvr", transfer_function=TransferFunction(SMOOTH.table.copy()))
    plain = gl(scene_of(camera=camera), method).image
    lensed = gl(scene_of(Lens(appearance=same, **SHAPES[shape]), camera=camera), method).image
    assert plain[..., 3].max() > 0.5
    np.testing.assert_allclose(lensed, plain, rtol=0, atol=1e-5)


@needs_gl
@pytest.mark.parametrize("method", METHODS)
def test_the_default_threshold_terminates_lens_rays_early_as_without_a_lens(method):
    scene = scene_of(Lens(appearance=APPEARANCES["dvr, another table, opacity x2"], **SHAPES["sphere"]))
    early = renderers.get("gl-raycast", variant="single-pass", lens_method=method).render(scene)
    full = gl(scene, method)
    assert early.counters["samples"] < full.counters["samples"]
    assert psnr(reference(scene), early.image) >= 30


@needs_gl
@pytest.mark.parametrize("method", METHODS)
def test_a_clip_lens_takes_fewer_samples(method):
    plain = gl(scene_of(), method)
    clipped = gl(scene_of(Lens(appearance=CLIP, **SHAPES["sphere"])), method)
    assert clipped.counters["samples"] < plain.counters["samples"]


EDGES = {
    "partly outside the box": dict(shape="sphere", center=(18.0, 0.0, 0.0), radius=12.0),
    "fully in front": dict(shape="sphere", center=tuple(60 * BACK), radius=15.0),
    "fully behind": dict(shape="box", center=tuple(-60 * BACK), size=(20.0, 20.0, 20.0)),
    "enclosing the volume": dict(shape="box", center=(0.0, 0.0, 0.0), size=(50.0, 50.0, 50.0)),
    "enclosing the camera": dict(shape="sphere", center=(0.0, 0.0, 0.0), radius=500.0),
}


@needs_gl
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("appearance", APPEARANCES)
@pytest.mark.parametrize("edge", EDGES)
def test_edge_cases_match_the_reference(edge, appearance, method):
    scene = scene_of(Lens(appearance=APPEARANCES[appearance], **EDGES[edge]))
    truth = reference(scene)
    image = gl(scene, method).image
    if edge.startswith("enclosing") and appearance == "clip":
        assert np.all(truth == 0) and np.all(image == 0)
        return
    assert truth[..., 3].max() > 0.5
    assert psnr(truth, image) >= 40
    if edge.startswith("fully"):
        # A lens the rays meet only outside the box changes nothing, with no seam.
        np.testing.assert_allclose(image, gl(scene_of(), method).image, rtol=0, atol=1e-5)


@needs_gl
def test_a_perspective_camera_inside_the_lens_and_the_volume_has_no_holes():
    camera = Camera(azimuth=30.0, elevation=20.0, projection="perspective", distance=10.0)
    for appearance in APPEARANCES.values():
        scene = scene_of(Lens("sphere", center=(0.0, 0.0, 9.0), radius=8.0, appearance=appearance), camera=camera)
        truth = reference(scene)
        for method in METHODS:
            assert psnr(truth, gl(scene, method).image) >= 40


@needs_gl
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("face", [-17.9, -17.8])
def test_the_last_partial_cell_is_classified_by_where_its_sample_lies(face, method):
    # Axis-aligned rays through a homogeneous box [-18, 18]³ with step 0.7: 51 whole cells, then a
    # partial one sampled at z = -17.85, where a whole cell's centre would be at -18.05. A clip lens
    # behind z = face takes that sample exactly when face > -17.85.
    volume = Volume(np.full((36, 36, 36), 128, np.uint8))
    tf = TransferFunction.constant(color=(0.9, 0.5, 0.2), alpha=0.02)
    back = -30.0
    lens = Lens("box", center=(0.0, 0.0, (face + back) / 2), size=(60.0, 60.0, face - back), appearance=CLIP)
    scene = Scene((VolumeInstance(volume, tf),), camera=Camera(), width=8, height=8, lenses=[lens])
    plain = Scene((VolumeInstance(volume, tf),), camera=Camera(), width=8, height=8)
    truth = renderers.get("reference", step_factor=0.7).render(scene).image
    image = gl(scene, method, step_factor=0.7).image
    # The partial cell's sample changes alpha by about 3e-3; the caster matches to float rounding.
    no_lens = renderers.get("reference", step_factor=0.7).render(plain).image
    assert (np.abs(truth - no_lens).max() > 1e-3) == (face > -17.85)
    np.testing.assert_allclose(image, truth, rtol=0, atol=2e-5)
