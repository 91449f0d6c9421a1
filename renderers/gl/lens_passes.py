"""The passes of a lens frame in ``gl-raycast``: the geometry pass, the region passes or the one volume pass.

:mod:`renderers.gl.lens` has the methods, their GLSL and the lens's geometry; this module issues
the draws in their order, with their GL state, and reads the counters back. Every volume pass
rasterises back faces (the box's: one fragment per ray that meets the box in front of the eye;
for region₁ and region₂ the lens's) with the depth test ``GREATER`` against a depth buffer
cleared to 0, where an occluder has written 1: passes that do not write ``gl_FragDepth`` drop
the occluded fragments before their shader runs (early depth test), ``frag-depth`` runs its
shader first.
"""

import numpy as np

from renderers.gl import context, glsl, stencil
from renderers.gl import lens as lenses


def programs(ctx, lens, method, *, front_to_back, phong, sampling, exact_iso=False):
    """The lens frame's programs: ``volume``, for the image methods ``geometry``, and the stencil sequence's
    (``exact_iso``: an iso lens's crossing by the cell walk)."""
    def volume(outside):
        source = glsl.fragment_source(sampling, lenses.LENS_GLSL, lenses.INSIDE_GLSL, lenses.MARCH_GLSL,
                                      lenses.VOLUME_FRAGMENT, phong=phong, mode="dvr",
                                      defines=lenses.defines(lens, method, outside=outside,
                                                             front_to_back=front_to_back, exact_iso=exact_iso))
        return context.program(ctx, glsl.CUBE_VERTEX, source)

    result = {"volume": volume(False)}
    if method in lenses.SEGMENT_METHODS:
        result["volume_outside"] = volume(True)
    if method in lenses.IMAGE_METHODS:
        result["geometry"] = context.program(ctx, lenses.GEOMETRY_VERTEX,
                                             glsl.fragment_source(lenses.LENS_GLSL, lenses.GEOMETRY_FRAGMENT))
    if method == "segments-stencil":
        result.update(stencil.programs(ctx))
    return result


def geometry_pass(renderer, ctx, timer, program, targets, world_mvp, lens):
    """Rasterise the lens into ``targets["lens_t"]``: r its entry, g minus its exit along each pixel's ray
    (``world_mvp``: :func:`renderers.gl.lens.geometry_projection`)."""
    import moderngl

    rows = lenses.geometry(lens)
    program["u_world_mvp"].write(np.ascontiguousarray(world_mvp.T, dtype=np.float32).tobytes())
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


def lens_footprint(lens, view, world_mvp):
    """The lens's triangles in the volume's texture coordinates, wound counter-clockwise seen from outside
    (``(T·3, 3)`` float32), and their texture → clip matrix: drawn with front faces culled they give one
    fragment per ray that meets the lens in front of the eye, the only rays with a region₁ or region₂."""
    rows = lenses.geometry(lens)
    triangles = rows[:, :3].reshape(-1, 3, 3).astype(np.float64)
    normals = rows[::3, 3:]
    turned = np.einsum("ij,ij->i", np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]),
                       normals) < 0
    triangles[turned] = triangles[turned][:, ::-1]
    to_tex = np.linalg.inv(view.model)
    tex = triangles.reshape(-1, 3) @ to_tex[:3, :3].T + to_tex[:3, 3]
    return tex.astype(np.float32), world_mvp @ view.model


def volume_passes(renderer, ctx, timer, programs, targets, view, world_mvp, lens, method, front_to_back):
    """The volume passes of ``method`` into ``main_fbo`` (or the ping-pong pair); returns the output texture.

    Region₀'s pass and the single pass draw the box's back faces (every ray); region₁'s and region₂'s
    draw the lens's back faces (:func:`lens_footprint`: the paper's regions exist only there), so rays
    that miss the lens cost those passes nothing.
    """
    import moderngl

    volume = programs["volume"]
    box = renderer._cube_vao(ctx, volume)
    ctx.cull_face = "front"               # back faces: one fragment per ray
    if method not in lenses.SEGMENT_METHODS:
        ctx.enable_only(moderngl.CULL_FACE | moderngl.DEPTH_TEST)
        ctx.depth_func = ">"
        targets["main_fbo"].use()
        timer.run("main", box.render, count=True)
        return targets["res"]
    triangles, lens_mvp = lens_footprint(lens, view, world_mvp)
    buffer = renderer._buffer("lens_footprint", triangles)

    def draw(region):
        program = volume if region == 1 else programs["volume_outside"]
        program["u_region"].value = region
        if region == 0:
            program["u_mvp"].write(np.ascontiguousarray(view.mvp.T, dtype=np.float32).tobytes())
            timer.run("region0", renderer._cube_vao(ctx, program).render, count=True)
            return
        program["u_mvp"].write(np.ascontiguousarray(lens_mvp.T, dtype=np.float32).tobytes())
        footprint = renderer._vao((program, buffer), lambda: ctx.vertex_array(program, [(buffer, "3f", "in_tex")]))
        timer.run(f"region{region}", lambda: footprint.render(vertices=len(triangles)), count=True)

    regions = (0, 1, 2)
    if lens.appearance.mode == "clip":
        regions = (0, 2)                  # a clipping lens's region is not rendered
    if not front_to_back:
        ctx.enable_only(moderngl.CULL_FACE | moderngl.DEPTH_TEST | moderngl.BLEND)
        ctx.depth_func = ">"
        ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA    # premultiplied "over", back to front
        targets["main_fbo"].use()
        for region in regions:
            draw(region)
        return targets["res"]
    # Front to back: each pass continues the other target's accumulation (no blending, no occluder). Until
    # region₀'s pass every ray outside the lens's footprint has accumulated nothing, so the partial passes'
    # targets start cleared.
    ctx.enable_only(moderngl.CULL_FACE)
    source, target = "res2", "res"
    targets["res2_fbo"].clear(0.0, 0.0, 0.0, 0.0)
    for region in reversed(regions):
        targets[source].use(location=volume["u_acc"].value)  # one unit for every program (raycast.UNITS)
        fbo = targets["res2_fbo" if target == "res2" else "main_fbo"]
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        fbo.use()
        draw(region)
        source, target = target, source
    return targets[source]


def counters(buffer):
    """The lens frame's counters (:data:`renderers.gl.lens.COUNTERS`) from its storage buffer."""
    values = np.frombuffer(buffer.read(4 * len(lenses.COUNTERS)), dtype=np.uint32)
    return {name: int(value) for name, value in zip(lenses.COUNTERS, values)}
