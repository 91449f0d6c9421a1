"""Closed triangle meshes and what a scene puts on them (Kainz et al. 2009, §3 and Fig. 2).

A :class:`Mesh` is geometry only, in its own object space; a :class:`MeshInstance` places one in
the world with an object→world transform and gives it a :class:`SurfaceMaterial` (what is drawn
where a ray crosses its boundary) and/or a :class:`HomogeneousMedium` (what fills its interior).
Several instances may share one Mesh (instancing). Volumes may also be bounded by a Mesh
(``VolumeInstance.boundary``), and CSG trees over instances live in :mod:`core.scene`.

Inside and outside are defined by ray parity: a point is inside a closed mesh when a ray from it
crosses the surface an odd number of times. That needs a closed, two-manifold, consistently
oriented surface, which :class:`Mesh` checks on construction.
"""

import hashlib
from dataclasses import dataclass, field

import numpy as np

from core.errors import InputError
from core.validation import check_finite_vector, check_matrix4, check_scalar


def _edge_problems(faces):
    """Why ``faces`` is not a closed, two-manifold, consistently oriented surface ("" if it is).

    Each directed edge ``(a, b)`` of such a surface occurs exactly once and its reverse ``(b, a)``
    exactly once: an edge with no reverse is a hole, one occurring twice in the same direction is
    either shared by more than two triangles or joins two triangles of opposite orientation.
    """
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    unique, counts = np.unique(directed, axis=0, return_counts=True)
    if (counts > 1).any():
        a, b = unique[np.argmax(counts > 1)]
        return (f"{int((counts > 1).sum())} directed edges occur more than once (e.g. {a}→{b}): an edge is "
                "shared by more than two triangles, or neighbouring triangles have opposite orientation")
    keys = unique[:, 0] * (faces.max() + 1) + unique[:, 1]
    reverse = unique[:, 1] * (faces.max() + 1) + unique[:, 0]
    open_edges = ~np.isin(reverse, keys)
    if open_edges.any():
        a, b = unique[np.argmax(open_edges)]
        return f"not closed: {int(open_edges.sum())} edges belong to one triangle only (e.g. {a}→{b})"
    return ""


@dataclass(frozen=True, eq=False)
class Mesh:
    """A closed, two-manifold, consistently oriented triangle mesh in its own object space.

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
        Finite coordinates, stored as float64.
    faces : array_like, shape (F, 3)
        Vertex indices of each triangle, stored as int64. At least 4 triangles (a tetrahedron).
    name : str, optional
    meta : dict, optional
        Provenance: generator and parameters, file path, triangle count before decimation.

    Raises
    ------
    InputError
        Wrong shapes or dtypes, non-finite vertices, indices out of range, a triangle that
        repeats a vertex, or a surface that is not closed, two-manifold and consistently
        oriented (the message says which edge; ``trimesh.repair`` or the generator's repair step
        fixes most).

    Notes
    -----
    Both arrays are stored read-only: backends cache per-Mesh packed copies.
    """

    vertices: np.ndarray
    faces: np.ndarray
    name: str = "mesh"
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        where = f"mesh {self.name!r}"
        try:
            vertices = np.array(self.vertices, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"{where} vertices: expected a (V, 3) array of numbers") from None
        if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) < 4:
            raise InputError(f"{where} vertices: expected a (V, 3) array with V >= 4, got shape {vertices.shape}")
        if not np.isfinite(vertices).all():
            raise InputError(f"{where} vertices: contain NaN or infinite coordinates")
        faces = np.asarray(self.faces)
        if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) < 4:
            raise InputError(f"{where} faces: expected an (F, 3) array with F >= 4, got shape {faces.shape}")
        if faces.dtype.kind not in "iu":
            raise InputError(f"{where} faces: expected integer vertex indices, got dtype {faces.dtype}")
        faces = faces.astype(np.int64)
        if faces.min() < 0 or faces.max() >= len(vertices):
            raise InputError(f"{where} faces: indices must lie in [0, {len(vertices) - 1}], "
                             f"got [{faces.min()}, {faces.max()}]")
        repeated = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
        if repeated.any():
            raise InputError(f"{where} faces: {int(repeated.sum())} triangles repeat a vertex "
                             f"(e.g. triangle {int(np.argmax(repeated))}); remove degenerate faces")
        problem = _edge_problems(faces)
        if problem:
            raise InputError(f"{where}: must be a closed, two-manifold, consistently oriented surface so that "
                             f"inside and outside are defined; {problem}")
        for array in (vertices, faces):
            array.flags.writeable = False
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "faces", faces)

    @property
    def triangle_count(self):
        return len(self.faces)

    def bounds(self):
        """Object-space axis-aligned bounds, ``(min_xyz, max_xyz)``."""
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    def face_normals(self):
        """Unnormalised face normals ``(b − a) × (c − a)``, shape (F, 3), object space.

        They point outwards when the faces wind counter-clockwise seen from outside.
        """
        a, b, c = (self.vertices[self.faces[:, i]] for i in range(3))
        return np.cross(b - a, c - a)

    def signed_volume(self):
        """Enclosed volume, positive for outward-facing (counter-clockwise) winding."""
        a, b, c = (self.vertices[self.faces[:, i]] for i in range(3))
        return float(np.einsum("ij,ij->", a, np.cross(b, c)) / 6.0)

    def content_hash(self):
        """Hex digest of the vertices and faces: stable across runs and machines."""
        digest = hashlib.sha256()
        digest.update(np.ascontiguousarray(self.vertices).tobytes())
        digest.update(np.ascontiguousarray(self.faces).tobytes())
        return digest.hexdigest()[:16]


def _colour(value, *, name):
    colour = check_finite_vector(value, length=3, name=name)
    if not all(0.0 <= c <= 1.0 for c in colour):
        raise InputError(f"{name}: every channel must lie in [0, 1], got {colour}")
    return colour


@dataclass(frozen=True)
class SurfaceMaterial:
    """What is drawn where a ray crosses a mesh instance's visible boundary.

    Parameters
    ----------
    colour : tuple of 3 floats in [0, 1]
        Unpremultiplied RGB.
    alpha : float in [0, 1]
        Opacity of one crossing; below 1 the surface is translucent (feature
        ``translucent_geometry``).
    ambient, diffuse, specular, shininess : float
        Blinn–Phong terms, the formula of :class:`core.scene.Shading` with the triangle's normal
        (two-sided) instead of the gradient; applied when the scene's shading model is
        ``phong``, with the scene's light. Under ``none`` the surface shows its flat colour.

    Notes
    -----
    A crossing composites front to back like a volume sample:
    ``C += (1 − A)·alpha·shaded_colour``, ``A += (1 − A)·alpha``.
    """

    colour: tuple = (1.0, 1.0, 1.0)
    alpha: float = 1.0
    ambient: float = 0.3
    diffuse: float = 0.7
    specular: float = 0.3
    shininess: float = 20.0

    def __post_init__(self):
        object.__setattr__(self, "colour", _colour(self.colour, name="surface material colour"))
        object.__setattr__(self, "alpha", check_scalar(self.alpha, name="surface material alpha", low=0, high=1))
        for term in ("ambient", "diffuse", "specular"):
            object.__setattr__(self, term, check_scalar(getattr(self, term), name=f"surface material {term}", low=0))
        object.__setattr__(self, "shininess", check_scalar(self.shininess, name="surface material shininess",
                                                           low=0, low_open=True))

    @property
    def translucent(self):
        return self.alpha < 1.0


@dataclass(frozen=True)
class HomogeneousMedium:
    """A constant emission–absorption material filling a mesh instance's interior.

    Parameters
    ----------
    colour : tuple of 3 floats in [0, 1]
        Unpremultiplied RGB.
    extinction : float >= 0
        ``σ``, optical depth per world unit: a path of world length ``L`` through the medium alone
        has opacity ``α = 1 − exp(−σ·L)`` and premultiplied colour ``α·colour``, composited
        analytically (no sampling). This is CONVENTIONS' opacity correction
        ``1 − (1 − α0)^(L/Δ0)`` with ``σ = −ln(1 − α0)/Δ0``; :meth:`from_opacity` converts.

    Notes
    -----
    Where media overlap, their extinctions add and the colour is the ``σ``-weighted mean (the
    exact solution of emission–absorption); where a medium overlaps a volume, the medium's
    opacity over the sample's length joins the volume samples' sum like one more volume
    (Kainz et al. 2009 blending, see :mod:`core.scene`).
    """

    colour: tuple = (1.0, 1.0, 1.0)
    extinction: float = 1.0

    def __post_init__(self):
        object.__setattr__(self, "colour", _colour(self.colour, name="medium colour"))
        object.__setattr__(self, "extinction", check_scalar(self.extinction, name="medium extinction", low=0))

    @classmethod
    def from_opacity(cls, alpha, length, *, colour=(1.0, 1.0, 1.0)):
        """The medium whose path of world ``length`` has opacity ``alpha`` (in [0, 1))."""
        alpha = check_scalar(alpha, name="medium opacity", low=0, high=1, high_open=True)
        length = check_scalar(length, name="medium opacity length", low=0, low_open=True)
        return cls(colour=colour, extinction=-np.log1p(-alpha) / length)

    def opacity(self, length):
        """``1 − exp(−σ·length)`` for a world ``length``."""
        return float(-np.expm1(-self.extinction * length))


@dataclass(frozen=True, eq=False)
class MeshInstance:
    """One placement of a :class:`Mesh` in the scene.

    Parameters
    ----------
    mesh : Mesh
        May be shared with other instances (instancing: only the transform and materials differ).
    transform : array_like, shape (4, 4), optional
        Object→world affine transform; identity by default (meshes are modelled in world units,
        unlike volume boxes there is nothing to centre).
    surface : SurfaceMaterial, optional
        Drawn where a ray crosses the instance's visible boundary; ``None``: the boundary is
        invisible.
    medium : HomogeneousMedium, optional
        Fills the interior where the instance contributes; ``None``: the interior is empty.
        An instance with neither is a pure CSG operand (a clip or cut-away shape).
    name : str, optional
        Defaults to the mesh's name; CSG leaves refer to instances by name.
    """

    mesh: Mesh
    transform: np.ndarray | None = None
    surface: SurfaceMaterial | None = None
    medium: HomogeneousMedium | None = None
    name: str = ""

    def __post_init__(self):
        if not isinstance(self.mesh, Mesh):
            raise InputError(f"mesh instance {self.name!r}: mesh must be a Mesh, got {type(self.mesh).__name__}")
        if not self.name:
            object.__setattr__(self, "name", self.mesh.name)
        if self.surface is not None and not isinstance(self.surface, SurfaceMaterial):
            raise InputError(f"mesh instance {self.name!r}: surface must be a SurfaceMaterial or None")
        if self.medium is not None and not isinstance(self.medium, HomogeneousMedium):
            raise InputError(f"mesh instance {self.name!r}: medium must be a HomogeneousMedium or None")
        transform = np.eye(4) if self.transform is None else self.transform
        matrix = check_matrix4(transform, name=f"mesh instance {self.name!r} transform")
        matrix.flags.writeable = False
        object.__setattr__(self, "transform", matrix)

    def world_vertices(self):
        """The mesh's vertices in world space, shape (V, 3)."""
        return self.mesh.vertices @ self.transform[:3, :3].T + self.transform[:3, 3]
