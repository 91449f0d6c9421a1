"""The volume atlas: every distinct volume of a scene packed into one 3-D array (Kainz et al. 2009, §3.5).

The paper keeps all volumes in one big 3-D texture and reduces packing to one dimension (slots
along one axis); that cannot hold many small volumes in a cube-shaped atlas (note 002 §2.7), so
this atlas uses **shelf packing in 3-D**: volumes, largest first, are placed side by side along
``x`` in rows, rows stack along ``y`` into layers, layers stack along ``z``; rows and layers are
closed when the next volume would pass the target edge (the cube root of the total voxel count
rounded up to a whole number of the largest volume's edge), so 50 volumes of 64³ go into a
256 × 256 × 256 atlas (16 per layer, 4 layers).

The atlas is a plain device buffer indexed ``[z, y, x]`` and sampled by the kernels' own
trilinear filter, which clamps to each volume's slot (clamp-to-edge per volume, as
CONVENTIONS asks). Slots therefore need no duplicated border voxels, and the filter weights are
float32 (texture units filter with 8-bit weights on most GPUs, which would cap the accuracy
against the reference).

Values are stored as ``uint8`` (normalised in the kernel by 1/255) when every volume is uint8
with the default range, else as normalised ``float32`` (:meth:`core.volume.Volume.normalized`).
"""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Layout:
    """Where each volume sits in the atlas.

    Attributes
    ----------
    shape_xyz : tuple of int
        Atlas dimensions ``(ax, ay, az)``.
    origins : tuple of tuple of int
        Slot origin ``(ox, oy, oz)`` per volume, in the order the volumes were given.
    """

    shape_xyz: tuple
    origins: tuple


def pack(shapes_xyz):
    """Shelf-pack boxes of ``shapes_xyz`` (``[(nx, ny, nz), ...]``) into one atlas; see the module notes.

    Returns
    -------
    Layout
        Non-overlapping slots, every one inside the atlas.
    """
    shapes = [tuple(int(n) for n in shape) for shape in shapes_xyz]
    total = sum(nx * ny * nz for nx, ny, nz in shapes)
    largest = max(max(shape[:2]) for shape in shapes)
    # The cube root rounded up to whole largest edges, so equal volumes tile the layers exactly.
    edge = largest * max(1, int(np.ceil(round(total ** (1 / 3) / largest, 9))))
    order = sorted(range(len(shapes)), key=lambda i: (-shapes[i][2], -shapes[i][1], -shapes[i][0], i))
    origins = [None] * len(shapes)
    x = y = z = 0
    row_depth = layer_depth = 0   # largest ny of the row, largest nz of the layer
    width = height = 0
    for i in order:
        nx, ny, nz = shapes[i]
        if x > 0 and x + nx > edge:          # close the row
            x, y = 0, y + row_depth
            row_depth = 0
        if y > 0 and y + ny > edge:          # close the layer
            x, y, z = 0, 0, z + layer_depth
            row_depth = layer_depth = 0
        origins[i] = (x, y, z)
        x += nx
        row_depth = max(row_depth, ny)
        layer_depth = max(layer_depth, nz)
        width = max(width, x)
        height = max(height, y + ny)
    return Layout(shape_xyz=(width, height, z + layer_depth), origins=tuple(origins))


def storage_dtype(volumes):
    """``uint8`` if every volume is uint8 with the default range [0, 255], else ``float32``."""
    if all(v.data.dtype == np.uint8 and tuple(v.value_range) == (0.0, 255.0) for v in volumes):
        return np.dtype(np.uint8)
    return np.dtype(np.float32)


def fill(volumes, layout, dtype):
    """The atlas array ``(az, ay, ax)`` of ``dtype`` with each volume in its slot (zeros elsewhere)."""
    ax, ay, az = layout.shape_xyz
    atlas = np.zeros((az, ay, ax), dtype=dtype)
    for volume, (ox, oy, oz) in zip(volumes, layout.origins):
        nx, ny, nz = volume.shape_xyz
        data = volume.data if dtype == np.uint8 else volume.normalized(np.float32)
        atlas[oz:oz + nz, oy:oy + ny, ox:ox + nx] = data
    return atlas
