"""Head phantoms: the MRI head (note 000), the CT phantom skull (003, 001, 004) and the folded
brain in a head (003's MR "brain" / "brainsmall").

Lengths are in normalised units (the longest axis is 1); the comments give them in voxels at 256,
the size the notes describe. Axes: x left→right, y front (face, −y) → back, z feet → crown.

The three share one anatomy, scaled to the box (:class:`_Head`): a soft-tissue head with nose,
lips and ears (:func:`_soft_head`), and a cerebrum whose cortex is cut by sulci (:func:`_cortex`).
The CT skull adds the bones of the face, the jaw, the teeth and the cervical spine.
"""

import numpy as np

from datasets import noise
from datasets.shapes import (
    Blend, Box, Canvas, Capsule, Ellipsoid, Field, Grid, Offset, Shell, SmoothUnion, Sphere, Torus, rotation,
)
from core.volume import Volume
from core.errors import InputError

V = 1 / 256
"""One voxel at the notes' reference size, in normalised units."""


class _Head:
    """Places the shared head anatomy: ``scale`` times the CT skull's proportions, then shifted by ``offset``."""

    def __init__(self, scale=1.0, offset=(0.0, 0.0, 0.0)):
        self.k = float(scale)
        self.offset = np.asarray(offset, dtype=np.float64)

    def p(self, x, y, z):
        """A point of the reference head in the box."""
        return self.offset + self.k * np.array([x, y, z], dtype=np.float64)

    def r(self, *radii):
        """Lengths of the reference head in the box (one value or a tuple)."""
        scaled = tuple(self.k * r for r in radii)
        return scaled if len(scaled) > 1 else scaled[0]

    @property
    def cranium(self):
        """Outer table of the skull vault: 146 × 179 × 159 voxels at scale 1 (cephalic index 0.81)."""
        return Ellipsoid(self.p(0, 0.05, 0.13), self.r(0.285, 0.35, 0.31))

    @property
    def brain(self):
        """The cerebrum's outer envelope, inside the skull with a CSF gap."""
        return Ellipsoid(self.p(0, 0.06, 0.15), self.r(0.245, 0.31, 0.255))


def _soft_head(head, *, scalp=6 * V):
    """Skin surface of a head with face, nose, lips, ears and a neck leaving through the bottom face."""
    p, r = head.p, head.r
    cranium = Offset(head.cranium, r(scalp))
    face = Ellipsoid(p(0, -0.15, -0.08), r(0.235, 0.26, 0.2))
    jaw = Ellipsoid(p(0, -0.13, -0.22), r(0.185, 0.24, 0.1))
    chin = Ellipsoid(p(0, -0.31, -0.26), r(0.06, 0.05, 0.05))
    neck = Capsule(p(0, 0.07, -0.18), p(0, 0.06, -1.0), r(0.165), r(0.18))
    nose = SmoothUnion(Capsule(p(0, -0.365, 0.01), p(0, -0.445, -0.1), r(0.018), r(0.03)),
                       Ellipsoid(p(0, -0.405, -0.115), r(0.048, 0.035, 0.022)), r(0.015))
    lips = SmoothUnion(Capsule(p(-0.05, -0.385, -0.17), p(0.05, -0.385, -0.17), r(0.016)),
                       Capsule(p(-0.045, -0.375, -0.205), p(0.045, -0.375, -0.205), r(0.017)), r(0.006))
    parts = [(face, r(0.08)), (jaw, r(0.06)), (chin, r(0.04)), (neck, r(0.07)), (nose, r(0.02)), (lips, r(0.02))]
    for side in (-1, 1):  # ears: a helix rim around a thin concha plate and a lobe, tilted off the head
        tilt = rotation("z", side * 15) @ rotation("y", side * 90)
        center = p(side * 0.315, 0.07, 0.0)
        rim = Torus(center, r(0.038), r(0.008), tilt)
        plate = Ellipsoid(center, r(0.05, 0.032, 0.01), tilt)
        lobe = Ellipsoid(p(side * 0.315, 0.065, -0.055), r(0.01, 0.018, 0.022))
        parts.append((SmoothUnion(SmoothUnion(rim, plate, r(0.006)), lobe, r(0.01)), r(0.012)))
    return Blend(cranium, parts)


def _cortex(grid, rng, head, *, depth=14 * V, period=34 * V):
    """Signed distance of a folded cerebrum: the brain envelope cut by sulci and the midline fissure.

    Sulci are V-shaped grooves ``depth`` deep along the zero set of a band-limited noise of mean
    period ``period`` (gyri about half that wide), the way a displaced shell folds; the
    interhemispheric fissure splits the hemispheres down to the corpus callosum.
    """
    folds = noise.fbm(grid, rng, wavelength=head.r(period), octaves=2, gain=0.35)
    x, y, z = grid.coords()
    d = head.brain.sdf(x, y, z)
    d += np.float32(head.r(depth)) * np.maximum(0, 1 - np.abs(folds) / np.float32(0.3))
    midline = np.float32(head.offset[0])
    fissure = np.minimum(np.float32(head.r(1.5 * V)) - np.abs(x - midline),
                         z - np.float32(head.p(0, 0, 0.08)[2]))
    return np.maximum(d, fissure)


def _cerebellum(head):
    """The cerebellum under the occipital lobes."""
    return Ellipsoid(head.p(0, 0.2, -0.08), head.r(0.17, 0.1, 0.07))


def mri_head(size, seed):
    """T1-like MRI head for Krüger & Westermann's "MRI head" (note 000 §6).

    A head filling the box the way the real MRI head fills its scan (nose to occiput 0.9 of the
    box), with nose, lips, ears and a neck leaving through the bottom face. T1 levels: scalp fat
    ≈185 over muscle ≈90, a dark cortical skull (≈25) around a brighter marrow (≈110), dark CSF
    (≈25) in the sulci and ventricles, grey matter ≈100, white matter ≈140 ± 10, vitreous ≈30.
    Rician noise σ 6.4 gives the background a Rayleigh floor of mean ≈ 8, sd ≈ 4 that the
    transfer function has to cut off.
    """
    rng = np.random.default_rng(seed)
    grid = Grid.for_aspect(size)
    canvas = Canvas(grid)
    head = _Head(1.1, (0, 0.01, -0.03))
    texture = noise.fbm(grid, noise.fork(rng), wavelength=0.35, octaves=3)
    skin = SmoothUnion(_soft_head(head), Ellipsoid((0, 0.06, -0.6), (0.5, 0.24, 0.16)), 0.08)   # shoulders
    at, d = grid.distance(skin)
    canvas.paint(grid.region_of(d, at), 185 + 8 * texture)
    canvas.paint(grid.region_of(d + np.float32(head.r(4 * V)), at), 90 + 6 * texture)   # muscle under the fat
    at, d = grid.distance(head.cranium)
    canvas.paint(grid.region_of(d, at), 25)
    marrow = d + np.float32(head.r(2 * V))
    canvas.paint(grid.region_of(np.maximum(marrow, -(marrow + np.float32(head.r(2.5 * V)))), at), 110)  # diploë
    canvas.paint(grid.region_of(d + np.float32(head.r(7 * V)), at), 25)                                # CSF
    cortex = _cortex(grid, noise.fork(rng), head, period=28 * V, depth=16 * V)
    canvas.paint(grid.region_of(cortex), 100 + 6 * texture)
    canvas.paint(grid.region_of(cortex + np.float32(head.r(3.5 * V))), 140 + 10 * texture)
    canvas.paint(_cerebellum(head), 115 + 6 * texture)
    for side in (-1, 1):
        canvas.paint(Ellipsoid(head.p(side * 0.045, 0.07, 0.12), head.r(0.025, 0.1, 0.045),
                               rotation("y", side * 15)), 25)                      # ventricles
        canvas.paint(Sphere(head.p(side * 0.09, -0.3, 0.025), head.r(0.042)), 30)  # eyes
    canvas.paint(Ellipsoid(head.p(0, -0.2, -0.09), head.r(0.1, 0.1, 0.09)), 10)  # sinuses, nasal cavity (air)
    noise.rician(canvas.data, noise.fork(rng), 6.4)
    return Volume(canvas.to_uint8(), name="mri_head")


def _skull_thickness(base, head):
    """Skull thickness ``base`` thinning to 40 % at the temples (note 001: 3–10 voxels)."""
    cz, k = head.p(0, 0, 0.02)[2], head.k

    def thickness(x, y, z):
        temple = np.exp(-(((z - np.float32(cz)) / np.float32(0.09 * k)) ** 2)) * np.minimum((x / np.float32(0.28 * k)) ** 2, 1)
        return np.float32(base * k) * (1 - np.float32(0.6) * temple)
    return thickness


def _arch(head, theta, *, width, depth, y0, z):
    """Points of a dental/mandibular arch: a parabola-like curve opening backwards."""
    return np.stack([head.k * width * np.sin(theta), head.k * (y0 - depth * np.cos(theta)),
                     np.full_like(theta, head.k * z)], axis=1) + head.offset


def _plate(a, b, thickness, height):
    """A rounded slab from ``a`` to ``b``: ``thickness`` across, ``height`` tall (z), along the segment."""
    along = np.asarray(b, float) - np.asarray(a, float)
    length = float(np.linalg.norm(along))
    u = along / length
    side = np.cross((0, 0, 1.0), u)
    side /= np.linalg.norm(side)
    rot = np.stack([u, side, np.cross(u, side)], axis=1)
    return Box((np.asarray(a) + np.asarray(b)) / 2, (length / 2 + thickness / 2, thickness / 2, height / 2),
               rounding=min(thickness, height) / 2.01, rotation=rot)


def _teeth(head):
    """Sixteen upper and sixteen lower teeth: (crown tip, root apex, crown radius, root radius)."""
    radii = np.array([2.3, 2.2, 2.6, 3.0, 3.0, 4.2, 4.2, 3.8]) * V   # incisors … third molar
    gaps = np.concatenate([[radii[0]], radii[:-1] + radii[1:]])
    theta = np.cumsum(gaps) / 0.2                                    # arc length along the arch
    theta = np.concatenate([-theta[::-1], theta])
    tooth_r = np.concatenate([radii[::-1], radii])
    teeth = []
    for z_tip, z_root, width, y0 in ((-0.213, -0.15, 0.165, 0.0), (-0.217, -0.28, 0.155, -0.005)):
        pts = _arch(head, theta, width=width, depth=0.27, y0=y0, z=z_tip)
        for point, radius in zip(pts, tooth_r):
            apex = point + np.array([0, 0, head.k * (z_root - z_tip)])
            teeth.append(Capsule(point, apex, head.r(radius), head.r(0.55 * radius)))
    return teeth


def _head_rest(head):
    """The scanner's head rest: a curved foam-and-plastic cradle behind the occiput."""
    center, radius, wall = head.p(0, 0.02, 0.0), head.r(0.4), head.r(3 * V)
    low, high = head.p(0, 0, -0.15)[2], head.p(0, 0, 0.05)[2]

    def sdf(x, y, z):
        rho = np.sqrt((x - np.float32(center[0])) ** 2 + (y - np.float32(center[1])) ** 2)
        ring = np.abs(rho - np.float32(radius)) - np.float32(wall)
        back = np.float32(center[1] + 0.22 * head.k) - y
        span = np.maximum(np.float32(low) - z, z - np.float32(high))
        return np.maximum(np.maximum(ring, back), span)

    return Field(sdf, center - radius - wall, center + radius + wall)


def ct_skull(size, seed):
    """CT head: skull, face, jaw, teeth and cervical spine in soft tissue with a face and ears.

    Note 003's "phantom skull", note 001's "Head" and note 004's skull: a cranium of varying
    thickness (outer and inner tables around a darker trabecular diploë, 3–9 voxels, thinnest at
    the temples) over a brain; orbits with bony rims holding the eyes; a nasal cavity behind a
    pear-shaped aperture with a septum; maxillary and frontal sinuses; zygomatic bones and arches;
    the maxilla and a mandible (body, rami, condyles, coronoid processes) with 32 teeth; cervical
    vertebrae (body, arch, spinous and transverse processes). Soft tissue ≈90 with a subcutaneous
    fat layer ≈68, so that the skin band of a transfer function shows a surface with nose, lips
    and ears; the head lies on the scanner's curved head rest (≈55), as in the real CT head. CT levels: cortical bone ≈220, cancellous ≈170 ± 35, enamel ≈250, brain ≈95 over
    CSF ≈80, air 0, noise σ 3.
    """
    rng = np.random.default_rng(seed)
    grid = Grid.for_aspect(size)
    canvas = Canvas(grid)
    head = _Head(1.06, (0, 0, -0.015))
    p, r = head.p, head.r
    texture = noise.fbm(grid, noise.fork(rng), wavelength=0.3, octaves=3)
    trabecular = noise.fbm(grid, noise.fork(rng), wavelength=10 * V, octaves=1)
    cortical, spongy, enamel = 220, 185 + 25 * trabecular, 250

    canvas.paint(_head_rest(head), 55)
    at, d = grid.distance(_soft_head(head))
    canvas.paint(grid.region_of(d, at), 90 + 6 * texture)
    fat = d + np.float32(1 * V)
    canvas.paint(grid.region_of(np.maximum(fat, -(fat + np.float32(3 * V))), at), 68 + 4 * texture)  # subcutaneous

    cranium = head.cranium
    thickness = _skull_thickness(0.045, head)
    # Facial skeleton: one hollow bony mass from the brow to the upper jaw, joined smoothly to the
    # vault, with the maxillary sinuses and the nasal cavity inside, cheekbones on its sides.
    zygomas = [Ellipsoid(p(side * 0.165, -0.21, -0.045), r(0.05, 0.045, 0.04)) for side in (-1, 1)]
    midface = Ellipsoid(p(0, -0.2, -0.09), r(0.13, 0.13, 0.12))
    face = SmoothUnion(SmoothUnion(midface, zygomas[0], r(0.03)), zygomas[1], r(0.03))
    solid = canvas.paint(SmoothUnion(cranium, face, r(0.06)), cortical)
    canvas.paint(Offset(face, -r(3.5 * V)), 0)                                      # sinuses, nasal cavity
    at, d = grid.distance(cranium)
    t = thickness(*grid.coords_of(at, d))
    diploe = d + np.float32(0.3) * t
    canvas.paint(grid.region_of(np.maximum(diploe, -(diploe + np.float32(0.4) * t)), at), spongy)
    canvas.paint(grid.region_of(d + t, at), 80)                                    # CSF
    canvas.paint(grid.region_of(_cortex(grid, noise.fork(rng), head)), 95 + 3 * texture)
    canvas.paint(_cerebellum(head), 95 + 3 * texture)
    for side in (-1, 1):                                                            # sinus walls
        canvas.paint(Box(p(side * 0.035, -0.2, -0.12), r(1.5 * V, 0.1, 0.07)), cortical - 20)
    canvas.paint(Box(p(0, -0.22, -0.1), r(1.5 * V, 0.1, 0.06)), cortical - 30)       # nasal septum
    canvas.paint(Ellipsoid(p(0, -0.32, -0.085), r(0.032, 0.05, 0.055)), 0)         # piriform aperture
    canvas.paint(Capsule(p(0, -0.318, 0.015), p(0, -0.345, -0.03), r(3 * V)), cortical)  # nasal bones
    for center, radii in (((0, -0.25, 0.15), (0.06, 0.02, 0.035)), ((0, -0.08, -0.05), (0.04, 0.035, 0.03))):
        canvas.paint(Ellipsoid(p(*center), r(*radii)), 0)                           # frontal, sphenoid sinus
    for side in (-1, 1):
        canvas.paint(Capsule(p(side * 0.19, -0.19, -0.05), p(side * 0.275, 0.02, -0.04), r(4.5 * V)),
                     cortical)                                                      # zygomatic arch
        orbit = Ellipsoid(p(side * 0.09, -0.265, 0.025), r(0.052, 0.11, 0.048), rotation("z", -side * 12))
        canvas.paint(grid.region(Shell(Offset(orbit, r(3 * V)), r(3 * V))).intersect(solid), cortical)
        canvas.paint(orbit, 70)                                                      # orbital fat
        canvas.paint(Sphere(p(side * 0.09, -0.305, 0.025), r(0.042)), 85)           # eye
    canvas.paint(Ellipsoid(p(0, 0.12, -0.17), r(0.04, 0.05, 0.04)), 80)            # foramen magnum

    # Mandible: a U-shaped plate (body) with rami up to the condyles, cortex around cancellous bone.
    theta = np.linspace(-1.25, 1.25, 15)
    body = _arch(head, theta, width=0.18, depth=0.3, y0=0.0, z=-0.265)
    mandible = [_plate(a, b, r(9 * V), r(0.075)) for a, b in zip(body[:-1], body[1:])]
    for end, side in ((body[0], -1), (body[-1], 1)):
        condyle = p(side * 0.215, 0.075, -0.07)
        mandible.append(_plate(end, condyle, r(7 * V), r(0.05)))
        mandible.append(Ellipsoid(condyle, r(0.02, 0.012, 0.012)))
        mandible.append(Capsule(end + np.array([0, -r(0.03), 0.02 * head.k]), p(side * 0.2, -0.02, -0.1), r(4 * V)))
    canvas.paint(grid.union(mandible), cortical)
    canvas.paint(grid.union(Offset(m, -2.5 * V) for m in mandible), spongy)
    canvas.paint(grid.union(_teeth(head)), enamel)

    # Cervical vertebrae C1–C7 under the foramen magnum (the lower ones leave the box).
    for k in range(7):
        z = -0.22 - 0.062 * k
        body = Ellipsoid(p(0, 0.06, z), r(0.042, 0.032, 0.02))
        parts = [body, Torus(p(0, 0.115, z), r(0.034), r(4 * V)),
                 Capsule(p(0, 0.145, z), p(0, 0.2, z - 0.025), r(4 * V), r(3 * V))]
        parts += [Capsule(p(side * 0.03, 0.08, z), p(side * 0.07, 0.085, z), r(4 * V)) for side in (-1, 1)]
        canvas.paint(grid.union(parts), cortical)
        canvas.paint(Offset(body, -2 * V), spongy)

    noise.add_gaussian(canvas.data, noise.fork(rng), 3.0)
    return Volume(canvas.to_uint8(), name="ct_skull")


FOLDED_BRAIN_ASPECT = (1.0, 1.0, 167 / 256)
"""The thesis's MR brain is 256×256×167 (Table 5.1)."""


def folded_brain(size, seed, decimate=1):
    """MR "folded brain in a head" for Lacroute's brain and brainsmall (note 003 §5).

    The MR head of :func:`mri_head`'s anatomy, lying face-forward in a 256×256×167 box, with the
    scalp, skull and CSF cut away over the upper left of the cranium (as in VolPack's brainsmall
    rendering) so that the folded cortex shows: sulci 14 voxels deep along the zero set of a
    noise of 34-voxel period (gyri about 17 voxels wide), the interhemispheric fissure and a
    cerebellum. Scalp ≈110 (4 voxels), dark skull ≈20, CSF ≈30, grey matter ≈100 ± 16 following
    the folds 3.5 voxels deep over white matter ≈140 ± 16, ventricles ≈30; a Gaussian
    point-spread function (σ 0.8 output voxel) and Rician noise σ 3.5.

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
    head = _Head(0.94, (0, 0.0, -0.1))
    texture = noise.fbm(grid, noise.fork(rng), wavelength=0.1, octaves=3)
    canvas.paint(_soft_head(head, scalp=4 * V), 110 + 10 * texture)
    cranium = head.cranium
    at, d = grid.distance(Offset(cranium, head.r(8 * V)))
    canvas.paint(grid.region_of(d - np.float32(head.r(7 * V)), at), 20)
    canvas.paint(grid.region_of(d + np.float32(head.r(14 * V)), at), 30)
    # The cut-away: a quarter of the head above the eyes removed down to the brain.
    x, y, z = grid.coords()
    window = grid.region_of(np.broadcast_to(np.maximum(np.float32(head.p(0, 0, 0.12)[2]) - z, -x + np.float32(0.02)),
                                            grid.shape))
    canvas.paint(window.intersect(grid.region_of(d, at)), 0)
    cortex = _cortex(grid, noise.fork(rng), head)
    canvas.paint(grid.region_of(cortex), 100 + 16 * texture)
    canvas.paint(grid.region_of(cortex + np.float32(head.r(3.5 * V))), 140 + 16 * texture)
    canvas.paint(_cerebellum(head), 110 + 16 * texture)
    for side in (-1, 1):
        ventricle = Ellipsoid(head.p(side * 0.045, 0.07, 0.12), head.r(0.025, 0.1, 0.045), rotation("y", side * 15))
        canvas.paint(ventricle, 30)
    # The scanner's point-spread function, about one output voxel wide, before the noise.
    from scipy import ndimage  # here, not at the top: render jobs import the registry, never generate

    data = ndimage.gaussian_filter(canvas.data, sigma=0.8 * decimate, mode="nearest")
    noise.rician(data, noise.fork(rng), 3.5)
    if decimate > 1:
        data = data.reshape(nz, decimate, ny, decimate, nx, decimate).mean(axis=(1, 3, 5), dtype=np.float32)
    return Volume(np.clip(np.rint(data), 0, 255).astype(np.uint8), name="folded_brain")
