"""Shared by the exact iso-surface tests of gl-raycast and cl-tiled: the reference's crossing on a ray, random rays
through random cells, and the thin features a sampled hit steps over (a one-voxel sheet, a tube thinner than a step)."""

import numpy as np

from core.camera import Camera
from core.scene import Scene, Shading, VolumeInstance
from core.transfer import TransferFunction
from core.volume import Volume
from renderers.reference import raycast as reference_walk

ISO = TransferFunction.from_points([(0, 0.9, 0.6, 0.3, 1), (1, 0.9, 0.6, 0.3, 1)], name="iso-colour")


def reference_crossings(volume, base, slope, iso):
    """The reference walk's first crossing on ``t`` in [0, 1] of each ray ``base + t·slope`` (lattice coordinates of
    ``volume``, z-y-x, unit spacing), ``inf`` where there is none."""
    nz, ny, nx = volume.shape
    flat = np.ascontiguousarray(volume, dtype=float).ravel()
    return np.array([reference_walk._walk_volume(flat, 0, nx, ny, nz, *b, *s, 0.0, 1.0, True, iso, 1e-13, np.inf)[1]
                     for b, s in zip(base, slope)])


def normal_angles(volume, hits, normals, where):
    """Degrees between ``normals[i]`` and the reference's normal at ``hits[i]`` (lattice coordinates x, y, z: central
    differences one voxel apart of the trilinear field) for the rays ``where`` selects. Where the reference's
    gradient is nearly zero (a saddle) its direction is undefined: hits with |∇s| < 0.05 per voxel are left out."""
    nz, ny, nx = volume.shape
    flat = np.ascontiguousarray(volume, dtype=float).ravel()
    angles = []
    for i in np.flatnonzero(where):
        expected = np.array(reference_walk._gradient(flat, 0, nx, ny, nz, *hits[i], 1.0, 1.0, 1.0))
        if np.linalg.norm(expected) >= 0.05:
            cosine = normals[i] @ expected / (np.linalg.norm(normals[i]) * np.linalg.norm(expected))
            angles.append(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))))
    return np.array(angles)


def random_rays(seed, shape, count=512):
    """``(volume, base, slope)``: a random volume of ``shape`` (z, y, x) and ``count`` random rays through and
    around it, in its lattice coordinates."""
    rng = np.random.default_rng(seed)
    volume = rng.uniform(0.0, 1.0, shape)
    base = rng.uniform(-0.5, np.array(shape[::-1]) - 0.5, (count, 3))
    return volume, base, rng.normal(0.0, 2.5, (count, 3))


def thin_scene(data, *, azimuth=37.0, elevation=23.0, size=48):
    """An unshaded iso scene of ``data`` at isovalue 0.5."""
    return Scene((VolumeInstance(Volume(data.astype(np.float32), name="thin"), ISO, isovalue=0.5),),
                 camera=Camera(azimuth=azimuth, elevation=elevation), width=size, height=size,
                 shading=Shading(model="none"), mode="iso")


def sheet(n=24):
    """A one-voxel-thick sheet: one slab of voxels at 0.6 in a volume of 0, so the trilinear field reaches the
    isovalue 0.5 within 1/6 voxel of the slab's centre (a surface a third of a voxel thick)."""
    data = np.zeros((n, n, n))
    data[:, :, n // 2] = 0.6
    return data


def tube(n=24, radius=0.6):
    """A tube along z thinner than a step: 1 on an axis line off the lattice, 0 at ``2 · radius`` from it, so
    above the isovalue 0.5 in a band a few tenths of a voxel across."""
    z, y, x = np.meshgrid(*(np.arange(n, dtype=float),) * 3, indexing="ij")
    r = np.hypot(x - n / 2 - 0.3, y - n / 2 + 0.2)
    return np.clip(1.0 - r / (2 * radius), 0.0, 1.0)
