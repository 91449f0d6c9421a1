"""Controls with known answers: the sphere, constant cubes, checkerboards and the fBm "no-cue" volume.

Notes 003 (§5: sphere 256³, constant-opacity cubes of Fig. 5.19, checkerboards of Figs 5.20–5.21)
and 000 (§6: the E2 control where no ray terminates and no block is empty).
"""

import numpy as np

from datasets import noise
from datasets.shapes import Canvas, Grid, Shell, Sphere
from core.volume import Volume
from core.errors import InputError
from core.validation import check_positive_int


def _check_value(value, name):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value <= 255:
        raise InputError(f"{name} value: expected an integer from 0 to 255, got {value!r}")
    return int(value)


def sphere(size, seed, shell=0):
    """One band-limited sphere, radius 100 voxels at 256 (0.39 of the box), value 200 on 0.

    The view-independence control of Lacroute's Fig. 5.3 and the strided-access test. No noise,
    so ``seed`` does not change it. ``shell`` > 0 keeps only the outer layer that many voxels
    thick (of this ``size``): the thin features of the stability atlas. 0 is the solid sphere.
    """
    if isinstance(shell, bool) or not isinstance(shell, (int, float, np.integer, np.floating)) or not shell >= 0:
        raise InputError(f"sphere shell: expected a thickness in voxels >= 0 (0: solid), got {shell!r}")
    grid = Grid.for_aspect(size)
    canvas = Canvas(grid)
    ball = Sphere((0, 0, 0), 100 / 256)
    canvas.paint(Shell(ball, float(shell) * grid.h) if shell else ball, 200)
    return Volume(canvas.to_uint8(), name="sphere")


def constant_cube(size, seed, value=128):
    """Every voxel equal to ``value`` (uint8); with the ``identity`` preset, ``α = value/255``.

    The constant-opacity cubes of the thesis's Fig. 5.19 (one non-transparent run per scanline
    when ``value/255`` is above the threshold) and the homogeneous medium of closed-form tests.
    """
    value = _check_value(value, "constant_cube")
    grid = Grid.for_aspect(size)
    return Volume(np.full(grid.shape, value, dtype=np.uint8), name="constant_cube")


def checkerboard(size, seed, block=8, value=255):
    """3-D checkerboard ``((x//block + y//block + z//block) & 1) · value`` with hard edges.

    No blur and no noise, so run counts are exact: a scanline of ``size`` voxels holds
    ``size / (2·block)`` non-transparent runs when ``2·block`` divides ``size`` (Figs 5.20–5.21).
    ``block`` is in voxels of the generated volume.
    """
    block = check_positive_int(block, name="checkerboard block")
    value = _check_value(value, "checkerboard")
    index = np.arange(size) // block
    parity = (index[:, None, None] + index[None, :, None] + index[None, None, :]) & 1
    return Volume((parity * value).astype(np.uint8), name="checkerboard")


def fbm_control(size, seed):
    """Smooth fBm filling the whole cube with values 50–200 (note 000, experiment E2).

    With the ``no_cue`` preset (uniform α ≈ 0.003) no ray reaches the termination threshold and
    no block is empty, so only the acceleration techniques' overhead is measured.
    """
    rng = np.random.default_rng(seed)
    grid = Grid.for_aspect(size)
    field = noise.fbm(grid, noise.fork(rng), wavelength=0.5, octaves=5)
    data = np.clip(np.rint(125 + 30 * field), 50, 200).astype(np.uint8)
    return Volume(data, name="fbm_control")
