"""Orbit camera and the ray set it defines (CONVENTIONS, Cameras and images).

World space is right-handed with ``+y`` up by default. Azimuth 0, elevation 0 puts the eye on the
``+z`` axis of the target looking down ``−z`` (OpenGL's default view); azimuth turns the eye
towards ``+x``, elevation lifts it towards ``up``. View space has ``x`` right, ``y`` up and the
camera looking down ``−z``. Image row 0 is the top of the picture and pixel centres are at
half-integer positions.
"""

import functools
from dataclasses import dataclass, replace

import numpy as np

from core.errors import InputError
from core.validation import check_choice, check_finite_vector, check_scalar

PROJECTIONS = ("orthographic", "perspective")


@dataclass(frozen=True)
class Camera:
    """Orbit camera.

    Parameters
    ----------
    azimuth, elevation : float
        Degrees.
    distance : float, optional
        Eye to target. ``None`` lets the scene frame its bounding sphere.
    target : tuple of float
        World-space point looked at.
    up : tuple of float
        World-space up vector (must not be parallel to the view direction).
    projection : {'orthographic', 'perspective'}
    view_height : float, optional
        Orthographic: world-space height of the picture. ``None`` frames the scene.
    fov_y : float
        Perspective: vertical field of view in degrees.
    """

    azimuth: float = 0.0
    elevation: float = 0.0
    distance: float | None = None
    target: tuple = (0.0, 0.0, 0.0)
    up: tuple = (0.0, 1.0, 0.0)
    projection: str = "orthographic"
    view_height: float | None = None
    fov_y: float = 30.0

    def __post_init__(self):
        object.__setattr__(self, "azimuth", check_scalar(self.azimuth, name="camera azimuth"))
        object.__setattr__(self, "elevation", check_scalar(self.elevation, name="camera elevation", low=-90, high=90))
        object.__setattr__(self, "target", check_finite_vector(self.target, length=3, name="camera target"))
        object.__setattr__(self, "up", check_finite_vector(self.up, length=3, name="camera up"))
        check_choice(self.projection, PROJECTIONS, name="camera projection")
        if self.distance is not None:
            object.__setattr__(self, "distance", check_scalar(self.distance, name="camera distance", low=0, low_open=True))
        if self.view_height is not None:
            object.__setattr__(self, "view_height", check_scalar(self.view_height, name="camera view_height", low=0, low_open=True))
        object.__setattr__(self, "fov_y", check_scalar(self.fov_y, name="camera fov_y", low=0, high=180, low_open=True, high_open=True))
        self._check_basis()

    def _check_basis(self):
        """Refuse an ``up`` that cannot span a view frame: zero, or parallel to the view direction.

        Either gives a zero ``right`` vector, so every ray would be NaN (and a renderer could loop
        on it). ``up`` is compared as a unit vector with the view direction; below a sine of 1e-6
        (a 0.0002° angle) the frame is numerically meaningless. This covers elevation ±90 with the
        default ``up = +y`` and any ``up`` along the line of sight at any elevation.
        """
        up = np.asarray(self.up, dtype=np.float64)
        length = np.linalg.norm(up)
        if not length > 0:
            raise InputError(f"camera up: must be a non-zero vector, got {self.up}; the default is (0, 1, 0)")
        forward = -self._offset_direction()
        if np.linalg.norm(np.cross(forward, up / length)) < 1e-6:
            raise InputError(
                f"camera: up {self.up} is parallel to the view direction (azimuth {self.azimuth}, "
                f"elevation {self.elevation}); choose another up vector (e.g. (0, 0, -1) looking "
                "straight down) or an elevation away from ±90"
            )

    def _offset_direction(self):
        az, el = np.radians(self.azimuth), np.radians(self.elevation)
        return np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])

    def framed(self, center, radius):
        """A copy with ``distance`` / ``view_height`` filled so a sphere fits the picture height.

        Only the fields left as ``None`` are filled; the target moves to ``center`` only if it
        was left at the origin default and the scene is off-centre.
        """
        updates = {}
        if self.distance is None:
            if self.projection == "perspective":
                updates["distance"] = 1.05 * radius / np.sin(np.radians(self.fov_y) / 2)
            else:
                updates["distance"] = 3.0 * radius
        if self.view_height is None and self.projection == "orthographic":
            updates["view_height"] = 2.1 * radius
        return replace(self, **updates) if updates else self

    @property
    def eye(self):
        if self.distance is None:
            raise InputError("camera: distance is not set; frame the camera with a scene first")
        return np.asarray(self.target) + self.distance * self._offset_direction()

    def basis(self):
        """World-space unit vectors ``(right, up, back)`` of the view frame (read-only arrays).

        Computed once per camera: a camera is immutable, and backends that render in a few
        milliseconds ask for its frame several times a frame.
        """
        return self._frame

    @functools.cached_property
    def _frame(self):
        back = self._offset_direction()
        right = np.cross(np.asarray(self.up, dtype=np.float64), back)
        length = np.linalg.norm(right)
        if not (np.isfinite(length) and length > 0):  # unreachable through __post_init__; never NaN rays
            raise InputError(f"camera: up {self.up} and the view direction do not span a view frame")
        right /= length
        up = np.cross(back, right)
        for vector in (right, up, back):
            vector.flags.writeable = False
        return right, up, back

    def view_matrix(self):
        """4×4 world→view matrix (what ``gluLookAt`` builds)."""
        right, up, back = self.basis()
        rotation = np.stack([right, up, back])
        matrix = np.eye(4)
        matrix[:3, :3] = rotation
        matrix[:3, 3] = -rotation @ self.eye
        return matrix

    def projection_matrix(self, aspect, near, far):
        """4×4 OpenGL-style view→clip matrix for ``aspect = width / height``."""
        if not 0 < near < far:
            raise InputError(f"camera: expected 0 < near < far, got near={near}, far={far}")
        matrix = np.zeros((4, 4))
        if self.projection == "orthographic":
            half_h = self.view_height / 2
            half_w = half_h * aspect
            matrix[0, 0] = 1 / half_w
            matrix[1, 1] = 1 / half_h
            matrix[2, 2] = -2 / (far - near)
            matrix[2, 3] = -(far + near) / (far - near)
            matrix[3, 3] = 1
        else:
            f = 1 / np.tan(np.radians(self.fov_y) / 2)
            matrix[0, 0] = f / aspect
            matrix[1, 1] = f
            matrix[2, 2] = (far + near) / (near - far)
            matrix[2, 3] = 2 * far * near / (near - far)
            matrix[3, 2] = -1
        return matrix

    def rays(self, width, height):
        """Ray origins and unit directions for every pixel, float64, shape ``(H, W, 3)`` each.

        Orthographic rays start on the plane through the eye; perspective rays start at the eye.
        Rays travel for ``t >= 0`` only.
        """
        right, up, back = self.basis()
        # Pixel centres in normalised [-1, 1] coordinates; row 0 is the top.
        xs = (np.arange(width) + 0.5) / width * 2 - 1
        ys = 1 - (np.arange(height) + 0.5) / height * 2
        px, py = np.meshgrid(xs, ys)
        eye = self.eye
        if self.projection == "orthographic":
            half_h = self.view_height / 2
            half_w = half_h * width / height
            origins = eye + (px * half_w)[..., None] * right + (py * half_h)[..., None] * up
            directions = np.broadcast_to(-back, origins.shape).copy()
        else:
            half_h = np.tan(np.radians(self.fov_y) / 2)
            half_w = half_h * width / height
            directions = (px * half_w)[..., None] * right + (py * half_h)[..., None] * up - back
            directions /= np.linalg.norm(directions, axis=-1, keepdims=True)
            origins = np.broadcast_to(eye, directions.shape).copy()
        return origins, directions
