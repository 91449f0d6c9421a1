"""Lens volumes (Ropinski et al. 2005) in the OpenGL ray caster: every lens method against the
reference's lens images per shape and appearance, a lens with the outside appearance as no lens,
the edge cases of where a lens lies, the region passes' order and counts, and the refusals."""

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

METHODS = gl_lens.LENS_METHODS
EXACT = tuple(m for m in METHODS if m != "per-sample-mask")
"""Methods whose lens boundary is the lens's own (the mask's is the voxel grid's)."""
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
    assert GLRaycastRenderer().options["lens_method"] == "segments"
    assert GLRaycastRenderer(lens_method="per-sample").options["lens_method"] == "per-sample"
    with pytest.raises(InputError, match="gl-raycast option lens_method"):
        GLRaycastRenderer(lens_method="stencil-magic")
    assert GLRaycastRenderer.capabilities.lenses
    assert "single-pass" in GLRaycastRenderer.capabilities.reasons["lenses"]


@pytest.mark.parametrize("backend", ["gl-slicer", "gl-isbvr", "gl-peel"])
def test_the_other_gl_backends_still_refuse_lenses(backend):
    assert not renderers.backend_class(backend).capabilities.lenses


@needs_gl
def test_a_lens_scene_renders_with_the_default_options_in_the_single_pass_variant_and_says_so():
    """The default variant (rc-b) renders no lens: asked for nothing, a lens scene gets single-pass, the record names
    the choice, and the image is single-pass's; the next scene without a lens is rc-b's again."""
    scene = scene_of(Lens(appearance=CLIP, **SHAPES["sphere"]))
    default = renderers.get("gl-raycast").render(scene)
    chosen = renderers.get("gl-raycast", variant="single-pass").render(scene)
    assert default.info["variant"] == "single-pass" and "default variant rc-b renders no lens" in \
        default.info["variant_chosen"]
    assert "variant_chosen" not in chosen.info
    np.testing.assert_array_equal(default.image, chosen.image)
    caster = renderers.get("gl-raycast")
    caster.render(scene)
    plain = caster.render(scene_of())
    assert plain.info["variant"] == "rc-b" and "variant_chosen" not in plain.info


@needs_gl
@pytest.mark.parametrize("variant", ["rc", "rc-a", "rc-b"])
def test_a_multi_pass_variant_refuses_a_lens_naming_itself_and_what_is_to_come(variant):
    with pytest.raises(UnsupportedFeatureError, match=f"variant '{variant}'.*not cut at a lens.*single-pass"):
        renderers.get("gl-raycast", variant=variant).render(scene_of(Lens(appearance=CLIP, **SHAPES["sphere"])))
    # The same variant without a lens renders.
    assert renderers.get("gl-raycast", variant=variant).render(scene_of()).image[..., 3].max() > 0.5


@needs_gl
@pytest.mark.parametrize("method", ["per-sample", "per-sample-mask", "frag-depth"])
@pytest.mark.parametrize("appearance, match", [
    (LensAppearance("mip"), "'mip' lens appearance with lens_method"),
    (LensAppearance("iso", isovalue=0.5), "'iso' lens appearance with lens_method"),
])
def test_mip_and_iso_lenses_are_refused_by_the_per_sample_methods(appearance, match, method):
    with pytest.raises(UnsupportedFeatureError, match=match + ".*segments, segments-stencil, fused"):
        gl(scene_of(Lens(appearance=appearance, **SHAPES["sphere"])), method)


@needs_gl
def test_a_gradient_opacity_lens_is_refused():
    appearance = LensAppearance("dvr", transfer_function=OTHER,
                                gradient_opacity=GradientOpacity.from_points([(0, 0), (1, 1)]))
    with pytest.raises(UnsupportedFeatureError, match="gradient_opacity"):
        gl(scene_of(Lens(appearance=appearance, **SHAPES["sphere"])))


def test_front_to_back_is_an_order_of_the_segment_passes_only():
    with pytest.raises(InputError, match="region_order.*'fused' has one pass"):
        GLRaycastRenderer(lens_method="fused", region_order="front-to-back")
    with pytest.raises(InputError, match="region_order.*occluder=0"):
        GLRaycastRenderer(variant="single-pass", region_order="front-to-back", occluder=0.5)


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
    # Measured at 48², 36³: 66–69 dB for the exact methods; the mask's voxel-grid boundary 46–54 dB.
    assert psnr(truth, result.image) >= (60 if method in EXACT else 40)
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
        # The mask's voxel-grid boundary, seen from inside the volume up close, is far off (27.5 dB).
        for method in EXACT:
            assert psnr(truth, gl(scene, method).image) >= 40


@needs_gl
@pytest.mark.parametrize("method", EXACT)
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


# ---------------------------------------------------------------------------------------------
# Whole-segment appearances, region passes and their order, counters, early-z


WHOLE = {"mip": LensAppearance("mip"), "iso": LensAppearance("iso", isovalue=0.45),
         "iso, another table": LensAppearance("iso", isovalue=0.45, transfer_function=OTHER)}


@needs_gl
@pytest.mark.parametrize("method", gl_lens.WHOLE_SEGMENT_METHODS)
@pytest.mark.parametrize("appearance", WHOLE)
@pytest.mark.parametrize("shape", SHAPES)
def test_mip_and_iso_lenses_match_the_references_lens_image(shape, appearance, method):
    scene = scene_of(Lens(appearance=WHOLE[appearance], **SHAPES[shape]))
    truth = reference(scene)
    assert psnr(reference(scene_of()), truth) < 31
    # Measured: 64.5–68.4 dB (the reference's maximum and crossing are exact, ours on the step grid).
    assert psnr(truth, gl(scene, method).image) >= 60


@needs_gl
@pytest.mark.parametrize("method", gl_lens.SEGMENT_METHODS)
@pytest.mark.parametrize("appearance", ["clip", "dvr, another table, opacity x2"])
def test_the_regions_samples_add_up_and_match_between_segments_and_fused(appearance, method):
    scene = scene_of(Lens(appearance=APPEARANCES[appearance], **SHAPES["rotated box"]))
    counts = gl(scene, method).counters
    regions = [counts[f"samples_region{r}"] for r in range(3)]
    assert sum(regions) == counts["samples"]
    assert all(regions) or (appearance == "clip" and regions[1] == 0 and regions[0] and regions[2])
    assert counts["lens_rays"] > 0
    fused = gl(scene, "fused").counters
    assert fused["lens_rays"] == counts["lens_rays"]
    if method == "segments-stencil":
        # Where a ray grazes the lens, the rasterised faces can cross (entry past exit): the paper's
        # transitions then give region 2 what the lens interval gives region 0 (measured: 42 samples).
        assert fused["samples"] == counts["samples"]
        assert np.abs(np.subtract([fused[f"samples_region{r}"] for r in range(3)], regions)).max() <= 0.01 * sum(regions)
    else:
        assert [fused[f"samples_region{r}"] for r in range(3)] == regions


@needs_gl
@pytest.mark.parametrize("method", METHODS)
def test_a_lens_with_the_outside_appearance_takes_the_no_lens_samples(method):
    same = LensAppearance("dvr", transfer_function=TransferFunction(SMOOTH.table.copy()))
    plain = gl(scene_of(), method).counters["samples"]
    assert gl(scene_of(Lens(appearance=same, **SHAPES["sphere"])), method).counters["samples"] == plain


@needs_gl
@pytest.mark.parametrize("appearance", ["clip", "dvr, another table, opacity x2"])
@pytest.mark.parametrize("shape", SHAPES)
def test_front_to_back_regions_give_the_back_to_front_image(shape, appearance):
    scene = scene_of(Lens(appearance=APPEARANCES[appearance], **SHAPES[shape]))
    back = gl(scene, "segments")
    front = gl(scene, "segments", region_order="front-to-back")
    assert front.info["region_order"] == "front-to-back"
    np.testing.assert_allclose(front.image, back.image, rtol=0, atol=1e-5)
    assert front.counters["samples"] == back.counters["samples"]


@needs_gl
def test_front_to_back_stops_rays_that_are_opaque_in_front_of_the_lens():
    # Opaque material: most rays saturate in front of a lens at the back of the blob.
    tf = TransferFunction.ramp(0.05, 0.3, color=(0.8, 0.7, 0.6), alpha=1.0)
    lens = Lens("sphere", center=tuple(-8 * BACK), radius=9.0, appearance=APPEARANCES["dvr, another table, opacity x2"])
    scene = scene_of(lens, tf=tf)
    options = dict(variant="single-pass", lens_method="segments")
    back = renderers.get("gl-raycast", **options).render(scene)
    front = renderers.get("gl-raycast", region_order="front-to-back", **options).render(scene)
    # Measured: region 1 1327 → 0 samples, region 0 34383 → 32061 (the lens's rays; the others are all region 0).
    assert front.counters["samples_region1"] < 0.05 * back.counters["samples_region1"]
    assert front.counters["samples_region0"] < back.counters["samples_region0"] - back.counters["samples_region1"]
    assert front.counters["samples_region2"] == back.counters["samples_region2"]
    # Back to front composites what front to back drops (below 1 - threshold of each pixel's light).
    assert np.abs(front.image - back.image).max() <= 1 - 0.95 + 1e-6
    assert psnr(back.image, front.image) >= 40


@needs_gl
@pytest.mark.parametrize("method", METHODS)
def test_an_occluder_culls_the_lens_passes_fragments_unless_they_write_depth(method):
    scene = scene_of(Lens(appearance=CLIP, **SHAPES["sphere"]))
    free = gl(scene, method)
    covered = gl(scene, method, occluder=0.5)
    assert covered.counters["rays_occluded"] > 0.3 * free.counters["rays"]
    shaded = covered.counters["fragments_shaded"]
    if method == "frag-depth":
        # Writing gl_FragDepth turns early depth testing off: every fragment runs its shader.
        assert shaded == free.counters["fragments_shaded"]
    else:
        assert shaded < free.counters["fragments_shaded"] - 0.3 * covered.counters["rays_occluded"]
    # Occluded pixels show the plane's grey, the others the lens image.
    grey = covered.image[..., 3] == 1.0
    assert grey.sum() >= covered.counters["rays_occluded"] // 2
    np.testing.assert_allclose(covered.image[~grey], free.image[~grey], rtol=0, atol=1e-6)


def test_the_lens_geometry_of_a_box_is_its_faces_with_outward_normals():
    lens = Lens(appearance=CLIP, **SHAPES["rotated box"])
    rows = gl_lens.geometry(lens)
    assert rows.shape == (36, 6)
    centre = np.asarray(lens.center)
    faces = rows[:, :3].reshape(12, 3, 3)
    outward = np.einsum("ij,ij->i", faces.mean(axis=1) - centre, rows[::3, 3:])
    assert np.all(outward > 0)
    np.testing.assert_allclose(np.linalg.norm(rows[:, 3:], axis=1), 1, atol=1e-6)
    # The half-spaces agree: every vertex is on the lens's boundary.
    local = rows[:, :3] @ np.linalg.inv(lens.object_to_world())[:3, :3].T + np.linalg.inv(lens.object_to_world())[:3, 3]
    normals, offsets = lens.half_spaces()
    assert np.allclose((local @ normals.T - offsets).max(axis=1), 0, atol=1e-4)


def test_the_lens_mask_marks_voxel_centres_inside_the_lens():
    lens = Lens("sphere", center=(0.0, 0.0, 0.0), radius=10.0, appearance=CLIP)
    instance = scene_of(lens).volumes[0]
    mask = gl_lens.lens_mask(instance.volume, instance.transform, lens)
    assert mask.shape == VOLUME.data.shape and set(np.unique(mask)) == {0, 255}
    # Voxels of edge 1 around the origin: about the sphere's volume of them are inside.
    assert abs((mask > 0).sum() - 4 / 3 * np.pi * 10 ** 3) < 0.03 * 4 / 3 * np.pi * 10 ** 3


def box_span(scene):
    """Each pixel's ray's ``(t_in, t_out)`` in the volume's box, ``t_in`` clipped to 0 (NaN: a miss)."""
    instance = scene.volumes[0]
    origins, directions = scene.camera.rays(scene.width, scene.height)
    inverse = np.linalg.inv(instance.transform)
    o = origins @ inverse[:3, :3].T + inverse[:3, 3]
    d = directions @ inverse[:3, :3].T
    with np.errstate(divide="ignore", invalid="ignore"):
        ta, tb = -o / d, (np.asarray(instance.volume.extent) - o) / d
    t_in = np.maximum(np.minimum(ta, tb).max(axis=-1), 0.0)
    t_out = np.maximum(ta, tb).min(axis=-1)
    hit = t_out > t_in
    return np.where(hit, t_in, np.nan), np.where(hit, t_out, np.nan)


@needs_gl
@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
@pytest.mark.parametrize("where", ["sphere", "rotated box", "octahedron mesh", "fully behind", "enclosing the volume"])
def test_the_stencil_sequences_transitions_are_the_per_pixel_resolve(where, projection):
    placement = SHAPES.get(where) or EDGES[where]
    scene = scene_of(Lens(appearance=CLIP, **placement), camera=Camera(azimuth=30.0, elevation=20.0,
                                                                          projection=projection))
    caster = renderers.get("gl-raycast", variant="single-pass", lens_method="segments-stencil")
    result = caster.render(scene)
    images = caster.lens_images()
    entry, exit_ = images["lens_entry"], images["lens_exit"]
    t_in, t_out = box_span(scene)
    box = ~np.isnan(t_in)
    grazing = entry > exit_ - 1e-3  # faces that cross on the silhouette: either answer is right
    check = box & ~grazing
    # transition 1: the lens's entry where it lies inside the box (the erratum as intended).
    inside = ~np.isnan(exit_) & (entry > t_in) & (entry < t_out)
    np.testing.assert_array_equal(~np.isnan(images["transition1"])[check], inside[check])
    np.testing.assert_allclose(images["transition1"][check & inside], entry[check & inside], rtol=1e-5, atol=1e-4)
    # transition 0: the lens's exit inside the box; the box's entry where the ray has no lens inside or
    # behind the box's front; unmarked where the lens's exit lies behind the box's back.
    exit_inside = ~np.isnan(exit_) & (exit_ > t_in) & (exit_ < t_out)
    behind = ~np.isnan(exit_) & (exit_ >= t_out)
    expected = np.where(exit_inside, exit_, np.where(behind, np.nan, t_in))
    np.testing.assert_array_equal(np.isnan(images["transition0"])[check], np.isnan(expected)[check])
    both = check & ~np.isnan(expected)
    np.testing.assert_allclose(images["transition0"][both], expected[both], rtol=1e-5, atol=1e-4)
    # The guide's hole: rays whose lens lies wholly behind the box are unmarked and have no lens inside it.
    holes = box & behind & ~(entry < t_out)
    assert result.counters["hole_rays"] == holes.sum()
    if where == "fully behind":
        assert holes.sum() > 100
    if where == "enclosing the volume":
        # Unmarked too, but lens ∩ box (the CSG images) says region 1 runs to the box's back: no hole.
        assert holes.sum() == 0 and np.isnan(images["transition0"][box]).all()


@needs_gl
def test_the_holes_of_the_papers_images_are_rendered_as_region_zero():
    scene = scene_of(Lens(appearance=APPEARANCES["dvr, another table, opacity x2"], **EDGES["fully behind"]))
    result = gl(scene, "segments-stencil")
    assert result.counters["hole_rays"] > 100
    np.testing.assert_allclose(result.image, gl(scene_of(), "segments-stencil").image, rtol=0, atol=1e-5)
