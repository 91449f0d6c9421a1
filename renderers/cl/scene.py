"""Scene → the arrays the cl-tiled kernels read: objects, leaves, the CSG program, tables, camera.

:data:`OBJECT_DTYPE` mirrors the ``Object`` struct of ``kernels/common.cl`` member for member
(every member 16 bytes aligned, so host and device agree on the layout without padding rules).

Objects and leaves
------------------
An *object* is one closed triangle mesh whose crossings toggle one bit of the pixel kernel's
64-bit inside mask; a *leaf* is what the CSG semantics of :mod:`core.scene` talk about. Leaves
are numbered as the reference numbers them: volume instances ``0 … V − 1``, then mesh instances
``V … L − 1``. Object ``i < L`` is leaf ``i``'s own boundary (a volume's box or hull, a mesh
instance's mesh); objects ``L, L + 1, …`` are the polygonal boundaries of the volumes that have
one, and a volume leaf is inside where both its box (or hull) and its boundary are.
"""

from dataclasses import dataclass

import numpy as np

from core.transfer import MAX_GRADIENT

OBJECT_DTYPE = np.dtype([
    ("to_voxel", np.float32, (3, 4)),   # world point → continuous voxel coordinates (rows)
    ("to_world", np.float32, (3, 4)),   # object point → world point (rows)
    ("gradient", np.float32, (3, 4)),   # A^-T diag(1/2s): voxel differences → world gradient
    ("spacing", np.float32, 4),         # sx, sy, sz, reference step Δ0
    ("params", np.float32, 4),          # det(A) sign, gradient-opacity scale Δ0/(√3/2), isovalue (NaN: none), 0
    ("dims", np.int32, 4),
    ("slot", np.int32, 4),
    ("tables", np.int32, 4),            # TF offset, size, gradient table offset, size (0: none)
])
assert OBJECT_DTYPE.itemsize == 224

MAX_OBJECTS = 64
"""Objects per scene: the inside set is one 64-bit mask."""

OP_LEAF, OP_UNION, OP_INTERSECTION, OP_DIFFERENCE = 0, 1, 2, 3
OP_FIRST = 4
"""Flag on a node's operation code: the node is its parent's first child (what a difference keeps)."""
OPERATION_CODES = {"union": OP_UNION, "intersection": OP_INTERSECTION, "difference": OP_DIFFERENCE}

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


def _mask(indices):
    bits = 0
    for index in indices:
        bits |= 1 << index
    return np.uint64(bits)


@dataclass(frozen=True)
class Leaves:
    """The scene's leaves, objects and CSG forest as the pixel kernel reads them.

    Attributes
    ----------
    count : int
        Leaves ``L``: volume instances, then mesh instances.
    boundary_volumes : tuple of int
        Volume instance bounded by object ``L + j``, per ``j``.
    masks : dict of numpy.uint64
        Bits over leaves: ``leaves`` (all), ``volumes``, ``surfaces`` (mesh instances with a
        surface material), ``media`` (with a medium), ``trees`` (leaves of a CSG tree); and
        ``volume_objects``, the volumes' own box or hull objects (the cells' anchor is the first
        entry into one of them, as the reference's is the entry into the union of the boxes).
    materials : numpy.ndarray, shape (L, 3, 4), float32
        Per leaf: surface colour and alpha; ambient, diffuse, specular, shininess; medium colour
        and extinction ``σ`` (zeros where the leaf has none).
    nodes : numpy.ndarray, shape (N, 4), int32
        The CSG forest in postfix order (children before parents): operation code (with
        :data:`OP_FIRST`), leaf index (leaves) or first entry in ``children`` (operations),
        child count, parent index (``-1`` for roots). Standalone leaves are not in it.
    children : numpy.ndarray, int32
        Child node indices of the operations, contiguous per node.
    """

    count: int
    boundary_volumes: tuple
    masks: dict
    materials: np.ndarray
    nodes: np.ndarray
    children: np.ndarray

    @property
    def objects(self):
        return self.count + len(self.boundary_volumes)


def leaves(scene):
    """The :class:`Leaves` of ``scene`` (see the module notes)."""
    nvol = len(scene.volumes)
    count = nvol + len(scene.meshes)
    names = [v.name for v in scene.volumes] + [m.name for m in scene.meshes]
    materials = np.zeros((count, 3, 4), np.float32)
    for i, instance in enumerate(scene.meshes, start=nvol):
        if instance.surface is not None:
            surface = instance.surface
            materials[i, 0] = (*surface.colour, surface.alpha)
            materials[i, 1] = (surface.ambient, surface.diffuse, surface.specular, surface.shininess)
        if instance.medium is not None:
            materials[i, 2] = (*instance.medium.colour, instance.medium.extinction)
    nodes, children = [], []

    def emit(node):
        if isinstance(node, str):
            nodes.append([OP_LEAF, names.index(node), 0, -1])
            return len(nodes) - 1
        ids = [emit(child) for child in node.children]
        nodes.append([OPERATION_CODES[node.operation], len(children), len(ids), -1])
        children.extend(ids)
        for position, child in enumerate(ids):
            nodes[child][3] = len(nodes) - 1
            nodes[child][0] |= OP_FIRST if position == 0 else 0
        return len(nodes) - 1

    for tree in scene.csg:
        emit(tree)
    in_trees = [names.index(name) for tree in scene.csg for name in tree.leaves()]
    masks = {
        "leaves": _mask(range(count)),
        "volumes": _mask(range(nvol)),
        "surfaces": _mask(nvol + i for i, m in enumerate(scene.meshes) if m.surface is not None),
        "media": _mask(nvol + i for i, m in enumerate(scene.meshes) if m.medium is not None),
        "trees": _mask(in_trees),
    }
    return Leaves(count=count, boundary_volumes=tuple(i for i, v in enumerate(scene.volumes) if v.boundary is not None),
                  masks=masks, materials=materials,
                  nodes=np.array(nodes, np.int32).reshape(-1, 4), children=np.array(children, np.int32))


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
    transfer = (np.concatenate([tf.table for tf in tfs]) if tfs else np.zeros((1, 4))).astype(np.float32)
    gradients, g_index = _distinct([instance.gradient_opacity for instance in scene.volumes
                                    if instance.gradient_opacity is not None])
    g_starts = np.cumsum([0] + [g.table.size for g in gradients])
    gradient = (np.concatenate([g.table for g in gradients]) if gradients else np.zeros(1)).astype(np.float32)
    g_offsets, g_iter = [], iter(g_index)
    for instance in scene.volumes:
        g_offsets.append(-1 if instance.gradient_opacity is None else int(g_starts[next(g_iter)]))
    return transfer, [int(tf_starts[i]) for i in tf_index], gradient, g_offsets


def object_records(scene, slots, tf_offsets, gradient_offsets):
    """One :data:`OBJECT_DTYPE` record per object (see the module notes; ``slots``: atlas origin per volume).

    Mesh instances and volume boundaries only need the object→world transform and its
    orientation for binning; the sampling members stay zero.
    """
    placed = [m.transform for m in scene.meshes] + [v.transform for v in scene.volumes if v.boundary is not None]
    records = np.zeros(len(scene.volumes) + len(placed), dtype=OBJECT_DTYPE)
    for record, transform in zip(records[len(scene.volumes):], placed):
        record["to_world"] = transform[:3, :]
        record["params"] = (np.sign(np.linalg.det(transform[:3, :3])), 0, 0, 0)
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
        isovalue = np.nan if instance.isovalue is None else instance.isovalue
        record["params"] = (np.sign(np.linalg.det(transform[:3, :3])), reference / MAX_GRADIENT, isovalue, 0)
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


def rasterisation(scene):
    """How the binning rasterises this view: ``(homogeneous, problem)``.

    Snapped integer edge functions (``homogeneous`` False, exact) need every box corner and mesh
    vertex in front of the eye and projected within :data:`SCREEN_LIMIT` pixels. Points inside a
    box project inside the hull of its projected corners, so hulls and volume boundaries (inside
    the box) obey too. A perspective view where some geometry reaches behind the eye (an eye
    inside a volume or a mesh) or projects further is rasterised with homogeneous edge functions
    instead (``kernels/binning.cl``, ``HOMOGENEOUS``). An orthographic view that projects further
    cannot be rasterised: ``problem`` says why (``""`` otherwise).
    """
    eye, right, up, back, (half_w, half_h), perspective = camera_arguments(scene)
    _, radius = scene.bounding_sphere()
    placed = [(f"volume instance {v.name!r}", v.world_corners()) for v in scene.volumes]
    placed += [(f"mesh instance {m.name!r}", m.world_vertices()) for m in scene.meshes]
    for label, points in placed:
        v = points - eye
        x, y, depth = v @ right, v @ up, -(v @ back)
        if perspective:
            if np.any(depth <= 1e-6 * radius):
                return True, ""
            x, y = x / depth, y / depth
        sx = (x / half_w + 1) * 0.5 * scene.width
        sy = (1 - y / half_h) * 0.5 * scene.height
        if np.abs(np.concatenate([sx, sy])).max() >= SCREEN_LIMIT:
            if perspective:
                return True, ""
            return False, f"{label} projects beyond {SCREEN_LIMIT} pixels from the picture; move the camera away from it"
    return False, ""


def winding_number(point, mesh):
    """The generalised winding number of closed ``mesh`` around ``point`` (its object space).

    The sum of the solid angles its triangles subtend at ``point`` over ``4π`` (van Oosterom and
    Strackee 1983): ±1 inside a closed mesh and 0 outside, whatever the triangulation, with no
    ray to graze an edge or a vertex.
    """
    a, b, c = (mesh.vertices[mesh.faces[:, k]] - point for k in range(3))
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    volume = np.einsum("ij,ij->i", a, np.cross(b, c))
    denominator = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la
                   + np.einsum("ij,ij->i", c, a) * lb)
    return float(np.arctan2(volume, denominator).sum() / (2 * np.pi))


def eye_inside(scene, leaves):
    """The objects (bits, as :func:`leaves` numbers them) whose inside holds a perspective eye.

    A perspective ray starts at the eye, so the pixel kernel starts it inside these; an
    orthographic ray finds them from the crossings behind its origin (0 here). A volume whose box
    holds the eye is its box object (the caller gives it no hull); mesh instances and volume
    boundaries are tested by their winding number.
    """
    if scene.camera.projection != "perspective":
        return np.uint64(0)
    eye = np.append(scene.camera.eye, 1.0)
    names = set(scene.camera_inside_volume())
    objects = [i for i, v in enumerate(scene.volumes) if v.name in names]
    placed = [(m.mesh, m.transform) for m in scene.meshes]
    placed += [(scene.volumes[i].boundary, scene.volumes[i].transform) for i in leaves.boundary_volumes]
    for index, (mesh, transform) in enumerate(placed, start=len(scene.volumes)):
        if abs(winding_number(np.linalg.solve(transform, eye)[:3], mesh)) > 0.5:
            objects.append(index)
    return _mask(objects)
