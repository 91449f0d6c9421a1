"""The passes of a lens frame in ``gl-raycast``: the geometry pass, the region passes or the one volume pass.

:mod:`renderers.gl.lens` has the methods, their GLSL and the lens's geometry; this module issues
the draws in their order, with their GL state, and reads the counters back. Every volume pass
rasterises the box's back faces (one fragment per ray that meets the box in front of the eye)
with the depth test ``GREATER`` against a depth buffer cleared to 0, where an occluder has
written 1: passes that do not write ``gl_FragDepth`` drop the occluded fragments before their
shader runs (early depth test), ``frag-depth`` runs its shader first.
"""

import numpy as np

from renderers.gl import context, glsl, stencil
from renderers.gl import lens as lenses


def programs(ctx, lens, method, *, front_to_back, phong, sampling):
    """The lens frame's programs: ``volume``, for the image methods ``geometry``, and the stencil sequence's."""
    source = glsl.fragment_source(sampling, lenses.LENS_GLSL, lenses.INSIDE_GLSL, lenses.MARCH_GLSL,
                                  lenses.VOLUME_FRAGMENT, phong=phong, mode="dvr",
                                  defines=lenses.defines(lens, method, front_to_back=front_to_back))
    result = {"volume": context.program(ctx, glsl.CUBE_VERTEX, source)}
    if method in lenses.IMAGE_METHODS:
        result["geometry"] = context.program(ctx, lenses.GEOMETRY_VERTEX,
                                             glsl.fragment_source(lenses.LENS_GLSL, lenses.GEOMETRY_FRAGMENT))
    if method == "segments-stencil":
        result.update(stencil.programs(ctx))
    return result


def geometry_pass(renderer, ctx, timer, program, targets, scene, view, lens):
    """Rasterise the lens into ``targets["lens_t"]``: r its entry, g minus its exit along each pixel's ray."""
    import moderngl

    rows = lenses.geometry(lens)
    program["u_world_mvp"].write(np.ascontiguousarray(
        lenses.geometry_projection(scene, view, rows[:, :3]).T, dtype=np.float32).tobytes())
    buffer = renderer._buffer("lens_geometry", rows)
    vao = renderer._vao((program, buffer), lambda: ctx.vertex_array(
        program, [(buffer, "3f 3f", "in_world", "in_normal")]))

    def draw():
        targets["lens_fbo"].clear(lenses.NO_HIT, lenses.NO_HIT, 0.0, 0.0)
        targets["lens_fbo"].use()
        vao.render(vertices=len(rows))

    ctx.enable_only(moderngl.BLEND)       # both faces: front and back are told apart by their normals
    ctx.blend_equation = moderngl.MIN
    timer.run("lens_geometry", draw)
    ctx.blend_equation = moderngl.FUNC_ADD


def volume_passes(renderer, ctx, timer, programs, targets, lens, method, front_to_back):
    """The volume passes of ``method`` into ``main_fbo`` (or the ping-pong pair); returns the output texture."""
    import moderngl

    volume = programs["volume"]
    vao = renderer._cube_vao(ctx, volume)
    ctx.cull_face = "front"               # the box's back faces: one fragment per ray
    if method not in lenses.SEGMENT_METHODS:
        ctx.enable_only(moderngl.CULL_FACE | moderngl.DEPTH_TEST)
        ctx.depth_func = ">"
        targets["main_fbo"].use()
        timer.run("main", vao.render, count=True)
        return targets["res"]
    regions = (0, 1, 2)
    if lens.appearance.mode == "clip":
        regions = (0, 2)                  # a clipping lens's region is not rendered
    if not front_to_back:
        ctx.enable_only(moderngl.CULL_FACE | moderngl.DEPTH_TEST | moderngl.BLEND)
        ctx.depth_func = ">"
        ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA    # premultiplied "over", back to front
        targets["main_fbo"].use()
        for region in regions:
            volume["u_region"].value = region
            timer.run(f"region{region}", vao.render, count=True)
        return targets["res"]
    # Front to back: each pass continues the other target's accumulation (no blending, no occluder).
    ctx.enable_only(moderngl.CULL_FACE)
    source, target = ("res2", "res")
    targets["res2_fbo"].clear(0.0, 0.0, 0.0, 0.0)
    for region in reversed(regions):
        volume["u_region"].value = region
        targets[source].use(location=volume["u_acc"].value)
        targets[f"{target}_fbo" if target == "res2" else "main_fbo"].use()
        timer.run(f"region{region}", vao.render, count=True)
        source, target = target, source
    return targets[source]


def counters(buffer):
    """The lens frame's counters (:data:`renderers.gl.lens.COUNTERS`) from its storage buffer."""
    values = np.frombuffer(buffer.read(4 * len(lenses.COUNTERS)), dtype=np.uint32)
    return {name: int(value) for name, value in zip(lenses.COUNTERS, values)}
