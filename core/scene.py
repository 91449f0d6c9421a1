"""The declarative scene every backend renders (CONVENTIONS, all sections).

A scene holds only what it uses: volume instances (data, transform, classification), the camera,
the image size, the mode and the shading. Later features (polygon meshes with CSG, lens volumes)
are optional fields that default to empty, so a scene that does not use them does not carry them,
and :meth:`Scene.features` lists what a scene needs so that backends can refuse early.
"""

from dataclasses import dataclass, field, replace

import numpy as np

from core.volume import Volume
from core.camera import Camera
from core.errors import InputError
from core.transfer import GradientOpacity, TransferFunction
from core.validation import check_choice, check_finite_vector, check_matrix4, check_positive_int, check_scalar

MODES = ("dvr", "mip", "iso")
SHADING_MODELS = ("none", "phong")


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
    """

    volume: Volume
    transfer_function: TransferFunction
    transform: np.ndarray | None = None
    gradient_opacity: GradientOpacity | None = None
    isovalue: float | None = None
    name: str = ""

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
class Scene:
    """What to render.

    Parameters
    ----------
    volumes : sequence of VolumeInstance
        At least one.
    camera : Camera, optional
        Unset ``distance``/``view_height`` are framed to the volumes' bounding sphere.
    width, height : int
        Image size in pixels.
    mode : {'dvr', 'mip', 'iso'}
    shading : Shading, optional
    name : str, optional
    """

    volumes: tuple
    camera: Camera = field(default_factory=Camera)
    width: int = 256
    height: int = 256
    mode: str = "dvr"
    shading: Shading = field(default_factory=Shading)
    name: str = "scene"

    def __post_init__(self):
        volumes = tuple(self.volumes) if not isinstance(self.volumes, VolumeInstance) else (self.volumes,)
        if not volumes:
            raise InputError(f"scene {self.name!r}: needs at least one volume instance")
        for instance in volumes:
            if not isinstance(instance, VolumeInstance):
                raise InputError(f"scene {self.name!r}: volumes must be VolumeInstance objects, got {type(instance).__name__}")
        object.__setattr__(self, "volumes", volumes)
        check_positive_int(self.width, name=f"scene {self.name!r} width")
        check_positive_int(self.height, name=f"scene {self.name!r} height")
        check_choice(self.mode, MODES, name=f"scene {self.name!r} mode")
        if not isinstance(self.camera, Camera):
            raise InputError(f"scene {self.name!r}: camera must be a Camera")
        if not isinstance(self.shading, Shading):
            raise InputError(f"scene {self.name!r}: shading must be a Shading")
        center, radius = self.bounding_sphere()
        object.__setattr__(self, "camera", self.camera.framed(center, radius))

    def bounds(self):
        """World-space axis-aligned bounds of all volume boxes, ``(min_xyz, max_xyz)``."""
        corners = np.concatenate([v.world_corners() for v in self.volumes])
        return corners.min(axis=0), corners.max(axis=0)

    def min_world_voxel_size(self):
        """Smallest world-space voxel edge over all volumes (``|A·e_i|·s_i``, transforms included).

        The unit of every backend's ``step_factor``: a step of 1 is one such voxel edge.
        """
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
