"""Head phantoms: the MRI head (note 000), the CT phantom skull (003, 001, 004) and the folded
brain in a head (003's MR "brain" / "brainsmall").

Lengths are in normalised units (the longest axis is 1); the comments give them in voxels at 256,
the size the notes describe. Axes: x left→right, y front (face, −y) → back, z feet → crown.
"""

import numpy as np

from datasets import noise
from datasets.shapes import (
    Box, Canvas, Capsule, Cylinder, Ellipsoid, Grid, Offset, Shell, SmoothUnion, Sphere, Torus,
    rotation,
)
from core.volume import Volume
from core.errors import InputError

V = 1 / 256
"""One voxel at the notes' reference size, in normalised units."""


def mri_head(size, seed):
    """T1-like MRI head for Krüger & Westermann's "MRI head" (note 000 §6).

    Ellipsoidal head on a neck and shoulders that leave through the bottom face; a bright scalp
    (≈185, 4–5 voxels), a dark skull (≈38, 6 voxels), thin CSF (≈45), grey (≈100) and white
    matter (≈140 ± 15 of low-frequency noise), two eyes (≈60). Rician noise of σ 6.4 gives the
    background a Rayleigh floor of mean ≈ 8, sd ≈ 4 that the transfer function has to cut off.

    The note's two numbers disagree: semi-axes of (92, 113, 102) voxels fill only ≈30 % of the
    box, not the 40–45 % that "55–60 % outside" implies (and that the real MRI head in the data
    folder shows). The head is therefore (108, 122, 114) voxels, with shoulders, and fills ≈38 %.
    """
    rng = np.random.default_rng(seed)
    grid = Grid.for_aspect(size)
    canvas = Canvas(grid)
    head = Ellipsoid((0, 0, 0.05), (108 * V, 122 * V, 114 * V))
    neck = Capsule((0, 0.03, -0.12), (0, 0.03, -0.8), 0.24)
    shoulders = Ellipsoid((0, 0.03, -0.56), (0.48, 0.26, 0.16))
    body = SmoothUnion(SmoothUnion(head, neck, 0.06), shoulders, 0.08)
    scalp, skull, csf = 4.5 * V, 6 * V, 2 * V
    texture = noise.fbm(grid, noise.fork(rng), wavelength=0.35, octaves=3)
    canvas.paint(body, 185 + 8 * texture)
    canvas.paint(Offset(body, -scalp), 90 + 6 * texture)
    canvas.paint(Offset(head, -scalp), 38)
    canvas.paint(Offset(head, -(scalp + skull)), 45)
    canvas.paint(Offset(head, -(scalp + skull + csf)), 100 + 6 * texture)
    canvas.paint(Offset(head, -(scalp + skull + csf + 14 * V)), 140 + 15 * texture)
    for side in (-1, 1):
        canvas.paint(Sphere((side * 0.125, -0.33, 0.02), 12 * V), 60)
    noise.rician(canvas.data, noise.fork(rng), 6.4)
    return Volume(canvas.to_uint8(), name="mri_head")


def _skull_thickness(base):
    """Skull thickness ``base`` thinning to 40 % at the temples (note 001: 3–10 voxels)."""
    def thickness(x, y, z):
        temple = np.exp(-(((z - 0.02) / 0.09) ** 2)) * np.minimum((x / 0.33) ** 2, 1)
        return np.float32(base) * (1 - np.float32(0.6) * temple)
    return thickness


def ct_skull(size, seed):
    """CT head phantom: soft tissue over a two-table skull with face, jaw, teeth and vertebrae.

    Note 003's "phantom skull" (air 0, soft tissue ≈90, skull shell 5–8 voxels at ≈220 with
    orbits, nasal aperture, foramen magnum, sinus air pockets, mandible, teeth ≈250, cervical
    vertebrae), note 001's "Head" (thinner at the temples, neck leaving through the bottom face)
    and note 004's skull (outer and inner tables around a darker, trabecular diploë, 3.7–9
    voxels thick, thinnest at the temples). A subcutaneous fat layer (≈68) under the skin makes
    the air/tissue boundary a few voxels thick, as in CT, so a skin band in the transfer
    function shows a surface rather than a film.
    """
    rng = np.random.default_rng(seed)
    grid = Grid.for_aspect(size)
    canvas = Canvas(grid)
    texture = noise.fbm(grid, noise.fork(rng), wavelength=0.3, octaves=3)
    trabecular = noise.fbm(grid, noise.fork(rng), wavelength=10 * V, octaves=1)

    cranium = Ellipsoid((0, 0.03, 0.1), (0.33, 0.40, 0.33))
    face = Ellipsoid((0, -0.13, -0.12), (0.26, 0.30, 0.24))
    neck = Capsule((0, 0.08, -0.15), (0, 0.08, -0.8), 0.17)
    nose = Capsule((0, -0.43, -0.03), (0, -0.47, -0.12), 0.03, 0.022)
    soft = SmoothUnion(SmoothUnion(SmoothUnion(Offset(cranium, 6 * V), face, 0.08), neck, 0.08), nose, 0.03)
    tissue = canvas.paint(soft, 90 + 6 * texture)
    canvas.paint(Shell(Offset(soft, -1 * V), 4 * V), 68 + 4 * texture)      # subcutaneous fat

    cortical, spongy = 220, 170 + 35 * trabecular
    thickness = _skull_thickness(0.036)
    canvas.paint(Shell(cranium, thickness), cortical)
    diploe = Shell(Offset(cranium, lambda x, y, z: -0.3 * thickness(x, y, z)),
                   lambda x, y, z: 0.4 * thickness(x, y, z))
    canvas.paint(diploe, spongy)
    canvas.paint(Offset(cranium, lambda x, y, z: -thickness(x, y, z)), 100 + 5 * texture)

    # Face: maxilla with the maxillary sinuses, zygomatic arches, frontal and sphenoid sinuses.
    maxilla = Box((0, -0.28, -0.1), (0.12, 0.09, 0.07), rounding=0.04)
    canvas.paint(maxilla, cortical)
    canvas.paint(Offset(maxilla, -4 * V), 0)
    for side in (-1, 1):
        canvas.paint(Capsule((side * 0.11, -0.27, -0.07), (side * 0.3, -0.05, -0.03), 4 * V), cortical)
    for center, radii in (((0, -0.33, 0.13), (0.06, 0.022, 0.035)), ((0, -0.1, -0.06), (0.04, 0.035, 0.03))):
        canvas.paint(Ellipsoid(center, np.add(radii, 3 * V)), cortical)
        canvas.paint(Ellipsoid(center, radii), 0)
    canvas.paint(Ellipsoid((0, -0.39, -0.07), (0.035, 0.07, 0.05)), 0)      # nasal aperture
    for side in (-1, 1):                                                      # orbits
        orbit = grid.region(Capsule((side * 0.11, -0.42, 0.0), (side * 0.06, -0.22, 0.02), 0.055, 0.018))
        canvas.paint(orbit.intersect(tissue), 70)
    canvas.paint(Cylinder((0, 0.09, -0.4), (0, 0.09, -0.1), 0.05), 95)       # foramen magnum

    # Mandible: a U-shaped tube (cortex around cancellous bone) with two rami up to the joints.
    theta = np.linspace(-1.2, 1.2, 17)
    arch = np.stack([0.2 * np.sin(theta), 0.04 - 0.34 * np.cos(theta), np.full_like(theta, -0.26)], axis=1)
    bone_path = [*zip(arch[:-1], arch[1:])]
    for end, side in ((arch[0], -1), (arch[-1], 1)):
        bone_path.append((end, (side * 0.24, 0.03, -0.07)))
    jaw = [Capsule(a, b, 6 * V) for a, b in bone_path]
    canvas.paint(grid.union(jaw), cortical)
    canvas.paint(grid.union(Capsule(a, b, 4 * V) for a, b in bone_path), spongy)

    # Teeth: two arches of 12 cylinders each, occluding at z = -0.19.
    for t in np.linspace(-0.95, 0.95, 12):
        x, y = 0.19 * np.sin(t), 0.04 - 0.33 * np.cos(t)
        canvas.paint(Cylinder((x, y, -0.245), (x, y, -0.192), 2.8 * V), 250)
        canvas.paint(Cylinder((x, y, -0.188), (x, y, -0.14), 2.8 * V), 250)

    # Cervical vertebrae: a body (cortex + cancellous core) and a ring around the spinal canal.
    for k in range(5):
        z = -0.31 - 0.055 * k
        body = Cylinder((0, 0.04, z - 0.02), (0, 0.04, z + 0.02), 0.045)
        canvas.paint(body, cortical)
        canvas.paint(Offset(body, -2 * V), spongy)
        canvas.paint(Torus((0, 0.115, z), 0.035, 3 * V), cortical - 10)

    noise.add_gaussian(canvas.data, noise.fork(rng), 3.0)
    return Volume(canvas.to_uint8(), name="ct_skull")


FOLDED_BRAIN_ASPECT = (1.0, 1.0, 167 / 256)
"""The thesis's MR brain is 256×256×167 (Table 5.1)."""


def folded_brain(size, seed, decimate=1):
    """MR "folded brain in a head" for Lacroute's brain and brainsmall (note 003 §5).

    Ellipsoidal head (semi-axes 0.45, 0.48, 0.42 of the box) with a scalp (≈110, 3 voxels), a
    dark skull gap (≈20, 6 voxels), CSF (≈30) and a brain whose cortex is cut by sulci: V-shaped
    grooves up to 16 voxels deep along the zero set of a noise of 40-voxel period (gyri about 20
    voxels wide), so the surface is convoluted (many runs per scanline) and occluding. Grey
    matter ≈100 follows the folds 3.5 voxels deep over white matter ≈140; two ventricles (≈30).
    Rician noise σ 2.5. (All lengths at size 256.)

    Parameters
    ----------
    decimate : int
        Generate at ``decimate`` times the size and average ``decimate³`` boxes, the way the
        thesis made brainsmall (128×128×84) from the 256×256×167 scan.
    """
    if isinstance(decimate, bool) or not isinstance(decimate, (int, np.integer)) or decimate < 1:
        raise InputError(f"folded_brain decimate: expected an integer >= 1, got {decimate!r}")
    rng = np.random.default_rng(seed)
    out = Grid.for_aspect(size, FOLDED_BRAIN_ASPECT)
    nz, ny, nx = out.shape
    grid = Grid((nx * decimate, ny * decimate, nz * decimate), size * decimate)
    canvas = Canvas(grid)
    ez = grid.extent[2]
    head = Ellipsoid((0, 0, 0), (0.45, 0.48, 0.42 * ez))
    texture = noise.fbm(grid, noise.fork(rng), wavelength=0.3, octaves=3)
    folds = noise.fbm(grid, noise.fork(rng), wavelength=40 * V, octaves=2, gain=0.35)
    scalp, skull, csf = 3 * V, 6 * V, 2.5 * V
    canvas.paint(head, 110 + 5 * texture)
    canvas.paint(Offset(head, -scalp), 20)
    canvas.paint(Offset(head, -(scalp + skull)), 30)
    cortex = head.sdf(*grid.coords()) + np.float32(scalp + skull + csf)
    cortex += np.float32(16 * V) * np.maximum(0, 1 - np.abs(folds) / np.float32(0.3))
    canvas.paint(grid.region_of(cortex), 100 + 4 * texture)
    canvas.paint(grid.region_of(cortex + np.float32(3.5 * V)), 140 + 4 * texture)
    for side in (-1, 1):
        ventricle = Ellipsoid((side * 0.05, 0.02, 0.03 * ez), (0.03, 0.12, 0.07 * ez), rotation("y", side * 20))
        canvas.paint(ventricle, 30)
    noise.rician(canvas.data, noise.fork(rng), 2.5)
    data = canvas.data
    if decimate > 1:
        data = data.reshape(nz, decimate, ny, decimate, nx, decimate).mean(axis=(1, 3, 5), dtype=np.float32)
    return Volume(np.clip(np.rint(data), 0, 255).astype(np.uint8), name="folded_brain")
