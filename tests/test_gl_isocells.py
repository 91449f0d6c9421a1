"""The exact iso-surface crossing of gl-raycast (renderers.gl.isocells, option iso_hit='exact') against the
reference's cell walk: the crossing itself on random cells, and what sampling misses (a one-voxel sheet, a tube
thinner than a step) in whole frames."""

from dataclasses import replace

import numpy as np
import pytest

from core.errors import InputError
from core.lens import Lens, LensAppearance
from core.transfer import TransferFunction
from renderers.base.interface import Renderer
from renderers.gl import context, glsl, isocells
from renderers.gl.base import SCREEN_TRIANGLE
from renderers.gl.raycast import GLRaycastRenderer
from renderers.reference.renderer import ReferenceRenderer
from reports.metrics import psnr
from iso_shapes import normal_angles, random_rays, reference_crossings, sheet, thin_scene, tube
from test_gl_raycast import blob, scene_of

GL_OK, GL_REASON = context.probe()
needs_gl = pytest.mark.skipif(not GL_OK, reason=f"no OpenGL 4.3 context through EGL here: {GL_REASON}")

CROSSING = glsl.VERSION + """
uniform sampler3D u_volume;
uniform vec2 u_value_map;
uniform vec3 u_extent;
uniform float u_iso;
uniform sampler2D u_starts;
uniform sampler2D u_dirs;
layout(location = 0) out vec4 o_result;
layout(location = 1) out vec4 o_gradient;
""" + isocells.CELL_WALK + """
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 start = texelFetch(u_starts, px, 0).xyz;
    vec3 dir = texelFetch(u_dirs, px, 0).xyz;
    iso_cells = 0;
    float t = iso_first_crossing(start, dir, 0.0, 1.0, scalar_exact(start) < u_iso);
    o_result = vec4(t, float(iso_cells), 0.0, 0.0);
    o_gradient = vec4(t < ISO_FAR ? gradient_exact(start + t * dir) : vec3(0.0), 0.0);
}
"""


def gl_crossings(volume, base, slope, iso):
    """The GLSL walk's first crossing on ``t`` in [0, 1] of each ray ``base + t·slope`` (lattice coordinates of
    ``volume``, z-y-x, unit spacing), ``inf`` where there is none, the cell segments it walked and the gradient
    at the hit."""
    import moderngl

    ctx = context.shared_context()
    nz, ny, nx = volume.shape
    n = np.array([nx, ny, nz], float)
    count = len(base)

    def rows(values):
        return ctx.texture((count, 1), 4, np.c_[values, np.zeros(count)].astype("f4").tobytes(), dtype="f4")

    program = context.program(ctx, glsl.SCREEN_VERTEX, CROSSING)
    data = ctx.texture3d((nx, ny, nz), 1, np.ascontiguousarray(volume, dtype="f4").tobytes(), dtype="f4")
    starts, dirs = rows((base + 0.5) / n), rows(slope / n)
    out, gradient = ctx.texture((count, 1), 4, dtype="f4"), ctx.texture((count, 1), 4, dtype="f4")
    fbo = ctx.framebuffer(color_attachments=[out, gradient])
    triangle = ctx.buffer(SCREEN_TRIANGLE.tobytes())
    vao = ctx.vertex_array(program, [(triangle, "2f", "in_position")])
    try:
        for unit, texture in enumerate((data, starts, dirs)):
            texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
            texture.use(location=unit)
        program["u_volume"], program["u_starts"], program["u_dirs"] = 0, 1, 2
        program["u_value_map"], program["u_iso"], program["u_extent"] = (1.0, 0.0), iso, tuple(n)
        fbo.use()
        ctx.viewport = (0, 0, count, 1)
        ctx.enable_only(moderngl.NOTHING)  # whatever an earlier render left on (culling, depth, blending)
        ctx.scissor = None
        vao.render(vertices=3)
        result = np.frombuffer(out.read(), dtype="f4").reshape(count, 4)
        normal = np.frombuffer(gradient.read(), dtype="f4").reshape(count, 4)[:, :3].astype(float)
    finally:
        for item in (vao, triangle, fbo, out, gradient, starts, dirs, data):
            item.release()
    t = result[:, 0].astype(float)
    return np.where(t >= 1e38, np.inf, t), result[:, 1].astype(int), normal


@needs_gl
def test_the_crossing_is_the_references_within_a_ten_thousandth_of_a_voxel_on_random_cells():
    volume, base, slope = random_rays(7, (5, 4, 6))
    count = len(base)
    gl, cells, _ = gl_crossings(volume, base, slope, 0.5)
    ref = reference_crossings(volume, base, slope, 0.5)
    both = np.isfinite(ref) & np.isfinite(gl)
    assert np.array_equal(np.isfinite(gl), np.isfinite(ref))  # the same rays hit
    assert both.sum() > count // 2
    voxels = np.abs(gl[both] - ref[both]) * np.linalg.norm(slope[both], axis=1)
    assert voxels.max() < 1e-4
    assert (cells >= 1).all()


@needs_gl
def test_the_normal_at_the_hit_is_the_references_within_half_a_degree():
    """The reference's normal: central differences one voxel apart of the trilinear field at its hit. Where the
    gradient is nearly zero (a saddle) its direction is undefined, so hits with |∇s| < 0.05 per voxel are left out."""
    volume, base, slope = random_rays(11, (6, 5, 7))
    count = len(base)
    gl, _, normal = gl_crossings(volume, base, slope, 0.5)
    ref = reference_crossings(volume, base, slope, 0.5)
    angles = normal_angles(volume, base + ref[:, None] * slope, normal, np.isfinite(ref) & np.isfinite(gl))
    assert len(angles) > count // 3
    assert max(angles) < 0.5


@needs_gl
def test_a_crossing_between_two_samples_is_found_where_sampling_misses_it():
    """One cell, two corners at 1 and six at 0: along its diagonal the field is (1 − s)³ + s³, above 0.4 at both
    ends of s in [0.2, 0.8] and below it between, so a test at the ends sees nothing; along the other diagonal it is
    s(1 − s) ≤ 0.25, never above 0.4."""
    volume = np.zeros((2, 2, 2))
    volume[0, 0, 0] = volume[1, 1, 1] = 1.0
    base = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    slope = np.array([[1.0, 1.0, 1.0], [1.0, -1.0, 1.0]])
    gl, _, _ = gl_crossings(volume, base + 0.2 * slope, 0.6 * slope, 0.4)
    ref = reference_crossings(volume, base + 0.2 * slope, 0.6 * slope, 0.4)
    assert np.isfinite(ref[0]) and abs(gl[0] - ref[0]) * np.linalg.norm(0.6 * slope[0]) < 1e-4
    assert np.isinf(ref[1]) and np.isinf(gl[1])


# ------------------------------------------------------------------------------------- whole frames
def _coverage(renderer, scene):
    return renderer.render(scene).image[..., 3] > 0.5


@needs_gl
@pytest.mark.parametrize("make, camera", [(sheet, {}), (tube, {"elevation": 80.0, "size": 64})],
                         ids=["one-voxel sheet", "tube thinner than a step"])
@pytest.mark.parametrize("variant", ["single-pass", "rc", "rc-b"])
def test_thin_features_are_hit_where_the_exact_reference_hits_them(make, camera, variant):
    """Measured (llvmpipe): the exact hit covers the reference's pixels exactly; sampling at step 1 misses 125 of
    the sheet's 416 and 16 of the tube's 27 at 48²."""
    scene = thin_scene(make(), **camera)
    truth = _coverage(ReferenceRenderer(), scene)
    exact = _coverage(GLRaycastRenderer(variant=variant, iso_hit="exact", step_factor=1.0), scene)
    sampled = _coverage(GLRaycastRenderer(variant=variant, iso_hit="sampled", step_factor=1.0), scene)
    assert truth.sum() > 20
    assert (exact != truth).sum() <= 2  # grazing rays: float32 against float64
    assert (sampled != truth).sum() > 10 * max((exact != truth).sum(), 1)  # what the samples step over


@needs_gl
def test_the_exact_hit_option_is_declared_and_recorded():
    assert isinstance(GLRaycastRenderer(iso_hit="exact"), Renderer)
    with pytest.raises(InputError, match="iso_hit"):
        GLRaycastRenderer(iso_hit="analytic")
    result = GLRaycastRenderer(variant="single-pass", iso_hit="exact").render(thin_scene(sheet()))
    assert result.info["iso_hit"] == "exact" and result.counters["samples"] > 0


CLEAR = TransferFunction.from_points([(0, 0.5, 0.5, 0.5, 0), (1, 0.5, 0.5, 0.5, 0)], name="clear")


@needs_gl
@pytest.mark.parametrize("make, camera", [(sheet, {}), (tube, {"elevation": 80.0, "size": 64})],
                         ids=["one-voxel sheet", "tube thinner than a step"])
@pytest.mark.parametrize("method", ["segments", "fused"])
def test_an_iso_lens_hits_thin_features_inside_it_exactly(make, camera, method):
    """The volume transparent, an iso lens over the middle: only the lens shows the surface. Measured (llvmpipe):
    the exact hit covers the reference's 179 (sheet) and 36 (tube) pixels exactly; sampling at step 1 misses 54 and
    21 of them."""
    base = thin_scene(make(), **camera)
    instance = base.volumes[0]
    lens = Lens(shape="sphere", center=(0.0, 0.0, 0.0), radius=9.0,
                appearance=LensAppearance("iso", isovalue=0.5, transfer_function=instance.transfer_function))
    scene = replace(base, mode="dvr", lenses=[lens],
                    volumes=(replace(instance, transfer_function=CLEAR, isovalue=None),))
    truth = _coverage(ReferenceRenderer(), scene)
    exact = _coverage(GLRaycastRenderer(lens_method=method, iso_hit="exact", step_factor=1.0), scene)
    sampled = _coverage(GLRaycastRenderer(lens_method=method, iso_hit="sampled", step_factor=1.0), scene)
    assert truth.sum() > 20
    assert (exact != truth).sum() <= 2
    assert (sampled != truth).sum() > 10 * max((exact != truth).sum(), 1)


@needs_gl
@pytest.mark.parametrize("dtype", [np.float32, np.uint8], ids=["float32", "8-bit"])
@pytest.mark.parametrize("variant", ["single-pass", "rc-b"])
def test_an_exact_frame_is_the_references_to_rounding_shading_included(dtype, variant):
    """Measured (llvmpipe, the blob at 48², Blinn–Phong): 128–143 dB against the reference for the exact hit with its
    own normal; the sampled hit gets 90 dB on float32 and 38 dB on 8-bit data, whose filter weights have 8 bits."""
    scene = scene_of(blob(dtype=dtype), shading="phong", mode="iso")
    truth = ReferenceRenderer(step_factor=0.5).render(scene).image
    assert psnr(truth, GLRaycastRenderer(variant=variant, iso_hit="exact").render(scene).image) >= 100.0


@needs_gl
def test_every_variant_counts_the_cells_its_exact_passes_walk():
    """Measured (llvmpipe, the sheet at 48²): 20,398 cells in one pass; rc 30,158 (every pass walks its segment,
    hit or not), rc-a 22,828 (early termination), rc-b 13,301 (empty blocks skipped too), against M × fragments
    of 82,512 / 28,608 / 16,720 had the passes sampled."""
    scene = thin_scene(sheet())
    truth = _coverage(ReferenceRenderer(), scene).sum()
    walked = {}
    for variant in ("single-pass", "rc", "rc-a", "rc-b"):
        counters = GLRaycastRenderer(variant=variant, iso_hit="exact").render(scene).counters
        walked[variant] = counters["samples"]
        if variant != "single-pass":
            assert counters["samples"] != counters["fragments_main"] * 8
        assert abs(counters["crossings"] - truth) <= 2 and 0 < counters["iso_cells_solved"] < counters["samples"]
    sampled = GLRaycastRenderer(iso_hit="sampled", step_factor=1.0).render(scene).counters
    assert sampled["crossings"] < truth - 10 and "iso_cells_solved" not in sampled
    assert 0 < walked["rc-b"] < walked["rc-a"] < walked["rc"]
    assert walked["single-pass"] < walked["rc"]
