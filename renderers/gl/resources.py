"""Textures derived from volumes and classifications, built once and kept across frames.

A :class:`ResourceCache` holds, per renderer:

* the **scalar texture** of a volume (``GL_R8`` for uint8, ``GL_R16`` for uint16, ``GL_R32F`` for
  float32), linear filtering, clamp-to-edge. The raw values are uploaded with the affine map to
  normalised scalars applied in the shader, unless some value lies outside the volume's
  ``value_range``: normalisation clips those, and clipping does not commute with interpolation,
  so such a volume is uploaded normalised as ``GL_R32F``. Filtering precision depends on the
  driver: llvmpipe filters ``GL_R8`` with 8-bit fixed-point weights (measured: errors up to
  1/256 of the difference between neighbouring voxels, which moves a few grazing iso-surface
  hits) and ``GL_R16``/``GL_R32F`` in float; GPUs commonly use 8-bit weights for every format;
* the **gradient texture** (``GL_RGB16F``): object-space central differences at the voxels,
  ``(v[i+1] − v[i−1]) / 2s`` with clamped neighbours. Trilinear filtering of it equals the
  reference's central differences of the trilinear field everywhere inside the voxel-centre
  lattice; in the outer half voxel of the box the reference's one-sided reach differs;
* the **min–max block grid** (``GL_RG8UI``, :func:`renderers.gl.emptyspace.block_minmax`);
* the **transfer-function table** (``GL_RGBA32F``, ``N × 1``) and the **CT table**
  (``GL_R8UI``, 256 × 256, :func:`renderers.gl.emptyspace.visibility_table`), rebuilt when the
  transfer function (or the minimum opacity) changes.

Keys are the frozen :class:`core.volume.Volume` and :class:`core.transfer.TransferFunction`
objects themselves (by identity, held strongly while cached). What a frame builds is timed in
:class:`Preparation`: CPU work per kind (``gradients``, ``minmax``, ``ct_table``) and every
transfer to the device as ``upload`` (wall clock up to ``glFinish``), apart from the frame time.

The CPU side of the gradient texture and the block grids is kept for the whole process, by the volume's
content (:func:`derived`): every run of a pipeline's warm worker loads its volume afresh and builds a new
renderer, and computing them again took most of each run's first frame (gradients and min–max of a 128³
volume: 128 of 230 ms of gl-raycast's first frame, measured on llvmpipe); none of them is a timed stage.
"""

import threading
import time
import weakref
from collections import OrderedDict
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from renderers.gl import emptyspace
from renderers.gl import lens as lenses

VOLUME_CACHE_SIZE = 2
"""Volumes kept per renderer (each with its gradient texture and block grids)."""

CLASSIFICATION_CACHE_SIZE = 4
"""Transfer-function and CT tables kept per renderer."""

_FORMATS = {np.dtype(np.uint8): ("f1", 255.0, "R8"), np.dtype(np.uint16): ("nu2", 65535.0, "R16"),
            np.dtype(np.float32): ("f4", 1.0, "R32F")}


DERIVED_CACHE_BYTES = 512 * 2**20
"""Bytes of derived arrays (:func:`derived`) a process keeps at most, least recently used out first."""

DERIVED_CACHE_SHARE = 0.02
"""Share of the machine's memory those arrays may take in one process: a pipeline keeps up to eight idle
workers (:data:`pipeline.workers.MAX_IDLE_WORKERS`), so on a small machine each keeps less."""


def derived_capacity():
    """Bytes :func:`derived` keeps: :data:`DERIVED_CACHE_BYTES`, or less on a machine with little memory."""
    from core.resources import memory_limit

    return min(DERIVED_CACHE_BYTES, int(DERIVED_CACHE_SHARE * memory_limit()))


_derived = OrderedDict()  # (kind, content, params) -> array
_content_keys = weakref.WeakKeyDictionary()  # Volume -> its content hash, computed once per object
_derived_lock = threading.Lock()


def _content_key(volume):
    with _derived_lock:
        key = _content_keys.get(volume)
    if key is None:
        key = volume.content_hash()
        with _derived_lock:
            _content_keys[volume] = key
    return key


def derived(volume, kind, params, build):
    """The array ``build()`` derives from ``volume``, kept for the process by the volume's content.

    Parameters
    ----------
    volume : core.volume.Volume
        Keyed by :meth:`~core.volume.Volume.content_hash` (data, spacing, value range), so that another
        ``Volume`` object of the same data, a later run's, finds it.
    kind : str
        What is derived (``"gradients"``, ``"minmax"``).
    params : tuple
        Whatever else it depends on (the block size).
    build : callable
        Makes the array when it is not kept; its result must not be written to afterwards.

    Returns
    -------
    numpy.ndarray
        Read-only; an array larger than :func:`derived_capacity` is built every time and not kept.
    """
    key = (kind, _content_key(volume), tuple(params))
    with _derived_lock:
        if key in _derived:
            _derived.move_to_end(key)
            return _derived[key]
    array = np.asarray(build())
    array.flags.writeable = False
    capacity = derived_capacity()
    if array.nbytes <= capacity:
        with _derived_lock:
            _derived[key] = array
            while sum(a.nbytes for a in _derived.values()) > capacity:
                _derived.popitem(last=False)
    return array


class Preparation:
    """What one frame built: seconds per preparation stage and the names of the uploads."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.timings = {}
        self.uploaded = []

    @contextmanager
    def cpu(self, stage):
        """Time CPU work (a derived array) as ``stage``."""
        start = time.perf_counter()
        yield
        self.timings[stage] = self.timings.get(stage, 0.0) + time.perf_counter() - start

    @contextmanager
    def upload(self, name):
        """Time a transfer to the device (until ``glFinish``) as ``upload`` and record ``name``."""
        start = time.perf_counter()
        yield
        self.ctx.finish()
        self.timings["upload"] = self.timings.get("upload", 0.0) + time.perf_counter() - start
        self.uploaded.append(name)


@dataclass
class ScalarTexture:
    """A volume's scalar texture and the map from its values to normalised scalars."""

    texture: object
    value_map: tuple
    format: str

    def release(self):
        self.texture.release()


def texture_source(volume):
    """``(array, moderngl dtype, (scale, offset), format)`` to upload for ``volume``'s scalars."""
    dtype, top, name = _FORMATS[volume.data.dtype]
    lo, hi = volume.value_range
    if lo <= float(volume.data.min()) and float(volume.data.max()) <= hi:
        # Texture value v/top; normalised scalar (v - lo)/(hi - lo), an affine map of it.
        return volume.data, dtype, (top / (hi - lo), -lo / (hi - lo)), name
    return volume.normalized(np.float32), "f4", (1.0, 0.0), "R32F (normalised: values outside value_range)"


def central_gradients(normalised, spacing):
    """Object-space gradient at every voxel, ``(nz, ny, nx, 3)`` float32 ordered (x, y, z)."""
    padded = np.pad(normalised.astype(np.float32), 1, mode="edge")
    sx, sy, sz = spacing
    inner = (slice(1, -1),) * 3
    out = np.empty(normalised.shape + (3,), dtype=np.float32)
    out[..., 0] = (padded[inner[0], inner[1], 2:] - padded[inner[0], inner[1], :-2]) / (2 * sx)
    out[..., 1] = (padded[inner[0], 2:, inner[2]] - padded[inner[0], :-2, inner[2]]) / (2 * sy)
    out[..., 2] = (padded[2:, inner[1], inner[2]] - padded[:-2, inner[1], inner[2]]) / (2 * sz)
    return out


def _same(a, b):
    """Cache-key equality: identity for objects, value for plain numbers and strings."""
    if isinstance(a, (int, float, str)) and isinstance(b, (int, float, str)):
        return a == b
    return a is b


def _release(value):
    if isinstance(value, tuple):
        for item in value:
            _release(item)
    elif hasattr(value, "release"):
        value.release()


class ResourceCache:
    """GL textures per volume and per classification, least recently used first out.

    Parameters
    ----------
    ctx : moderngl.Context
    volumes : int
        Volumes whose textures stay alive together: a multi-volume frame needs all of its own.
    """

    def __init__(self, ctx, *, volumes=VOLUME_CACHE_SIZE):
        self.ctx = ctx
        self.volumes = volumes
        self._entries = {}

    def _get(self, kind, key, capacity, build):
        entries = self._entries.setdefault(kind, [])
        for index, (cached_key, value) in enumerate(entries):
            if len(cached_key) == len(key) and all(_same(a, b) for a, b in zip(cached_key, key)):
                entries.insert(0, entries.pop(index))
                return value
        value = build()
        entries.insert(0, (key, value))
        for _, evicted in entries[capacity:]:
            _release(evicted)
        del entries[capacity:]
        return value

    def _texture3d(self, array, components, dtype, prep, name, *, linear):
        import moderngl

        nz, ny, nx = array.shape[:3]
        with prep.upload(name):
            texture = self.ctx.texture3d((nx, ny, nz), components, np.ascontiguousarray(array).tobytes(),
                                         dtype=dtype)
            texture.repeat_x = texture.repeat_y = texture.repeat_z = False
            mode = moderngl.LINEAR if linear else moderngl.NEAREST
            texture.filter = (mode, mode)
        return texture

    def _texture2d(self, array, components, dtype, prep, name):
        import moderngl

        height, width = array.shape[:2]
        with prep.upload(name):
            texture = self.ctx.texture((width, height), components, np.ascontiguousarray(array).tobytes(),
                                       dtype=dtype)
            texture.repeat_x = texture.repeat_y = False
            texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        return texture

    def transfer_tables(self, tfs, prep):
        """``(buffer, offsets)``: every table of ``tfs`` in order as one RGBA32F storage buffer."""
        def build():
            with prep.upload("transfer_functions"):
                buffer = self.ctx.buffer(np.concatenate([tf.table for tf in tfs]).astype(np.float32).tobytes())
            return buffer, tuple(np.cumsum([0] + [tf.size for tf in tfs[:-1]]).tolist())

        return self._get("tables", tuple(tfs), CLASSIFICATION_CACHE_SIZE, build)

    def scalars(self, volume, prep):
        """The :class:`ScalarTexture` of ``volume``."""
        def build():
            array, dtype, value_map, name = texture_source(volume)
            return ScalarTexture(self._texture3d(array, 1, dtype, prep, "volume", linear=True), value_map, name)

        return self._get("scalars", (volume,), self.volumes, build)

    def gradients(self, volume, prep):
        """The gradient texture of ``volume``."""
        def compute():
            with prep.cpu("gradients"):
                # Half floats: a normal's direction to ~1e-3, half the memory of float32.
                return central_gradients(volume.normalized(np.float32), volume.spacing).astype(np.float16)

        def build():
            gradient = derived(volume, "gradients", (), compute)
            return self._texture3d(gradient, 3, "f2", prep, "gradients", linear=True)

        return self._get("gradients", (volume,), self.volumes, build)

    def blocks(self, volume, block_size, prep):
        """``(texture, (bx, by, bz))``: the min–max grid of ``volume`` in ``block_size³`` blocks."""
        def compute():
            with prep.cpu("minmax"):
                return emptyspace.block_minmax(volume.normalized(np.float32), block_size)

        def build():
            grid = derived(volume, "minmax", (int(block_size),), compute)
            bz, by, bx = grid.shape[:3]
            return self._texture3d(grid, 2, "u1", prep, "minmax", linear=False), (bx, by, bz)

        return self._get("blocks", (volume, block_size), self.volumes, build)

    def lens_mask(self, instance, lens, prep):
        """The 3-D mask of ``lens`` on ``instance``'s voxels (:func:`renderers.gl.lens.lens_mask`), linear."""
        def build():
            with prep.cpu("lens_mask"):
                mask = lenses.lens_mask(instance.volume, instance.transform, lens)
            return self._texture3d(mask, 1, "f1", prep, "lens_mask", linear=True)

        return self._get("lens_mask", (instance.volume, instance.transform, lens), CLASSIFICATION_CACHE_SIZE, build)

    def transfer_function(self, tf, prep):
        """The ``N × 1`` RGBA32F texture of ``tf``'s table."""
        return self._get("tf", (tf,), CLASSIFICATION_CACHE_SIZE,
                         lambda: self._texture2d(tf.table[None], 4, "f4", prep, "transfer_function"))

    def visibility_table(self, tf, min_opacity, prep):
        """The CT(min, max) texture of ``tf`` with opacities ``<= min_opacity`` counted empty."""
        def build():
            with prep.cpu("ct_table"):
                table = emptyspace.visibility_table(tf.table[:, 3], min_opacity)
            return self._texture2d(table, 1, "u1", prep, "ct_table")

        return self._get("ct", (tf, float(min_opacity)), CLASSIFICATION_CACHE_SIZE, build)

    def release(self):
        """Release every cached texture."""
        for entries in self._entries.values():
            for _, value in entries:
                _release(value)
        self._entries = {}
