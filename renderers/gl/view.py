"""Per-frame geometry shared by the OpenGL backends: matrices, ray uniforms, step, box mesh.

The volume's box is drawn as the unit cube of texture coordinates; ``model`` maps it to world
space (object→world transform × extent), the camera's own view matrix and an OpenGL projection
whose near and far planes bracket the box take it to clip space. Images are rendered with
OpenGL's row 0 at the bottom and flipped on readback, so a fragment at window position
``(x, y)`` is the pixel centre of :meth:`core.camera.Camera.rays` at row ``H − 1 − y``.
"""

from dataclasses import dataclass

import numpy as np

from renderers.base import world_step

NEAR_FRACTION = 1e-3
"""Near plane distance as a fraction of the scene's bounding radius (perspective).

The planes only bound rasterisation (depth values are never compared except against the 0/1
written by the intermediate passes), so the near plane sits close to the eye; where it still
clips a front face, rays start analytically (see :mod:`renderers.gl.raycast`)."""

SLIVER = 1e-3
"""A partial last cell no longer than this fraction of the step is not sampled (float32 rounding
of the ray length; the reference skips slivers of 1e-9 steps in double precision)."""


def cube_triangles():
    """The unit cube as 12 triangles, counter-clockwise seen from outside, ``(36, 3)`` float32."""
    faces = []
    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        for side in (0.0, 1.0):
            quad = []
            for a, b in ((0, 0), (1, 0), (1, 1), (0, 1)):
                corner = np.zeros(3)
                corner[axis], corner[u], corner[v] = side, a, b
                quad.append(corner)
            quad = np.array(quad)
            # e_u × e_v = e_axis: counter-clockwise seen from +axis, so flip the side facing -axis.
            if side == 0.0:
                quad = quad[::-1]
            faces.extend([quad[0], quad[1], quad[2], quad[0], quad[2], quad[3]])
    return np.asarray(faces, dtype=np.float32)



@dataclass(frozen=True)
class View:
    """What one frame of one volume instance needs on the GPU.

    Attributes
    ----------
    model : numpy.ndarray
        4×4 texture coordinate → world.
    mvp : numpy.ndarray
        4×4 texture coordinate → clip space.
    step : float
        World step ``Δ`` between samples.
    uniforms : dict
        Values for :data:`renderers.gl.glsl.COMMON` and ``SHADING`` uniforms.
    mirrored : bool
        The model matrix reverses orientation (front faces wind clockwise).
    near, far : float
        Clip planes (view-space distances in front of the eye).
    """

    model: np.ndarray
    mvp: np.ndarray
    step: float
    uniforms: dict
    mirrored: bool
    near: float
    far: float


def make_view(scene, step_factor):
    """The :class:`View` of ``scene``'s first volume instance at ``step_factor`` voxels per step."""
    instance = scene.volumes[0]
    camera = scene.camera
    extent = np.asarray(instance.volume.extent, dtype=np.float64)
    model = instance.transform @ np.diag([*extent, 1.0])
    view_matrix = camera.view_matrix()
    corners = np.array([[x, y, z, 1.0] for x in (0, 1) for y in (0, 1) for z in (0, 1)])
    depths = -(view_matrix @ model @ corners.T)[2]
    _, radius = scene.bounding_sphere()
    margin = max(1e-3 * radius, 1e-6)
    far = max(float(depths.max()) + margin, 2 * margin)
    if camera.projection == "perspective":
        near = NEAR_FRACTION * radius
        half_size = np.tan(np.radians(camera.fov_y) / 2) * np.array([scene.width / scene.height, 1.0])
    else:
        # Orthographic rays start on the plane through the eye (t >= 0), as in Camera.rays.
        near = min(margin, far / 2)
        half_size = camera.view_height / 2 * np.array([scene.width / scene.height, 1.0])
    projection = camera.projection_matrix(scene.width / scene.height, near, far)
    linear = model[:3, :3]
    object_linear = instance.transform[:3, :3]
    right, up, back = camera.basis()
    lx, ly, lz = scene.shading.light_direction
    light = lx * right + ly * up + lz * back
    shading = scene.shading
    step = world_step(scene, step_factor)
    uniforms = {
        "u_extent": extent,
        "u_world_to_tex": np.linalg.inv(model),
        "u_tex_to_world": linear,
        "u_eye": camera.eye,
        "u_right": right,
        "u_up": up,
        "u_back": back,
        "u_half_size": half_size,
        "u_perspective": int(camera.projection == "perspective"),
        "u_viewport": (scene.width, scene.height),
        "u_step": step,
        "u_ref_step": instance.reference_step,
        "u_normal_matrix": np.linalg.inv(object_linear).T,
        "u_light": light,
        "u_phong": (shading.ambient, shading.diffuse, shading.specular, shading.shininess),
    }
    return View(model=model, mvp=projection @ view_matrix @ model, step=step, uniforms=uniforms,
                mirrored=bool(np.linalg.det(linear) < 0), near=near, far=far)


def ray_lengths(scene):
    """World length of every pixel ray inside the first volume's box, ``(H, W)`` (0 where it misses).

    The rays are :meth:`core.camera.Camera.rays`, clipped to ``t >= 0`` as the reference clips them.
    """
    instance = scene.volumes[0]
    origins, directions = scene.camera.rays(scene.width, scene.height)
    inverse = np.linalg.inv(instance.transform)
    o = origins @ inverse[:3, :3].T + inverse[:3, 3]
    d = directions @ inverse[:3, :3].T
    extent = np.asarray(instance.volume.extent)
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = -o / d
        tb = (extent - o) / d
    inside = (o >= 0) & (o <= extent)
    lo = np.where(d == 0, np.where(inside, -np.inf, np.inf), np.minimum(ta, tb))
    hi = np.where(d == 0, np.where(inside, np.inf, -np.inf), np.maximum(ta, tb))
    t_in = np.maximum(lo.max(axis=-1), 0.0)
    t_out = hi.min(axis=-1)
    return np.maximum(t_out - t_in, 0.0)
