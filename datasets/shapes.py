"""Signed-distance primitives and a painter that turns them into band-limited voxel volumes.

The phantoms are written in *normalised coordinates*: the longest axis of the volume spans
``[-0.5, 0.5]``, the box is centred on the origin and voxel ``i`` of an axis with ``n`` voxels sits
at ``(i + 0.5 - n/2) / size`` (cell-centred, as CONVENTIONS.md asks). A shape therefore has the
same geometry at every ``size``; only the sampling changes.

Edges are band-limited the way a CT or MR scanner's point-spread function does it: a shape's
signed distance ``d`` becomes a coverage ``c = smoothstep`` over ``|d| < 1.5`` voxels. The slope of
that profile at the surface equals a Gaussian-blurred step of σ ≈ 0.8 voxel, the blur the notes ask
for (σ ≈ 0.7–1), but it has compact support, so a primitive is evaluated only inside its bounding
box plus a two-voxel margin. Materials are composited in painting order
(``value ← value + (v − value)·c``), so later shapes overwrite earlier ones with a partial-volume
edge. Unions of many small primitives take the maximum of their coverages, which is exactly the
coverage of the union's signed distance (``min``), and an intersection the minimum.
"""

from dataclasses import dataclass

import numpy as np

from core.errors import InputError

EDGE_HALF_WIDTH = 1.5
"""Half-width, in voxels, of the smoothstep edge profile (≈ Gaussian blur σ 0.8 voxel)."""

_MARGIN = EDGE_HALF_WIDTH + 1.0


# ---------------------------------------------------------------------------------------------
# Rotations


def rotation(axis, degrees):
    """3×3 matrix of a right-handed rotation by ``degrees`` about ``axis`` (x, y, z or a vector)."""
    if isinstance(axis, str):
        axis = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}[axis]
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    angle = np.radians(degrees)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def frame(direction):
    """Rotation whose third column is ``direction``: maps a shape's local z axis onto it."""
    w = np.asarray(direction, dtype=np.float64)
    w = w / np.linalg.norm(w)
    helper = np.array([1.0, 0, 0]) if abs(w[0]) < 0.9 else np.array([0, 1.0, 0])
    u = np.cross(helper, w)
    u /= np.linalg.norm(u)
    return np.stack([u, np.cross(w, u), w], axis=1)


# ---------------------------------------------------------------------------------------------
# Signed-distance shapes


class Shape:
    """A solid given by a signed distance (negative inside), in normalised units.

    Subclasses implement :meth:`sdf` on broadcastable coordinate arrays and :meth:`bounds`.
    Constructive geometry of many parts is done on coverages (:class:`Region`), so only the
    combinations that need a true distance (smooth unions, offsets, shells) are shapes.
    """

    def sdf(self, x, y, z):
        raise NotImplementedError

    def bounds(self):
        """Axis-aligned box ``(lo, hi)`` (xyz arrays) outside of which the distance is positive."""
        raise NotImplementedError


class _Placed(Shape):
    """A shape defined in a local frame: ``world = center + rotation @ local``."""

    def __init__(self, center, rotation=None):
        self.center = np.asarray(center, dtype=np.float64)
        self.rot = None if rotation is None else np.asarray(rotation, dtype=np.float64)

    def _local(self, x, y, z):
        dx, dy, dz = x - np.float32(self.center[0]), y - np.float32(self.center[1]), z - np.float32(self.center[2])
        if self.rot is None:
            return dx, dy, dz
        r = self.rot.astype(np.float32)
        return (r[0, 0] * dx + r[1, 0] * dy + r[2, 0] * dz,
                r[0, 1] * dx + r[1, 1] * dy + r[2, 1] * dz,
                r[0, 2] * dx + r[1, 2] * dy + r[2, 2] * dz)

    def _box_bounds(self, half):
        """Bounds of the local box ``[-half, half]`` after rotation and translation."""
        half = np.asarray(half, dtype=np.float64)
        extent = half if self.rot is None else np.abs(self.rot) @ half
        return self.center - extent, self.center + extent


class Ellipsoid(_Placed):
    """Ellipsoid with semi-axes ``radii``.

    The distance is Quílez's first-order approximation ``k0 (k0 − 1) / k1``: exact for a sphere
    and accurate to a few per cent near the surface, which is all the edge profile uses.
    """

    def __init__(self, center, radii, rotation=None):
        super().__init__(center, rotation)
        self.radii = np.broadcast_to(np.asarray(radii, dtype=np.float64), (3,)).copy()

    def sdf(self, x, y, z):
        lx, ly, lz = self._local(x, y, z)
        rx, ry, rz = (np.float32(r) for r in self.radii)
        k0 = np.sqrt((lx / rx) ** 2 + (ly / ry) ** 2 + (lz / rz) ** 2)
        k1 = np.sqrt((lx / rx**2) ** 2 + (ly / ry**2) ** 2 + (lz / rz**2) ** 2)
        return k0 * (k0 - 1) / np.maximum(k1, np.float32(1e-12))

    def bounds(self):
        if self.rot is None:
            return self.center - self.radii, self.center + self.radii
        extent = np.sqrt((self.rot**2) @ (self.radii**2))
        return self.center - extent, self.center + extent


def Sphere(center, radius):
    """A ball (an :class:`Ellipsoid` with equal radii; its distance is exact)."""
    return Ellipsoid(center, (radius, radius, radius))


class Box(_Placed):
    """Box with half-sizes ``half``, edges rounded by ``rounding`` (exact distance)."""

    def __init__(self, center, half, rounding=0.0, rotation=None):
        super().__init__(center, rotation)
        self.half = np.asarray(half, dtype=np.float64)
        self.rounding = float(rounding)

    def sdf(self, x, y, z):
        lx, ly, lz = self._local(x, y, z)
        r = np.float32(self.rounding)
        qx, qy, qz = (np.abs(c) - np.float32(h) + r for c, h in zip((lx, ly, lz), self.half))
        outside = np.sqrt(np.maximum(qx, 0) ** 2 + np.maximum(qy, 0) ** 2 + np.maximum(qz, 0) ** 2)
        inside = np.minimum(np.maximum(np.maximum(qx, qy), qz), 0)
        return outside + inside - r

    def bounds(self):
        return self._box_bounds(self.half)


class Capsule(Shape):
    """Segment ``a``–``b`` swept by a radius tapering linearly from ``ra`` to ``rb``.

    The distance is the tapered-capsule approximation (distance to the nearest axis point minus
    the radius there), accurate for the slow tapers of vessels and bones.
    """

    def __init__(self, a, b, ra, rb=None):
        self.a = np.asarray(a, dtype=np.float64)
        self.b = np.asarray(b, dtype=np.float64)
        self.ra = float(ra)
        self.rb = float(ra if rb is None else rb)

    def sdf(self, x, y, z):
        ax, ay, az = (np.float32(v) for v in self.a)
        bax, bay, baz = (np.float32(v) for v in self.b - self.a)
        length2 = np.float32(max(float(np.dot(self.b - self.a, self.b - self.a)), 1e-20))
        px, py, pz = x - ax, y - ay, z - az
        t = np.clip((px * bax + py * bay + pz * baz) / length2, 0, 1)
        dist = np.sqrt((px - t * bax) ** 2 + (py - t * bay) ** 2 + (pz - t * baz) ** 2)
        return dist - (np.float32(self.ra) + t * np.float32(self.rb - self.ra))

    def bounds(self):
        lo = np.minimum(self.a - self.ra, self.b - self.rb)
        hi = np.maximum(self.a + self.ra, self.b + self.rb)
        return lo, hi


class Cylinder(Shape):
    """Flat-capped cylinder of radius ``radius`` around the segment ``a``–``b`` (exact distance)."""

    def __init__(self, a, b, radius):
        self.a = np.asarray(a, dtype=np.float64)
        self.b = np.asarray(b, dtype=np.float64)
        self.radius = float(radius)

    def sdf(self, x, y, z):
        axis = self.b - self.a
        length = float(np.linalg.norm(axis))
        ux, uy, uz = (np.float32(v) for v in axis / length)
        px, py, pz = x - np.float32(self.a[0]), y - np.float32(self.a[1]), z - np.float32(self.a[2])
        along = px * ux + py * uy + pz * uz
        radial = np.sqrt(np.maximum((px - along * ux) ** 2 + (py - along * uy) ** 2 + (pz - along * uz) ** 2, 0))
        dr = radial - np.float32(self.radius)
        dh = np.abs(along - np.float32(length / 2)) - np.float32(length / 2)
        return np.minimum(np.maximum(dr, dh), 0) + np.sqrt(np.maximum(dr, 0) ** 2 + np.maximum(dh, 0) ** 2)

    def bounds(self):
        axis = (self.b - self.a) / np.linalg.norm(self.b - self.a)
        extent = self.radius * np.sqrt(np.clip(1 - axis**2, 0, 1))
        return np.minimum(self.a, self.b) - extent, np.maximum(self.a, self.b) + extent


class Torus(_Placed):
    """Ring of major radius ``major`` and tube radius ``minor`` around the local z axis."""

    def __init__(self, center, major, minor, rotation=None):
        super().__init__(center, rotation)
        self.major = float(major)
        self.minor = float(minor)

    def sdf(self, x, y, z):
        lx, ly, lz = self._local(x, y, z)
        q = np.sqrt(lx**2 + ly**2) - np.float32(self.major)
        return np.sqrt(q**2 + lz**2) - np.float32(self.minor)

    def bounds(self):
        r = self.major + self.minor
        return self._box_bounds((r, r, self.minor))


class Field(Shape):
    """A shape given by any distance function ``fn(x, y, z)`` and explicit bounds."""

    def __init__(self, fn, lo, hi):
        self.fn = fn
        self.lo = np.asarray(lo, dtype=np.float64)
        self.hi = np.asarray(hi, dtype=np.float64)

    def sdf(self, x, y, z):
        return self.fn(x, y, z)

    def bounds(self):
        return self.lo, self.hi


class SmoothUnion(Shape):
    """Union with a fillet of size ``k`` (Quílez's polynomial smooth minimum)."""

    def __init__(self, a, b, k):
        self.a, self.b, self.k = a, b, float(k)

    def sdf(self, x, y, z):
        da, db = self.a.sdf(x, y, z), self.b.sdf(x, y, z)
        k = np.float32(self.k)
        h = np.clip(0.5 + 0.5 * (db - da) / k, 0, 1)
        return db + (da - db) * h - k * h * (1 - h)

    def bounds(self):
        (alo, ahi), (blo, bhi) = self.a.bounds(), self.b.bounds()
        return np.minimum(alo, blo) - self.k, np.maximum(ahi, bhi) + self.k


class Blend(Shape):
    """``base`` smoothly joined to small ``parts``, each evaluated only near itself.

    The same surface as nesting :class:`SmoothUnion` (``parts`` is a list of ``(shape, k)``),
    but a part's distance is computed only inside its bounding box grown by ``2k``: farther
    out the smooth minimum equals the base's distance wherever a coverage is non-zero. Needs
    the axis-aligned coordinates a :class:`Grid` passes (``x (1,1,n), y (1,n,1), z (n,1,1)``).
    """

    def __init__(self, base, parts):
        self.base, self.parts = base, [(shape, float(k)) for shape, k in parts]

    def sdf(self, x, y, z):
        shape = np.broadcast_shapes(np.shape(x), np.shape(y), np.shape(z))
        d = np.array(np.broadcast_to(self.base.sdf(x, y, z), shape), dtype=np.float32)
        axes = (z.ravel(), y.ravel(), x.ravel())
        for part, k in self.parts:
            lo, hi = part.bounds()
            window = tuple(slice(int(np.searchsorted(axis, lo[c] - 2 * k)), int(np.searchsorted(axis, hi[c] + 2 * k, "right")))
                           for axis, c in zip(axes, (2, 1, 0)))
            if any(w.stop <= w.start for w in window):
                continue
            db = part.sdf(x[..., window[2]], y[:, window[1], :], z[window[0]])
            da = d[window]
            h = np.clip(0.5 + 0.5 * (db - da) / np.float32(k), 0, 1)
            d[window] = db + (da - db) * h - np.float32(k) * h * (1 - h)
        return d

    def bounds(self):
        los, his = zip(self.base.bounds(), *(part.bounds() for part, _ in self.parts))
        return np.min(los, axis=0), np.max(his, axis=0)


class Offset(Shape):
    """``shape`` grown by ``amount`` (shrunk when negative).

    ``amount`` may be a function of x, y, z; it must then not be positive, since the bounds are
    those of ``shape``.
    """

    def __init__(self, shape, amount):
        self.shape, self.amount = shape, amount

    def _amount(self, x, y, z):
        return self.amount(x, y, z) if callable(self.amount) else np.float32(self.amount)

    def sdf(self, x, y, z):
        return self.shape.sdf(x, y, z) - self._amount(x, y, z)

    def bounds(self):
        lo, hi = self.shape.bounds()
        grow = 0.0 if callable(self.amount) else max(float(self.amount), 0.0)
        return lo - grow, hi + grow


class Shell(Shape):
    """The layer of ``shape`` within ``thickness`` of its surface, on the inside.

    ``thickness`` may be a function of x, y, z (a skull thinner at the temples).
    """

    def __init__(self, shape, thickness):
        self.shape, self.thickness = shape, thickness

    def sdf(self, x, y, z):
        d = self.shape.sdf(x, y, z)
        t = self.thickness(x, y, z) if callable(self.thickness) else np.float32(self.thickness)
        return np.maximum(d, -(d + t))

    def bounds(self):
        return self.shape.bounds()


# ---------------------------------------------------------------------------------------------
# Grid, coverage regions and the painter


@dataclass
class Region:
    """Coverage in [0, 1] of a shape over a sub-box of the grid.

    ``start`` is the ``(z, y, x)`` index of ``cov[0, 0, 0]``; ``cov`` may have zero size.
    """

    start: tuple
    cov: np.ndarray

    @property
    def stop(self):
        return tuple(s + n for s, n in zip(self.start, self.cov.shape))

    @property
    def slices(self):
        return tuple(slice(a, b) for a, b in zip(self.start, self.stop))

    def _overlap(self, other):
        lo = tuple(max(a, b) for a, b in zip(self.start, other.start))
        hi = tuple(min(a, b) for a, b in zip(self.stop, other.stop))
        if any(h <= l for l, h in zip(lo, hi)):
            return None
        mine = tuple(slice(l - s, h - s) for l, h, s in zip(lo, hi, self.start))
        theirs = tuple(slice(l - s, h - s) for l, h, s in zip(lo, hi, other.start))
        return mine, theirs

    def intersect(self, other):
        """Keep only what ``other`` also covers (``c ← min(c, c_other)``), in place."""
        overlap = self._overlap(other)
        if overlap is None:
            self.cov[...] = 0
            return self
        mine, theirs = overlap
        kept = np.minimum(self.cov[mine], other.cov[theirs])
        self.cov[...] = 0
        self.cov[mine] = kept
        return self

    @staticmethod
    def union(regions):
        """One region covering all of ``regions`` (``c = max c_i``)."""
        regions = [r for r in regions if r.cov.size]
        if not regions:
            return Region((0, 0, 0), np.zeros((0, 0, 0), np.float32))
        lo = tuple(min(r.start[a] for r in regions) for a in range(3))
        hi = tuple(max(r.stop[a] for r in regions) for a in range(3))
        cov = np.zeros(tuple(h - l for l, h in zip(lo, hi)), np.float32)
        for r in regions:
            window = tuple(slice(s - l, e - l) for s, e, l in zip(r.start, r.stop, lo))
            np.maximum(cov[window], r.cov, out=cov[window])
        return Region(lo, cov)


class Grid:
    """The voxel grid of a phantom in normalised coordinates.

    Parameters
    ----------
    shape_xyz : tuple of int
        ``(nx, ny, nz)``.
    size : int
        Voxels per unit length: the size of the longest axis the phantom was designed for.
    """

    def __init__(self, shape_xyz, size):
        nx, ny, nz = (int(n) for n in shape_xyz)
        if min(nx, ny, nz) < 1:
            raise InputError(f"phantom grid: every dimension must be >= 1, got {shape_xyz}")
        self.shape = (nz, ny, nx)
        self.size = int(size)
        self.h = 1.0 / self.size
        self.axes = tuple(((np.arange(n) + 0.5 - n / 2) * self.h).astype(np.float32) for n in (nx, ny, nz))

    @classmethod
    def for_aspect(cls, size, aspect=(1.0, 1.0, 1.0)):
        """The grid of a phantom whose box has the given ``(x, y, z)`` proportions.

        ``size`` voxels span the longest side (``max(aspect)`` must be 1); the other sides get
        ``round(size · aspect)`` voxels, at least one.
        """
        return cls(tuple(max(1, int(round(size * a))) for a in aspect), size)

    @property
    def extent(self):
        """Normalised ``(ex, ey, ez)`` of the box."""
        nz, ny, nx = self.shape
        return nx * self.h, ny * self.h, nz * self.h

    def coords(self, start=(0, 0, 0), stop=None):
        """Broadcastable ``x (1,1,n), y (1,n,1), z (n,1,1)`` of the voxels in ``[start, stop)`` (z, y, x)."""
        stop = self.shape if stop is None else stop
        xs, ys, zs = self.axes
        return (xs[start[2]:stop[2]][None, None, :], ys[start[1]:stop[1]][None, :, None],
                zs[start[0]:stop[0]][:, None, None])

    def _window(self, lo, hi):
        """Index range (z, y, x) of the voxels within ``[lo, hi]`` (xyz) plus the edge margin."""
        start, stop = [], []
        for axis in range(3):
            n = self.shape[axis]
            coord = 2 - axis  # shape is (z, y, x), bounds are (x, y, z)
            half = n / 2
            first = np.floor((lo[coord] / self.h) + half - 0.5 - _MARGIN) if np.isfinite(lo[coord]) else 0
            last = np.ceil((hi[coord] / self.h) + half - 0.5 + _MARGIN) + 1 if np.isfinite(hi[coord]) else n
            start.append(int(np.clip(first, 0, n)))
            stop.append(int(np.clip(last, 0, n)))
        return tuple(start), tuple(stop)

    def coverage(self, d):
        """Smoothstep partial-volume coverage of signed distances ``d`` (normalised units)."""
        t = np.clip(np.float32(0.5) - d * np.float32(self.size / (2 * EDGE_HALF_WIDTH)), 0, 1)
        return t * t * (np.float32(3) - np.float32(2) * t)

    def region(self, shape):
        """The :class:`Region` a shape covers, evaluated only inside its bounding box."""
        start, stop = self._window(*shape.bounds())
        if any(b <= a for a, b in zip(start, stop)):
            return Region(start, np.zeros((0, 0, 0), np.float32))
        d = shape.sdf(*self.coords(start, stop))
        d = np.broadcast_to(d, tuple(b - a for a, b in zip(start, stop)))
        return Region(start, self.coverage(d.astype(np.float32, copy=False)))

    def region_of(self, d, start=(0, 0, 0)):
        """The :class:`Region` of a signed-distance array whose voxel ``[0, 0, 0]`` is ``start``.

        For noise-displaced surfaces (full-grid arrays) and for distances that several regions
        share (see :meth:`distance`); ``d`` must have the full shape of its window.
        """
        return Region(tuple(start), self.coverage(np.asarray(d, dtype=np.float32)))

    def distance(self, shape):
        """``(start, d)``: the signed distance of ``shape`` over its bounding box, evaluated once.

        Shells and offsets of an expensive shape (a smooth union of many parts) are then plain
        arithmetic on ``d``: ``region_of(np.maximum(d, -(d + t)), start)`` is a shell ``t`` thick.
        """
        start, stop = self._window(*shape.bounds())
        window = tuple(max(b - a, 0) for a, b in zip(start, stop))
        if 0 in window:
            return start, np.zeros(window, np.float32)
        d = shape.sdf(*self.coords(start, stop))
        return start, np.ascontiguousarray(np.broadcast_to(d, window), dtype=np.float32)

    def coords_of(self, start, d):
        """The broadcastable coordinates of the window of ``d`` that starts at ``start``."""
        return self.coords(start, tuple(a + n for a, n in zip(start, d.shape)))

    def union(self, shapes):
        """Coverage of the union of many shapes, each evaluated in its own bounding box."""
        return Region.union([self.region(s) for s in shapes])


class Canvas:
    """A float32 volume being painted, with an optional integer label volume.

    Parameters
    ----------
    grid : Grid
    background : float
        Initial value (grey levels, 0–255 scale).
    labels : bool
        Also keep a uint8 label volume (0 = background).
    """

    def __init__(self, grid, background=0.0, labels=False):
        self.grid = grid
        self.data = np.full(grid.shape, background, dtype=np.float32)
        self.labels = np.zeros(grid.shape, dtype=np.uint8) if labels else None

    def paint(self, what, value, *, label=None):
        """Composite ``value`` over the volume with the coverage of ``what``.

        Parameters
        ----------
        what : Shape or Region
        value : float, numpy.ndarray or callable
            A constant, a full-size array, or ``fn(x, y, z)`` evaluated on the region's voxels.
        label : int, optional
            Written to the label volume where the coverage is at least one half.
        """
        region = what if isinstance(what, Region) else self.grid.region(what)
        if region.cov.size == 0:
            return region
        window = region.slices
        if callable(value):
            v = value(*self.grid.coords(region.start, region.stop))
        elif isinstance(value, np.ndarray):
            v = value[window]
        else:
            v = np.float32(value)
        target = self.data[window]
        target += (v - target) * region.cov
        if label is not None and self.labels is not None:
            self.labels[window][region.cov >= 0.5] = label
        return region

    def to_uint8(self):
        """The painted volume rounded and clipped to uint8."""
        return np.clip(np.rint(self.data), 0, 255).astype(np.uint8)
