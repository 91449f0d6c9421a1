"""Scene → the arrays the cl-tiled kernels read: object records, tables and camera arguments.

:data:`OBJECT_DTYPE` mirrors the ``Object`` struct of ``kernels/common.cl`` member for member
(every member 16 bytes aligned, so host and device agree on the layout without padding rules).
"""

import numpy as np

from core.transfer import MAX_GRADIENT

OBJECT_DTYPE = np.dtype([
    ("to_voxel", np.float32, (3, 4)),   # world point → continuous voxel coordinates (rows)
    ("to_world", np.float32, (3, 4)),   # object point → world point (rows)
    ("gradient", np.float32, (3, 4)),   # A^-T diag(1/2s): voxel differences → world gradient
    ("spacing", np.float32, 4),         # sx, sy, sz, reference step Δ0
    ("params", np.float32, 4),          # det(A) sign, gradient-opacity scale Δ0/(√3/2), 0, 0
    ("dims", np.int32, 4),
    ("slot", np.int32, 4),
    ("tables", np.int32, 4),            # TF offset, size, gradient table offset, size (0: none)
])
assert OBJECT_DTYPE.itemsize == 224

SCREEN_LIMIT = 2 ** 20
"""Largest pixel coordinate a vertex may project to: keeps the 64-bit edge functions exact."""


def _distinct(items):
    """``(unique items in first-seen order, index of each item)`` by identity."""
    unique, index = [], []
    for item in items:
        for k, seen in enumerate(unique):
            if seen is item:
                index.append(k)
                break
        else:
            index.append(len(unique))
            unique.append(item)
    return unique, index


def distinct_volumes(scene):
    """The scene's distinct volumes (instancing shares one atlas slot) and each instance's index."""
    return _distinct([instance.volume for instance in scene.volumes])


def tables(scene):
    """Concatenated transfer-function tables ``(M, 4)`` and gradient tables ``(K,)``, with offsets.

    Returns
    -------
    transfer, tf_offsets, gradient, gradient_offsets
        Offsets per instance; an instance without gradient opacity gets ``-1``.
    """
    tfs, tf_index = _distinct([instance.transfer_function for instance in scene.volumes])
    tf_starts = np.cumsum([0] + [tf.size for tf in tfs])
    transfer = np.concatenate([tf.table for tf in tfs]).astype(np.float32)
    gradients, g_index = _distinct([instance.gradient_opacity for instance in scene.volumes
                                    if instance.gradient_opacity is not None])
    g_starts = np.cumsum([0] + [g.table.size for g in gradients])
    gradient = (np.concatenate([g.table for g in gradients]) if gradients else np.zeros(1)).astype(np.float32)
    g_offsets, g_iter = [], iter(g_index)
    for instance in scene.volumes:
        g_offsets.append(-1 if instance.gradient_opacity is None else int(g_starts[next(g_iter)]))
    return transfer, [int(tf_starts[i]) for i in tf_index], gradient, g_offsets


def object_records(scene, slots, tf_offsets, gradient_offsets):
    """One :data:`OBJECT_DTYPE` record per volume instance (``slots``: atlas origin per instance)."""
    records = np.zeros(len(scene.volumes), dtype=OBJECT_DTYPE)
    for record, instance, slot, tf_offset, g_offset in zip(records, scene.volumes, slots, tf_offsets,
                                                          gradient_offsets):
        spacing = np.asarray(instance.volume.spacing, dtype=np.float64)
        transform = instance.transform
        inverse = np.linalg.inv(transform)
        to_voxel = inverse[:3, :] / spacing[:, None]
        to_voxel[:, 3] -= 0.5
        record["to_voxel"] = to_voxel
        record["to_world"] = transform[:3, :]
        gradient = np.zeros((3, 4))
        gradient[:, :3] = inverse[:3, :3].T / (2 * spacing)[None, :]
        record["gradient"] = gradient
        reference = instance.reference_step
        record["spacing"] = (*spacing, reference)
        record["params"] = (np.sign(np.linalg.det(transform[:3, :3])), reference / MAX_GRADIENT, 0, 0)
        record["dims"] = (*instance.volume.shape_xyz, 0)
        record["slot"] = (*slot, 0)
        gradient_opacity = instance.gradient_opacity
        record["tables"] = (tf_offset, instance.transfer_function.size, max(g_offset, 0),
                            0 if gradient_opacity is None else gradient_opacity.table.size)
    return records


def light_direction(scene):
    """The shading light in world space (given in view space; see :class:`core.scene.Shading`)."""
    right, up, back = scene.camera.basis()
    lx, ly, lz = scene.shading.light_direction
    return lx * right + ly * up + lz * back


def camera_arguments(scene):
    """``(eye, right, up, back, half_size, perspective)`` for the kernels (float64, converted by the caller).

    ``half_size`` is the half width and height of the picture in world units (orthographic) or
    the tangents of the half angles (perspective), as :meth:`core.camera.Camera.rays` uses them.
    """
    camera = scene.camera
    right, up, back = camera.basis()
    aspect = scene.width / scene.height
    if camera.projection == "perspective":
        half_h = np.tan(np.radians(camera.fov_y) / 2)
    else:
        half_h = camera.view_height / 2
    return camera.eye, right, up, back, (half_h * aspect, half_h), int(camera.projection == "perspective")


def screen_problem(scene):
    """Why the boundary geometry cannot be rasterised in this view, or ``""``.

    Perspective: every volume box must lie in front of the eye (triangles are not clipped at a
    near plane). Any projection: box corners must project within :data:`SCREEN_LIMIT` pixels.
    Points inside a box project inside the hull of its projected corners, so hulls obey too.
    """
    eye, right, up, back, (half_w, half_h), perspective = camera_arguments(scene)
    _, radius = scene.bounding_sphere()
    for instance in scene.volumes:
        v = instance.world_corners() - eye
        x, y, depth = v @ right, v @ up, -(v @ back)
        if perspective:
            if np.any(depth <= 1e-6 * radius):
                return (f"volume instance {instance.name!r} reaches behind the perspective eye; boundary triangles "
                        "are not clipped at a near plane, so every box must lie in front of the camera")
            x, y = x / depth, y / depth
        sx = (x / half_w + 1) * 0.5 * scene.width
        sy = (1 - y / half_h) * 0.5 * scene.height
        if np.abs(np.concatenate([sx, sy])).max() >= SCREEN_LIMIT:
            return (f"volume instance {instance.name!r} projects beyond {SCREEN_LIMIT} pixels from the picture; "
                    "move the camera away from it")
    return ""
