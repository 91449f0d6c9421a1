"""The paper's transition images built with the stencil buffer and a second depth test (``segments-stencil``).

Ropinski, Steinicke & Hinrichs 2005, Sec. 4 (note 004 §2.4–2.6). Every image holds, per pixel,
the world ray parameter ``t`` of a surface in red and 1 in alpha where a fragment was written
(the paper stores volume texture coordinates; ``t`` is the same point, at float32 precision).

* **Second depth test** (§2.4): the lens's fragments read the depth of the box's front faces
  (``front_depth``) at their pixel and ``discard`` unless they lie behind it. A discarded fragment
  never reaches the stencil stage, where a fragment failing the standard depth test does.
* ``transition₀`` (§2.5), the entry of region₀: (1) the box's back faces write depth (``LESS``) and
  stencil 1; (2) the lens's back faces, with the second depth test, stencil test ``EQUAL 1`` and
  stencil set to 0 on depth pass *and* depth fail, write their ``t`` where they lie inside the box;
  behind the box they fail the depth test and leave alpha 0, the paper's "no region₀" mark; (3)
  where the stencil is still 1 the box's entry is written (rays that do not meet the lens's back
  inside the box: region₀ is their whole span). Step (3) draws the box's back faces with the
  entry computed in the shader (clipped to ``t >= 0``), so a camera inside the box gets one too.
* ``transition₁`` (§2.6, the erratum as intended): the box's back faces write depth, then the
  lens's front faces with the standard test ``LESS`` and the second test (behind the box's
  front): the lens's entry where it lies inside the box. The paper's literal ``GREATER``/``LESS``
  pair keeps no fragment.
* ``lens_front``/``lens_back`` (§2.7), the surfaces of lens ∩ box, are for two convex solids the
  per-pixel ``max``/``min`` the guide derives; they come from the geometry pass's lens images
  (:mod:`renderers.gl.lens_passes`) and tell a ray whose lens lies wholly behind the box from one
  whose lens encloses the box's back: both leave ``transition₀`` with alpha 0, and only the second
  has a region₁. The first is the guide's hole (§2.8): the paper's images give such a ray no region
  at all. The region passes render region₀ over the whole ray there and count those rays
  (``hole_rays``).

moderngl 5 has no stencil API: the framebuffer with a ``DEPTH24_STENCIL8`` renderbuffer and the
stencil state are made through PyOpenGL on moderngl's context (``detect_framebuffer`` wraps it).
"""

import os

import numpy as np

from renderers.gl import context, glsl
from renderers.gl import lens as lenses

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")  # the context is EGL's (before PyOpenGL is imported)

BOX_FRAGMENT = """
out vec4 o_entry;
// The box's entry along this pixel's ray (clipped to t >= 0), written with alpha 1.
void main() {
    vec3 origin, ray_dir;
    pixel_ray(gl_FragCoord.xy, origin, ray_dir);
    vec3 o = (u_world_to_tex * vec4(origin, 1.0)).xyz;
    o_entry = vec4(slab(o, mat3(u_world_to_tex) * ray_dir).x, 0.0, 0.0, 1.0);
}
"""

FACE_FRAGMENT = """
uniform mat4 u_world_mvp;
uniform int u_side;              // 0: the lens's front faces, 1: its back faces
uniform sampler2D u_front_depth; // the box's front faces' depth: the second depth test
in vec3 v_world;
flat in vec3 v_normal;
out vec4 o_t;
void main() {
    vec3 origin, ray_dir;
    pixel_ray(gl_FragCoord.xy, origin, ray_dir);
    float t;
    float depth = gl_FragCoord.z;
    if (u_lens_kind == 0) {
        // The sphere impostor: its circumscribed cube's back faces carry both of its surfaces.
        vec2 span = lens_interval(origin, ray_dir);
        t = u_side == 0 ? span.x : span.y;
        if (!(span.y > span.x) || dot(v_normal, ray_dir) < 0.0 || t < 0.0) {
            discard;
        }
        vec4 clip = u_world_mvp * vec4(origin + t * ray_dir, 1.0);
        depth = 0.5 * clip.z / clip.w + 0.5;
    } else {
        if ((dot(v_normal, ray_dir) < 0.0) != (u_side == 0)) {
            discard;     // a face of the other side
        }
        t = dot(v_world - origin, ray_dir);
    }
    if (!(depth > texelFetch(u_front_depth, ivec2(gl_FragCoord.xy), 0).r)) {
        discard;         // in front of the box: no stencil update
    }
    gl_FragDepth = depth;
    o_t = vec4(t, 0.0, 0.0, 1.0);
}
"""

UNIT_FRONT_DEPTH = 15


def programs(ctx):
    """The box program (depth, stencil and the entry fill) and the lens faces' (the second depth test)."""
    return {"stencil_box": context.program(ctx, glsl.CUBE_VERTEX, glsl.fragment_source(BOX_FRAGMENT)),
            "stencil_faces": context.program(ctx, lenses.GEOMETRY_VERTEX,
                                             glsl.fragment_source(lenses.LENS_GLSL, FACE_FRAGMENT))}


class StencilTargets:
    """The transition images, the box's front depth and a depth–stencil framebuffer for each image."""

    def __init__(self, ctx, size):
        from OpenGL import GL

        self.transition0 = ctx.texture(size, 4, dtype="f4")
        self.transition1 = ctx.texture(size, 4, dtype="f4")
        for texture in (self.transition0, self.transition1):
            texture.filter = (0x2600, 0x2600)  # GL_NEAREST
        self.front_depth = ctx.depth_texture(size)
        self.front_fbo = ctx.framebuffer(depth_attachment=self.front_depth)
        self._renderbuffer = int(GL.glGenRenderbuffers(1))
        GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._renderbuffer)
        GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_DEPTH24_STENCIL8, *size)
        self._framebuffers = []
        self.fbos = []
        for texture in (self.transition0, self.transition1):
            name = int(GL.glGenFramebuffers(1))
            GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, name)
            GL.glFramebufferTexture2D(GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_TEXTURE_2D, texture.glo, 0)
            GL.glFramebufferRenderbuffer(GL.GL_FRAMEBUFFER, GL.GL_DEPTH_STENCIL_ATTACHMENT, GL.GL_RENDERBUFFER,
                                         self._renderbuffer)
            status = GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER)
            if status != GL.GL_FRAMEBUFFER_COMPLETE:
                raise RuntimeError(f"segments-stencil: the depth-stencil framebuffer is not complete (status {status:#x})")
            self._framebuffers.append(name)
            self.fbos.append(ctx.detect_framebuffer(name))

    def release(self):
        from OpenGL import GL

        for item in (self.transition0, self.transition1, self.front_depth, self.front_fbo):
            item.release()
        GL.glDeleteFramebuffers(len(self._framebuffers), self._framebuffers)
        GL.glDeleteRenderbuffers(1, [self._renderbuffer])


def transition_passes(renderer, ctx, timer, programs, stencil_targets, view, world_mvp, lens):
    """Build ``transition₀`` and ``transition₁`` (stage ``lens_geometry``; see the module notes)."""
    import moderngl
    from OpenGL import GL

    rows = lenses.geometry(lens)
    box, faces = programs["stencil_box"], programs["stencil_faces"]
    box["u_mvp"].write(np.ascontiguousarray((world_mvp @ view.model).T, dtype=np.float32).tobytes())
    faces["u_world_mvp"].write(np.ascontiguousarray(world_mvp.T, dtype=np.float32).tobytes())
    faces["u_front_depth"].value = UNIT_FRONT_DEPTH
    box_vao = renderer._cube_vao(ctx, box)
    buffer = renderer._buffer("lens_geometry", rows)
    face_vao = renderer._vao((faces, buffer), lambda: ctx.vertex_array(
        faces, [(buffer, "3f 3f", "in_world", "in_normal")]))
    t0_fbo, t1_fbo = stencil_targets.fbos

    def draw_faces(side):
        faces["u_side"].value = side
        face_vao.render(vertices=len(rows))

    def front_depth():
        ctx.enable_only(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.depth_func = "1"
        ctx.cull_face = "back"
        stencil_targets.front_fbo.clear(depth=0.0)   # no front face (the eye inside the box): all behind it
        stencil_targets.front_fbo.use()
        box_vao.render()
        stencil_targets.front_depth.use(location=UNIT_FRONT_DEPTH)

    def box_back_depth(fbo):
        # moderngl applies a framebuffer's masks when it is bound.
        fbo.depth_mask = True
        fbo.color_mask = (False, False, False, False)
        fbo.use()
        ctx.enable_only(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.depth_func = "<"
        ctx.cull_face = "front"
        box_vao.render()
        fbo.color_mask = (True, True, True, True)
        fbo.depth_mask = False
        fbo.use()

    def transition0():
        t0_fbo.depth_mask = True   # the clear writes depth only through an open mask
        t0_fbo.use()
        GL.glClearColor(0.0, 0.0, 0.0, 0.0)
        GL.glClearDepth(1.0)
        GL.glClearStencil(0)
        GL.glStencilMask(0xFF)
        GL.glClear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT | GL.GL_STENCIL_BUFFER_BIT)
        GL.glEnable(GL.GL_STENCIL_TEST)
        GL.glStencilFunc(GL.GL_ALWAYS, 1, 0xFF)
        GL.glStencilOp(GL.GL_KEEP, GL.GL_KEEP, GL.GL_REPLACE)     # (1) stencil 1 under the box's back
        box_back_depth(t0_fbo)
        ctx.enable_only(moderngl.DEPTH_TEST)
        ctx.depth_func = "<"
        GL.glStencilFunc(GL.GL_EQUAL, 1, 0xFF)
        GL.glStencilOp(GL.GL_KEEP, GL.GL_ZERO, GL.GL_ZERO)        # (2) 0 on depth fail and pass
        draw_faces(1)
        ctx.enable_only(moderngl.CULL_FACE)
        ctx.cull_face = "front"
        GL.glStencilOp(GL.GL_KEEP, GL.GL_KEEP, GL.GL_KEEP)        # (3) the box's entry where still 1
        box_vao.render()
        GL.glDisable(GL.GL_STENCIL_TEST)

    def transition1():
        t1_fbo.depth_mask = True
        t1_fbo.use()
        GL.glClearColor(0.0, 0.0, 0.0, 0.0)
        GL.glClearDepth(1.0)
        GL.glClear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)
        box_back_depth(t1_fbo)
        ctx.enable_only(moderngl.DEPTH_TEST)
        ctx.depth_func = "<"
        draw_faces(0)

    timer.run("lens_geometry", front_depth)
    timer.run("lens_geometry", transition0)
    timer.run("lens_geometry", transition1)
