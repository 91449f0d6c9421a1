"""Lens volumes (Ropinski, Steinicke & Hinrichs 2005): a convex region of the scene with its own appearance.

A :class:`Lens` is a convex solid in world space (a sphere, a box, or a closed convex mesh) with
a :class:`LensAppearance`. Along a ray it covers one interval ``[t_Lin, t_Lout]`` (convexity);
intersected with the volume's box span ``[t_in, t_out]`` it cuts the ray into at most three
regions (note 004, 2.2 and 2.8): in front of the lens ``[t_in, t_Lin]``, inside it
``[t_Lin, t_Lout]`` and behind it ``[t_Lout, t_out]``. Inside, the lens's appearance applies;
outside every lens, the scene's own (its mode and the volume's transfer function).

The semantics every backend keeps (:mod:`core.scene` has the rest of the scene contract):

* **Samples.** A ray's samples stay where they would be without the lens (one global lattice,
  ``t_k = t_first + (k + ½)·Δ``); a sample at ``t`` is classified with the lens's appearance when
  ``t_Lin <= t <= t_Lout`` and with the scene's otherwise. So a lens whose appearance equals the
  scene's changes nothing, and a lens boundary is resolved to the step, as in any segment-based
  GPU caster.
* ``clip``: samples inside the lens contribute nothing (the paper's clipping lens).
* ``dvr``: samples inside are classified by the appearance's transfer function (post-
  classification, opacity corrected for the step as everywhere) with its opacity column
  multiplied by ``opacity_scale`` and clipped to 1 entry by entry
  (:meth:`LensAppearance.classification`), and by its gradient opacity if it has one.
* ``mip``: the lens segment contributes one sample: the maximum of the volume's field over the
  segment, classified by the transfer function without opacity correction (as scene-wide
  ``mip``), composited at its place along the ray.
* ``iso``: the first place in the lens segment where ``s < isovalue`` changes from its state at
  the segment's start (as scene-wide ``iso``), shaded with the transfer function's colour at the
  isovalue, opaque; nothing if the segment has no crossing.

``mip`` and ``iso`` use the volume's own transfer function where the appearance gives none.
"""

from dataclasses import KW_ONLY, dataclass, replace

import numpy as np

from core.errors import InputError
from core.mesh import Mesh
from core.transfer import GradientOpacity, TransferFunction
from core.validation import check_choice, check_finite_vector, check_matrix4, check_positive_vector, check_scalar

LENS_SHAPES = ("sphere", "box", "mesh")
LENS_MODES = ("clip", "dvr", "iso", "mip")

CONVEXITY_TOLERANCE = 1e-9
"""How far a mesh vertex may lie outside a face's plane, relative to the mesh's diameter, for the
mesh to count as convex (coplanar faces of a polytope carry rounding of about 1e-16)."""


def translation(offset):
    """4×4 translation by ``offset``."""
    matrix = np.eye(4)
    matrix[:3, 3] = offset
    return matrix


@dataclass(frozen=True, eq=False)
class LensAppearance:
    """What a lens shows inside (see the module notes for each mode).

    Parameters
    ----------
    mode : {'clip', 'dvr', 'iso', 'mip'}
    transfer_function : TransferFunction, optional
        ``dvr``: required. ``iso`` (the surface's colour) and ``mip``: ``None`` uses the volume's.
        ``clip``: not allowed.
    gradient_opacity : GradientOpacity, optional
        ``dvr`` only.
    opacity_scale : float, optional
        ``dvr`` only, ``>= 0``: multiplies the table's opacity (a transparency lens below 1).
    isovalue : float, optional
        ``iso`` only, required, normalised in [0, 1].

    Raises
    ------
    InputError
        An unknown mode, a missing field the mode needs, or a field the mode does not use.
    """

    mode: str
    _: KW_ONLY
    transfer_function: TransferFunction | None = None
    gradient_opacity: GradientOpacity | None = None
    opacity_scale: float = 1.0
    isovalue: float | None = None

    def __post_init__(self):
        check_choice(self.mode, LENS_MODES, name="lens appearance mode")
        where = f"lens appearance {self.mode!r}"
        if self.transfer_function is not None and not isinstance(self.transfer_function, TransferFunction):
            raise InputError(f"{where}: transfer_function must be a TransferFunction, "
                             f"got {type(self.transfer_function).__name__}")
        if self.gradient_opacity is not None and not isinstance(self.gradient_opacity, GradientOpacity):
            raise InputError(f"{where}: gradient_opacity must be a GradientOpacity, "
                             f"got {type(self.gradient_opacity).__name__}")
        object.__setattr__(self, "opacity_scale", check_scalar(self.opacity_scale, name=f"{where} opacity_scale", low=0))
        unused = []
        if self.mode == "clip" and self.transfer_function is not None:
            unused.append("transfer_function")
        if self.mode != "dvr" and self.gradient_opacity is not None:
            unused.append("gradient_opacity")
        if self.mode != "dvr" and self.opacity_scale != 1.0:
            unused.append("opacity_scale")
        if self.mode != "iso" and self.isovalue is not None:
            unused.append("isovalue")
        if unused:
            raise InputError(f"{where}: {', '.join(unused)} does not apply to this mode; remove it "
                             "(dvr: transfer_function, gradient_opacity, opacity_scale; iso: isovalue and an optional "
                             "transfer_function; mip: an optional transfer_function; clip: nothing)")
        if self.mode == "dvr" and self.transfer_function is None:
            raise InputError(f"{where}: needs a transfer_function (in a scene file: a preset of the volume's data set "
                             "or transfer_function points)")
        if self.mode == "iso":
            if self.isovalue is None:
                raise InputError(f"{where}: needs an isovalue in [0, 1]")
            object.__setattr__(self, "isovalue", check_scalar(self.isovalue, name=f"{where} isovalue", low=0, high=1))

    def classification(self, outside):
        """The transfer function samples inside the lens are classified with.

        ``outside`` is the volume's own transfer function, used by ``iso`` and ``mip`` where the
        appearance has none. ``dvr``: the appearance's table with its opacity multiplied by
        ``opacity_scale`` and clipped to 1 entry by entry (the same table object when the scale
        is 1, so an unscaled lens classifies bit for bit as its table). ``clip``: ``None``.
        """
        if self.mode == "clip":
            return None
        tf = self.transfer_function if self.transfer_function is not None else outside
        if self.opacity_scale == 1.0:
            return tf
        table = tf.table.copy()
        table[:, 3] = np.minimum(table[:, 3].astype(np.float64) * self.opacity_scale, 1.0)
        return replace(tf, table=table, name=f"{tf.name}×{self.opacity_scale:g}")


def _convex_half_spaces(mesh, *, where):
    """Outward unit normals and offsets ``(n, c)`` of ``mesh``'s face planes (inside: ``n·x <= c``).

    Raises
    ------
    InputError
        A face of zero area, or a vertex outside a face's plane (the mesh is not convex).
    """
    normals = mesh.face_normals()
    if mesh.signed_volume() < 0:
        normals = -normals  # faces wound clockwise seen from outside: flip so normals point out
    norms = np.linalg.norm(normals, axis=1)
    lo, hi = mesh.bounds()
    diameter = float(np.linalg.norm(hi - lo))
    if not (norms > 1e-12 * diameter ** 2).all():
        raise InputError(f"{where}: face {int(np.argmin(norms))} has zero area; remove degenerate faces")
    normals = normals / norms[:, None]
    offsets = np.einsum("ij,ij->i", normals, mesh.vertices[mesh.faces[:, 0]])
    outside = mesh.vertices @ normals.T - offsets  # (V, F): > 0 is outside that face's plane
    worst = np.unravel_index(np.argmax(outside), outside.shape)
    if outside[worst] > CONVEXITY_TOLERANCE * diameter:
        raise InputError(f"{where}: the mesh {mesh.name!r} is not convex (vertex {worst[0]} lies "
                         f"{outside[worst]:.3g} outside the plane of face {worst[1]}); a lens must be a convex solid, "
                         "so that a ray meets it in one interval: use its convex hull (trimesh's convex_hull) or "
                         "a sphere or box")
    return normals, offsets


@dataclass(frozen=True, eq=False)
class Lens:
    """A convex lens volume with its appearance (see the module notes).

    Parameters
    ----------
    shape : {'sphere', 'box', 'mesh'}
    center : sequence of 3 floats
        World position: the sphere's centre, the box's centre, the origin of the mesh's object space.
    appearance : LensAppearance
    radius : float
        ``sphere`` only, ``> 0``.
    size : sequence of 3 floats
        ``box`` only: edge lengths along the box's own axes, each ``> 0``.
    mesh : Mesh
        ``mesh`` only: a closed convex mesh in its own object space.
    transform : array_like, shape (4, 4), optional
        ``box`` and ``mesh``: object→lens affine transform applied before ``center`` moves it
        (rotate or scale the box about its centre); the identity by default.
    name : str, optional

    Raises
    ------
    InputError
        A field the shape needs is missing or one it does not use is given, a value out of range,
        or a mesh that is not convex.

    Notes
    -----
    :meth:`object_to_world` is ``translate(center) @ transform``. A box is the half-spaces
    ``±x_i <= size_i/2`` of its own frame and a mesh the planes of its faces
    (:meth:`half_spaces`); a ray ``o + t·d`` is clipped against them in that frame
    (``o' = M⁻¹o``, ``d' = M⁻¹d`` unnormalised, so ``t`` stays the world ray's parameter).
    """

    shape: str
    _: KW_ONLY
    center: tuple
    appearance: LensAppearance
    radius: float | None = None
    size: tuple | None = None
    mesh: Mesh | None = None
    transform: np.ndarray | None = None
    name: str = "lens"

    def __post_init__(self):
        check_choice(self.shape, LENS_SHAPES, name=f"lens {self.name!r} shape")
        where = f"lens {self.name!r} ({self.shape})"
        object.__setattr__(self, "center", check_finite_vector(self.center, length=3, name=f"{where} center"))
        if not isinstance(self.appearance, LensAppearance):
            raise InputError(f"{where}: appearance must be a LensAppearance, got {type(self.appearance).__name__}")
        needs = {"sphere": ("radius",), "box": ("size",), "mesh": ("mesh",)}[self.shape]
        fields = ("radius", "size", "mesh", "transform")
        allowed = needs + (() if self.shape == "sphere" else ("transform",))
        extra = [f for f in fields if f not in allowed and getattr(self, f) is not None]
        if extra:
            raise InputError(f"{where}: {', '.join(extra)} does not apply to a {self.shape} lens; remove it "
                             "(sphere: center, radius; box: center, size, transform; mesh: center, mesh, transform)")
        missing = [f for f in needs if getattr(self, f) is None]
        if missing:
            raise InputError(f"{where}: needs {', '.join(missing)}")
        if self.shape == "sphere":
            object.__setattr__(self, "radius", check_scalar(self.radius, name=f"{where} radius", low=0, low_open=True))
        if self.shape == "box":
            object.__setattr__(self, "size", check_positive_vector(self.size, length=3, name=f"{where} size"))
        if self.shape == "mesh":
            if not isinstance(self.mesh, Mesh):
                raise InputError(f"{where}: mesh must be a Mesh, got {type(self.mesh).__name__}")
            _convex_half_spaces(self.mesh, where=where)
        if self.shape != "sphere":
            transform = np.eye(4) if self.transform is None else self.transform
            matrix = check_matrix4(transform, name=f"{where} transform")
            matrix.flags.writeable = False
            object.__setattr__(self, "transform", matrix)

    def object_to_world(self):
        """The lens's object→world matrix, ``translate(center) @ transform`` (a sphere: the translation)."""
        return translation(self.center) @ (np.eye(4) if self.transform is None else self.transform)

    def half_spaces(self):
        """``(normals, offsets)``: the lens is ``n·x <= c`` for every row, in its object frame.

        A box gives its six slab planes; a mesh its face planes (outward unit normals). A sphere
        has none (it is a quadric: :meth:`object_to_world` and ``radius`` describe it).
        """
        if self.shape == "box":
            half = np.asarray(self.size) / 2
            normals = np.concatenate([np.eye(3), -np.eye(3)])
            return normals, np.concatenate([half, half])
        if self.shape == "mesh":
            return _convex_half_spaces(self.mesh, where=f"lens {self.name!r} (mesh)")
        return np.zeros((0, 3)), np.zeros(0)

    def world_half_spaces(self):
        """The lens's faces in world space: unit outward normals and offsets ``(n, c)``, inside ``n·x <= c``
        (none for a sphere)."""
        matrix = self.object_to_world()
        normals, offsets = self.half_spaces()
        world = normals @ np.linalg.inv(matrix[:3, :3])  # n·A⁻¹(x − t) <= c
        offsets = offsets + world @ matrix[:3, 3]
        norms = np.linalg.norm(world, axis=1)
        return world / norms[:, None], offsets / norms

    def contains(self, points):
        """Whether each world point (``(..., 3)``) lies in the closed lens."""
        points = np.asarray(points, dtype=np.float64)
        if self.shape == "sphere":
            return np.sum((points - np.asarray(self.center)) ** 2, axis=-1) <= self.radius ** 2
        normals, offsets = self.world_half_spaces()
        return np.all(points @ normals.T <= offsets, axis=-1)

    def voxel_mask(self, volume, transform):
        """The lens voxelised on ``volume``'s grid placed in the world by ``transform``: ``(nz, ny, nx)``
        bool, true where the voxel's centre lies in the lens (what a backend that classifies voxels, not
        ray samples, uses: a mask texture, a label map, per-voxel classification). One z-slice at a
        time, so the memory is a slice's points."""
        nx, ny, nz = volume.shape_xyz
        sx, sy, sz = volume.spacing
        y, x = np.meshgrid((np.arange(ny) + 0.5) * sy, (np.arange(nx) + 0.5) * sx, indexing="ij")
        transform = np.asarray(transform, dtype=np.float64)
        mask = np.zeros((nz, ny, nx), bool)
        for k in range(nz):
            points = np.stack([x, y, np.full_like(x, (k + 0.5) * sz)], axis=-1)
            mask[k] = self.contains(points @ transform[:3, :3].T + transform[:3, 3])
        return mask
