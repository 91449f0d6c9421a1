"""The declarative scene every backend renders (CONVENTIONS, all sections).

A scene holds only what it uses: volume instances (data, transform, classification), the camera,
the image size, the mode and the shading. Later features (closed meshes with CSG, lens volumes)
are optional fields that default to empty, so a scene that does not use them does not carry them,
and :meth:`Scene.features` lists what a scene needs so that backends can refuse early.

Lens volumes (Ropinski et al. 2005)
-----------------------------------
``lenses`` holds at most one :class:`~core.lens.Lens`: a convex region rendered with its own
appearance (clip, dvr, iso or mip; semantics in :mod:`core.lens`) while the scene's own appearance
applies outside it. A lens scene has one volume (the lens re-classifies that volume; its ``dvr``
preset is the volume's data set's), mode ``dvr`` (the outside appearance of the paper: context
DVR around the region of interest) and no meshes, boundaries or CSG. One lens is the paper's
case; several would need a rule where they overlap and more than three regions per ray, so a
second lens is refused rather than rendered by a rule no backend shares. The lens does not
count in :meth:`Scene.bounds`: the camera frames the volume, and a lens may reach past it.

Meshes and CSG (Kainz et al. 2009)
----------------------------------
Every instance, volume or mesh, is a *leaf* with an inside: a volume's inside is its box,
intersected with the interior of its ``boundary`` mesh when it has one; a mesh instance's inside
is its interior by ray parity. A :class:`CsgNode` tree combines named leaves (``union``,
``intersection``, ``difference``); an instance in no tree stands alone. Along a ray the fragments
(boundary crossings) cut it into segments with a fixed set of active (inside) leaves, and in each
segment a leaf *contributes* when it is active and every CSG node above it lets it through:
``union`` passes its children through; ``intersection`` passes them only where all its children
are inside; ``difference`` passes its first child only where the first is inside and none of the
others is, and never passes the others (they only carve). A volume contributes its own transfer
function's samples only where it contributes (so a volume is sampled only inside its boundary and
where its CSG expression holds); a mesh instance contributes its :class:`~core.mesh.HomogeneousMedium`.
Contributions of several leaves in one place are blended as overlapping volumes are (CONVENTIONS:
premultiplied colours and corrected opacities summed, the opacity clamped to 1).

A crossing of a mesh instance is drawn with its :class:`~core.mesh.SurfaceMaterial` where it is a
boundary of its tree's solid: where the root's inside/outside changes across it (for a standalone
instance, every crossing). So the cut face that a ``difference`` leaves is drawn with the material
of the subtracted instance if it has one, and not at all if it has none (the paper's toggle of
"including the boundary in the operation"). Along the ray everything is composited front to back
in depth order: the material between the previous crossing and a surface, then the surface, then
what lies behind it.

In ``iso`` a volume contributes no samples but its iso-surface: the first place in its contributing
intervals where ``s < isovalue`` differs from its state where the ray entered its box, opaque. So a
boundary or CSG cut through the inside of a surface shows the cut face (a cap), as a ``dvr`` cut
through opaque material does; surfaces and media in front of it composite as in ``dvr``. ``mip`` is
defined on volumes only: meshes, boundaries and CSG are refused there.
"""

from dataclasses import dataclass, field, replace

import numpy as np

from core.volume import Volume
from core.camera import Camera
from core.errors import InputError
from core.lens import Lens
from core.mesh import Mesh, MeshInstance
from core.resources import check_memory, largest_fitting
from core.transfer import GradientOpacity, TransferFunction
from core.validation import check_choice, check_finite_vector, check_matrix4, check_positive_int, check_scalar

MODES = ("dvr", "mip", "iso")
SHADING_MODELS = ("none", "phong")
CSG_OPERATIONS = ("union", "intersection", "difference")

IMAGE_BYTES_PER_PIXEL = 16
"""A rendered image's bytes per pixel: float32 RGBA (CONVENTIONS, Cameras and images)."""


def check_image_size(width, height, *, name):
    """``(width, height)`` as positive ints whose image this machine can hold.

    Backends add their own per-pixel buffers to this in their ``check``.

    Raises
    ------
    InputError
        A size that is not a positive integer, or an image larger than the machine's memory
        (the message names the most pixels that fit).
    """
    width = check_positive_int(width, name=f"{name} width")
    height = check_positive_int(height, name=f"{name} height")

    def fix(limit):
        pixels = largest_fitting(limit, IMAGE_BYTES_PER_PIXEL)
        side = largest_fitting(limit, IMAGE_BYTES_PER_PIXEL, power=2)
        return f"use width × height ≤ {pixels} pixels (e.g. {side}×{side})"

    check_memory(width * height * IMAGE_BYTES_PER_PIXEL, what=f"{name} image {width}×{height}",
                 detail=f"{IMAGE_BYTES_PER_PIXEL} bytes a pixel, float32 RGBA", fix=fix)
    return width, height


def centering_transform(volume):
    """Object→world transform that puts the centre of ``volume``'s box on the world origin."""
    matrix = np.eye(4)
    matrix[:3, 3] = -0.5 * np.asarray(volume.extent)
    return matrix


@dataclass(frozen=True, eq=False)
class VolumeInstance:
    """One placement of a volume in the scene with its own classification.

    Parameters
    ----------
    volume : Volume
    transfer_function : TransferFunction
    transform : array_like, shape (4, 4), optional
        Object→world affine transform; ``None`` centres the box on the world origin.
    gradient_opacity : GradientOpacity, optional
        Multiplies opacity by ``g(|∇s|)``.
    isovalue : float, optional
        Normalised isovalue used in ``iso`` mode.
    name : str, optional
    boundary : Mesh, optional
        A closed polygonal boundary in the volume's object space (the frame of its box
        ``[0, extent]``, moved by ``transform``): the volume is sampled only inside both the box
        and this mesh (a tight hull, a segmentation region). ``None``: the box alone. Its
        crossings are never drawn.
    """

    volume: Volume
    transfer_function: TransferFunction
    transform: np.ndarray | None = None
    gradient_opacity: GradientOpacity | None = None
    isovalue: float | None = None
    name: str = ""
    boundary: Mesh | None = None

    def __post_init__(self):
        if not isinstance(self.volume, Volume):
            raise InputError(f"volume instance {self.name!r}: volume must be a Volume, got {type(self.volume).__name__}")
        if not isinstance(self.transfer_function, TransferFunction):
            raise InputError(f"volume instance {self.name!r}: transfer_function must be a TransferFunction")
        if self.gradient_opacity is not None and not isinstance(self.gradient_opacity, GradientOpacity):
            raise InputError(f"volume instance {self.name!r}: gradient_opacity must be a GradientOpacity")
        transform = centering_transform(self.volume) if self.transform is None else self.transform
        object.__setattr__(self, "transform", check_matrix4(transform, name=f"volume instance {self.name!r} transform"))
        if self.isovalue is not None:
            object.__setattr__(self, "isovalue", check_scalar(self.isovalue, name=f"volume instance {self.name!r} isovalue", low=0, high=1))
        if not self.name:
            object.__setattr__(self, "name", self.volume.name)
        if self.boundary is not None and not isinstance(self.boundary, Mesh):
            raise InputError(f"volume instance {self.name!r}: boundary must be a Mesh or None, "
                             f"got {type(self.boundary).__name__}")

    @property
    def reference_step(self):
        """``Δ0`` in object units: the TF's own, else the volume's smallest spacing."""
        step = self.transfer_function.reference_step
        return self.volume.min_spacing if step is None else step

    def world_corners(self):
        """The eight corners of the object box in world space, shape (8, 3)."""
        ex, ey, ez = self.volume.extent
        corners = np.array([[x, y, z, 1.0] for x in (0, ex) for y in (0, ey) for z in (0, ez)])
        return (corners @ self.transform.T)[:, :3]


@dataclass(frozen=True)
class Shading:
    """Blinn–Phong parameters, the same for every backend.

    ``colour = c·(ambient + diffuse·|N·L|) + specular·|N·H|^shininess``, clamped to [0, 1] per
    sample, with ``N = −∇s/|∇s|`` (two-sided), ``L`` the unit direction towards a directional light
    given in view space (default: a headlight) and ``H = normalise(L + V)``, ``V`` pointing to the
    viewer. Where ``|∇s|`` is 0 the normal is undefined and only the ambient term applies.
    The gradient is taken in the volume's object space and carried to world space by the inverse
    transpose of the object→world transform, so scaled or sheared volumes shade correctly.
    """

    model: str = "none"
    ambient: float = 0.3
    diffuse: float = 0.7
    specular: float = 0.3
    shininess: float = 20.0
    light_direction: tuple = (0.0, 0.0, 1.0)

    def __post_init__(self):
        check_choice(self.model, SHADING_MODELS, name="shading model")
        for term in ("ambient", "diffuse", "specular"):
            check_scalar(getattr(self, term), name=f"shading {term}", low=0)
        check_scalar(self.shininess, name="shading shininess", low=0, low_open=True)
        light = np.asarray(check_finite_vector(self.light_direction, length=3, name="shading light_direction"))
        if np.linalg.norm(light) == 0:
            raise InputError("shading light_direction: must not be the zero vector")
        object.__setattr__(self, "light_direction", tuple(light / np.linalg.norm(light)))


@dataclass(frozen=True, eq=False)
class CsgNode:
    """A CSG operation over named instances and sub-trees (see the module notes for the semantics).

    Parameters
    ----------
    operation : {'union', 'intersection', 'difference'}
        ``difference`` subtracts every child after the first from the first.
    children : sequence of str or CsgNode
        At least two; a string names a volume or mesh instance of the scene.
    """

    operation: str
    children: tuple

    def __post_init__(self):
        check_choice(self.operation, CSG_OPERATIONS, name="csg operation")
        if isinstance(self.children, (str, CsgNode)) or not np.iterable(self.children):
            raise InputError(f"csg {self.operation}: children must be a list of instance names or CSG nodes")
        children = tuple(self.children)
        if len(children) < 2:
            raise InputError(f"csg {self.operation}: needs at least two children, got {len(children)}")
        for child in children:
            if not isinstance(child, (str, CsgNode)) or child == "":
                raise InputError(f"csg {self.operation}: a child must be an instance name or a CsgNode, got {child!r}")
        object.__setattr__(self, "children", children)

    def leaves(self):
        """Instance names of the leaves, left to right."""
        return [name for child in self.children
                for name in ((child,) if isinstance(child, str) else child.leaves())]


@dataclass(frozen=True, eq=False)
class Scene:
    """What to render.

    Parameters
    ----------
    volumes : sequence of VolumeInstance
        At least one volume or mesh instance in all.
    camera : Camera, optional
        Unset ``distance``/``view_height`` are framed to the scene's bounding sphere.
    width, height : int
        Image size in pixels.
    mode : {'dvr', 'mip', 'iso'}
    shading : Shading, optional
    name : str, optional
    meshes : sequence of MeshInstance, optional
        Closed meshes with surface materials and/or homogeneous interiors (``dvr`` and ``iso``).
    csg : sequence of CsgNode, optional
        CSG trees; each leaf names exactly one instance of the scene, and an instance is a leaf
        of at most one tree. Instances in no tree stand alone.
    lenses : sequence of Lens, optional
        At most one lens volume (see the module notes): it needs exactly one volume instance,
        mode ``dvr`` and no meshes, boundaries or CSG.
    """

    volumes: tuple = ()
    camera: Camera = field(default_factory=Camera)
    width: int = 256
    height: int = 256
    mode: str = "dvr"
    shading: Shading = field(default_factory=Shading)
    name: str = "scene"
    meshes: tuple = ()
    csg: tuple = ()
    lenses: tuple = ()

    def __post_init__(self):
        volumes = tuple(self.volumes) if not isinstance(self.volumes, VolumeInstance) else (self.volumes,)
        for instance in volumes:
            if not isinstance(instance, VolumeInstance):
                raise InputError(f"scene {self.name!r}: volumes must be VolumeInstance objects, got {type(instance).__name__}")
        object.__setattr__(self, "volumes", volumes)
        meshes = tuple(self.meshes) if not isinstance(self.meshes, MeshInstance) else (self.meshes,)
        for instance in meshes:
            if not isinstance(instance, MeshInstance):
                raise InputError(f"scene {self.name!r}: meshes must be MeshInstance objects, got {type(instance).__name__}")
        object.__setattr__(self, "meshes", meshes)
        if not volumes and not meshes:
            raise InputError(f"scene {self.name!r}: needs at least one volume or mesh instance")
        csg = tuple(self.csg) if not isinstance(self.csg, CsgNode) else (self.csg,)
        self._check_csg(csg)
        object.__setattr__(self, "csg", csg)
        check_image_size(self.width, self.height, name=f"scene {self.name!r}")
        check_choice(self.mode, MODES, name=f"scene {self.name!r} mode")
        if not isinstance(self.camera, Camera):
            raise InputError(f"scene {self.name!r}: camera must be a Camera")
        if not isinstance(self.shading, Shading):
            raise InputError(f"scene {self.name!r}: shading must be a Shading")
        if self.has_geometry() and self.mode == "mip":
            raise InputError(f"scene {self.name!r}: meshes, volume boundaries and CSG render in modes 'dvr' and "
                             "'iso' (a maximum intensity projection is defined on volumes), got mode 'mip'")
        self._check_lenses()
        with np.errstate(over="ignore", invalid="ignore"):  # overflow is refused just below
            center, radius = self.bounding_sphere()
        if not (np.isfinite(center).all() and np.isfinite(radius)):
            raise InputError(f"scene {self.name!r}: its bounds overflow float64 (centre {center.tolist()}, radius "
                             f"{radius}); use smaller spacings, scales or translations")
        object.__setattr__(self, "camera", self.camera.framed(center, radius))

    def _check_csg(self, trees):
        names = [v.name for v in self.volumes] + [m.name for m in self.meshes]
        used = set()
        for tree in trees:
            if not isinstance(tree, CsgNode):
                raise InputError(f"scene {self.name!r}: csg must hold CsgNode trees, got {type(tree).__name__}")
            for leaf in tree.leaves():
                if names.count(leaf) != 1:
                    found = "no instance" if leaf not in names else f"{names.count(leaf)} instances"
                    raise InputError(f"scene {self.name!r} csg: leaf {leaf!r} must name exactly one volume or mesh "
                                     f"instance, found {found}; instances: {sorted(set(names))}")
                if leaf in used:
                    raise InputError(f"scene {self.name!r} csg: instance {leaf!r} is a leaf more than once; "
                                     "instance its mesh or volume again under another name instead")
                used.add(leaf)

    def _check_lenses(self):
        lenses = tuple(self.lenses) if not isinstance(self.lenses, Lens) else (self.lenses,)
        for lens in lenses:
            if not isinstance(lens, Lens):
                raise InputError(f"scene {self.name!r}: lenses must be Lens objects, got {type(lens).__name__}")
        object.__setattr__(self, "lenses", lenses)
        if not lenses:
            return
        where = f"scene {self.name!r} lenses"
        if len(lenses) > 1:
            raise InputError(f"{where}: {len(lenses)} lenses given, at most one is supported (the paper's case: one "
                             "convex lens, at most three regions per ray; overlapping lenses have no shared rule); "
                             "merge them into one convex lens or render one scene per lens")
        if len(self.volumes) != 1:
            raise InputError(f"{where}: a lens re-classifies the scene's one volume, and the scene has "
                             f"{len(self.volumes)}; render a lens scene with exactly one volume")
        if self.mode != "dvr":
            raise InputError(f"{where}: a lens scene's own appearance (outside the lens) is dvr, got mode "
                             f"{self.mode!r}; set mode: dvr and give the lens appearance {{mode: {self.mode}}} for "
                             f"{self.mode} inside it")
        if self.has_geometry():
            raise InputError(f"{where}: lenses and meshes, volume boundaries or CSG cannot be combined; remove one")

    def has_geometry(self):
        """Whether the scene has mesh instances, volume boundaries or CSG (anything beyond boxes)."""
        return bool(self.meshes or self.csg or any(v.boundary is not None for v in self.volumes))

    def bounds(self):
        """World-space axis-aligned bounds of all volume boxes and mesh instances, ``(min_xyz, max_xyz)``."""
        points = np.concatenate([v.world_corners() for v in self.volumes] + [m.world_vertices() for m in self.meshes])
        return points.min(axis=0), points.max(axis=0)

    def min_world_voxel_size(self):
        """Smallest world-space voxel edge over all volumes (``|A·e_i|·s_i``, transforms included).

        The unit of every backend's ``step_factor``: a step of 1 is one such voxel edge.

        Raises
        ------
        InputError
            The scene has no volume, so there is no voxel to measure a step by.
        """
        if not self.volumes:
            raise InputError(f"scene {self.name!r}: has no volume, so no voxel size; give an absolute step instead")
        return min(float(np.min(np.linalg.norm(v.transform[:3, :3], axis=0) * np.asarray(v.volume.spacing)))
                   for v in self.volumes)

    def bounding_sphere(self):
        lo, hi = self.bounds()
        return (lo + hi) / 2, float(np.linalg.norm(hi - lo) / 2)

    def with_camera(self, **changes):
        """A copy with camera fields replaced (e.g. another view of a sweep)."""
        return replace(self, camera=replace(self.camera, **changes))

    def features(self):
        """The capabilities this scene needs, as ``{capability: value}``.

        Keys match :class:`renderers.base.Capabilities` fields, so a backend can check a scene
        before rendering it.
        """
        needs = {
            "projections": self.camera.projection,
            "modes": self.mode,
            "shading": self.shading.model,
            "max_volumes": len(self.volumes),
        }
        if any(v.gradient_opacity is not None for v in self.volumes):
            needs["gradient_opacity"] = True
        if any(not np.allclose(v.transform, centering_transform(v.volume)) for v in self.volumes):
            needs["transforms"] = True
        if any(v.volume.spacing[0] != v.volume.spacing[1] or v.volume.spacing[1] != v.volume.spacing[2]
               for v in self.volumes):
            needs["anisotropic_spacing"] = True
        if self.meshes or any(v.boundary is not None for v in self.volumes):
            needs["meshes"] = True
        if self.csg:
            needs["csg"] = True
        if any(m.surface is not None and m.surface.translucent for m in self.meshes):
            needs["translucent_geometry"] = True
        if any(m.medium is not None for m in self.meshes):
            needs["homogeneous_media"] = True
        if self.lenses:
            needs["lenses"] = True
        return needs

    def camera_inside_volume(self):
        """Names of the volume instances whose box contains the eye (perspective cameras)."""
        eye = np.append(self.camera.eye, 1.0)
        inside = []
        for instance in self.volumes:
            p = np.linalg.solve(instance.transform, eye)[:3]
            if np.all(p > 0) and np.all(p < np.asarray(instance.volume.extent)):
                inside.append(instance.name)
        return inside
