"""The in-memory volume: a scalar grid with its spacing and value range (CONVENTIONS, Volumes)."""

from dataclasses import dataclass, field

import numpy as np

from core.errors import InputError
from core.validation import check_positive_vector, check_value_range, check_volume_array

DTYPE_RANGES = {
    np.dtype(np.uint8): (0.0, 255.0),
    np.dtype(np.uint16): (0.0, 65535.0),
    np.dtype(np.float32): (0.0, 1.0),
}


@dataclass(frozen=True, eq=False)
class Volume:
    """A scalar volume, indexed ``[z, y, x]`` with x fastest.

    Parameters
    ----------
    data : numpy.ndarray
        uint8, uint16 or float32 array of shape ``(nz, ny, nx)``.
    spacing : tuple of float, optional
        ``(sx, sy, sz)`` world units per voxel. Isotropic 1.0 by default.
    value_range : tuple of float, optional
        ``(lo, hi)``, finite with ``lo < hi``: raw values map to ``(v - lo) / (hi - lo)`` and are
        clipped to [0, 1]. Defaults to the dtype's range (uint8 /255, uint16 /65535, float32
        taken as already in [0, 1]); a float32 volume with values outside [0, 1] must give its
        range, since clipping them silently would change the picture.
    name : str, optional
        Human-readable name used in reports and errors.
    labels : numpy.ndarray, optional
        Integer label volume of the same shape (material ids, e.g. the torso phantom).
    meta : dict, optional
        Provenance: generator and parameters, file path, statistics targets.

    Notes
    -----
    Samples are cell-centred: voxel ``(i, j, k)`` sits at ``((i+.5)·sx, (j+.5)·sy, (k+.5)·sz)`` in
    object space and the object box is ``[0, nx·sx] × [0, ny·sy] × [0, nz·sz]``.
    """

    data: np.ndarray
    spacing: tuple = (1.0, 1.0, 1.0)
    value_range: tuple | None = None
    name: str = "volume"
    labels: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        # A read-only view: backends cache per-Volume derived data (normalised copies, textures),
        # which an in-place edit through the Volume would silently invalidate.
        data = check_volume_array(self.data, name=f"volume {self.name!r}").view()
        data.flags.writeable = False
        object.__setattr__(self, "data", data)
        object.__setattr__(
            self, "spacing", check_positive_vector(self.spacing, length=3, name=f"volume {self.name!r} spacing")
        )
        if self.value_range is None:
            if data.dtype.kind == "f":
                lo, hi = float(data.min()), float(data.max())
                if lo < 0 or hi > 1:
                    # Normalising by [0, 1] would clip these values without a word.
                    raise InputError(
                        f"volume {self.name!r}: float32 values span [{lo:.6g}, {hi:.6g}], outside the "
                        f"default range [0, 1]; set value_range (e.g. value_range=({lo:.6g}, {hi:.6g}), "
                        "or 'value_range: [lo, hi]' in a scene file) to say how they normalise"
                    )
            object.__setattr__(self, "value_range", DTYPE_RANGES[data.dtype])
        else:
            object.__setattr__(
                self, "value_range", check_value_range(self.value_range, name=f"volume {self.name!r} value_range")
            )
        if self.labels is not None:
            labels = np.asarray(self.labels)
            if labels.shape != data.shape or labels.dtype.kind not in "iu":
                raise InputError(
                    f"volume {self.name!r} labels: expected an integer array of shape {data.shape}, "
                    f"got {labels.dtype} {labels.shape}"
                )

    @property
    def shape_xyz(self):
        """Dimensions as ``(nx, ny, nz)``."""
        nz, ny, nx = self.data.shape
        return nx, ny, nz

    @property
    def extent(self):
        """Object-space size of the box, ``(nx·sx, ny·sy, nz·sz)``."""
        return tuple(n * s for n, s in zip(self.shape_xyz, self.spacing))

    @property
    def min_spacing(self):
        """The reference opacity step ``Δ0`` (one voxel of the smallest spacing)."""
        return min(self.spacing)

    def normalized(self, dtype=np.float32):
        """Scalars mapped to [0, 1] by ``value_range`` (values outside are clipped)."""
        lo, hi = self.value_range
        out = (self.data.astype(dtype) - dtype(lo)) / dtype(hi - lo)
        return np.clip(out, 0, 1, out=out)

    def content_hash(self):
        """Hex digest of the data, spacing and range: stable across runs and machines."""
        import hashlib

        digest = hashlib.sha256()
        digest.update(str((self.data.dtype.str, self.data.shape, self.spacing, self.value_range)).encode())
        digest.update(np.ascontiguousarray(self.data).tobytes())
        return digest.hexdigest()[:16]
