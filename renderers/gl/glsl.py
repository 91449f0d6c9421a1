"""GLSL pieces shared by the OpenGL backends, and the source assembler.

Everything that decides what a sample *is* lives here once, so that the ray caster's passes,
the slicer and later backends sample, classify, correct and shade exactly alike (and like the
reference renderer, :mod:`renderers.reference.raycast`):

* **Texture space.** Positions are 3-D texture coordinates ``[0, 1]³`` of the volume's object
  box (object point = texture coordinate × extent). Texel centres sit at ``(i + ½)/n``, which is
  the cell-centred voxel ``i``, and ``GL_CLAMP_TO_EDGE`` with linear filtering is the reference's
  clamp-to-edge trilinear reconstruction.
* **Scalars** (:func:`scalar_at`): the texture value mapped by ``u_value_map`` (scale, offset) to
  the normalised scalar. The map is affine, so it commutes with trilinear filtering; textures
  whose values would be clipped by the volume's range are uploaded already normalised
  (:mod:`renderers.gl.resources`).
* **Classification** (:func:`classify`): the transfer-function table read with ``texelFetch``
  and blended in float32, entry ``i`` at ``s = i/(N − 1)``, clamped (not the texture unit's
  filter, whose weights may have 8 fractional bits).
* **Opacity correction**: ``α' = 1 − (1 − α)^r``, ``r`` the sample's object-space length over
  ``Δ0``.
* **Shading** (:func:`shade`): :class:`core.scene.Shading`'s two-sided Blinn–Phong with the
  normal from the gradient texture through ``A^{-T}``, the light in world space and the half
  vector of each ray's own direction.
* **Rays** (:func:`pixel_ray`, :func:`slab`): the pixel's ray exactly as
  :meth:`core.camera.Camera.rays` builds it, and its span in the box, clipped to ``t >= 0``.

Defines select variants at compile time: ``PHONG`` (shading on), ``MODE_DVR`` / ``MODE_MIP`` /
``MODE_ISO``.
"""

VERSION = "#version 430\n"

COMMON = """
uniform sampler3D u_volume;      // scalar texture, linear filter, clamp-to-edge
uniform vec2 u_value_map;        // normalised scalar = texture value * x + y
uniform sampler2D u_tf;          // (N, 1) RGBA32F transfer function, colours not premultiplied
uniform int u_tf_size;
uniform vec3 u_extent;           // object box size
uniform mat4 u_world_to_tex;     // world point -> texture coordinate
uniform mat3 u_tex_to_world;     // texture-space displacement -> world displacement
uniform vec3 u_eye;              // camera frame, world space (core.camera)
uniform vec3 u_right;
uniform vec3 u_up;
uniform vec3 u_back;
uniform vec2 u_half_size;        // orthographic: half width/height in world units; perspective: tan
uniform int u_perspective;
uniform vec2 u_viewport;         // image width, height in pixels
uniform float u_step;            // world step between samples
uniform float u_ref_step;        // reference step of the table's opacities (object units)

float scalar_at(vec3 p) {
    return clamp(texture(u_volume, p).r * u_value_map.x + u_value_map.y, 0.0, 1.0);
}

vec4 classify(float s) {
    float x = s * float(u_tf_size - 1);
    int i0 = min(int(floor(x)), u_tf_size - 2);
    return mix(texelFetch(u_tf, ivec2(i0, 0), 0), texelFetch(u_tf, ivec2(i0 + 1, 0), 0), x - float(i0));
}

float correct_opacity(float alpha, float ratio) {
    return 1.0 - pow(max(1.0 - alpha, 0.0), ratio);
}

// The ray through the pixel centre at window position `frag` (core.camera.Camera.rays).
void pixel_ray(vec2 frag, out vec3 origin, out vec3 direction) {
    vec2 ndc = frag / u_viewport * 2.0 - 1.0;
    vec3 offset = ndc.x * u_half_size.x * u_right + ndc.y * u_half_size.y * u_up;
    if (u_perspective == 1) {
        origin = u_eye;
        direction = normalize(offset - u_back);
    } else {
        origin = u_eye + offset;
        direction = -u_back;
    }
}

// Span [t_in, t_out] of the ray o + t d (texture space) in the unit box, clipped to t >= 0.
vec2 slab(vec3 o, vec3 d) {
    vec3 safe = mix(d, vec3(1e-12), lessThan(abs(d), vec3(1e-12)));
    vec3 ta = -o / safe;
    vec3 tb = (1.0 - o) / safe;
    vec3 lo = min(ta, tb);
    vec3 hi = max(ta, tb);
    return vec2(max(max(lo.x, lo.y), max(lo.z, 0.0)), min(hi.x, min(hi.y, hi.z)));
}
"""

LIGHTING = """
uniform vec3 u_light;            // world-space unit direction towards the light
uniform vec4 u_phong;            // ambient, diffuse, specular, shininess

// Two-sided Blinn-Phong of `color` with the world normal n (any length; 0: ambient only) for a
// ray travelling along `ray_dir`, with `terms` = ambient, diffuse, specular, shininess.
vec3 blinn_phong_terms(vec3 color, vec3 n, vec3 ray_dir, vec4 terms) {
    float norm = length(n);
    float factor = terms.x;
    float highlight = 0.0;
    if (norm > 0.0) {
        factor += terms.y * abs(dot(n, u_light)) / norm;
        vec3 h = u_light - ray_dir;
        float h_norm = length(h);
        if (h_norm > 0.0) {
            highlight = terms.z * pow(min(abs(dot(n, h)) / (h_norm * norm), 1.0), terms.w);
        }
    }
    return clamp(color * factor + highlight, 0.0, 1.0);
}

// The scene's Blinn-Phong (volume samples).
vec3 blinn_phong(vec3 color, vec3 n, vec3 ray_dir) {
    return blinn_phong_terms(color, n, ray_dir, u_phong);
}
"""
"""The conventions' Blinn–Phong of a normal, with the scene's terms or a surface material's (every GL backend
shades through it)."""

SHADING = LIGHTING + """
uniform sampler3D u_gradient;    // object-space gradient (central differences), RGB
uniform mat3 u_normal_matrix;    // object gradient -> world normal (A^-T)

// Blinn-Phong of `color` at texture point p, with the volume's gradient as the normal.
vec3 shade(vec3 color, vec3 p, vec3 ray_dir) {
    return blinn_phong(color, u_normal_matrix * texture(u_gradient, p).rgb, ray_dir);
}
"""

CUBE_VERTEX = VERSION + """
uniform mat4 u_mvp;              // texture coordinate -> clip space
in vec3 in_tex;
out vec3 v_tex;
void main() {
    v_tex = in_tex;
    gl_Position = u_mvp * vec4(in_tex, 1.0);
}
"""

SCREEN_VERTEX = VERSION + """
in vec2 in_position;
void main() {
    gl_Position = vec4(in_position, 0.5, 1.0);
}
"""

MIP_RESOLVE = """
uniform sampler2D u_res;         // r: largest scalar on the ray, g: 1 where a ray met the box
out vec4 o_color;
void main() {
    vec4 res = texelFetch(u_res, ivec2(gl_FragCoord.xy), 0);
    vec4 c = classify(res.r);
    o_color = res.g > 0.0 ? vec4(c.rgb * c.a, c.a) : vec4(0.0);
}
"""
"""Classification of a MIP target after the max-blended passes (as the reference: no correction, no shading)."""


def fragment_source(*parts, phong=False, mode=None, defines=()):
    """Assemble a fragment shader: version, defines, :data:`COMMON`, shading if ``phong``, ``parts``.

    Parameters
    ----------
    parts : str
        GLSL text appended in order (the program's own ``main``).
    phong : bool
        Define ``PHONG`` and include :data:`SHADING`.
    mode : {'dvr', 'mip', 'iso'}, optional
        Define ``MODE_DVR``, ``MODE_MIP`` or ``MODE_ISO``.
    defines : iterable of str
        Further names to define.
    """
    names = list(defines)
    if phong:
        names.append("PHONG")
    if mode is not None:
        names.append(f"MODE_{mode.upper()}")
    header = "".join(f"#define {name}\n" for name in names)
    return VERSION + header + COMMON + (SHADING if phong else "") + "".join(parts)
