"""Device buffers derived from volumes and classifications, built once and kept across frames.

A :class:`DeviceCache` (one per renderer) holds, least recently used first out:

* the **atlas** of a set of distinct volumes (:mod:`renderers.cl.atlas`), keyed by the volumes;
* each volume's **brick ranges** (min and max scalar per brick, one-voxel apron), keyed by the
  volume and the brick size, built by the ``brick_minmax`` kernel from the atlas;
* each classification's **hull** (closed triangle mesh around the non-empty bricks, or the box),
  keyed by volume, transfer function, brick size and minimum opacity, built by ``build_hull``
  and rebuilt whenever the transfer function changes (a new key);
* each :class:`core.mesh.Mesh`'s **triangles** (mesh instances and volume boundaries), uploaded
  once and shared by every instance of the mesh.

Keys are the frozen :class:`core.volume.Volume`, :class:`core.transfer.TransferFunction` and
:class:`core.mesh.Mesh` objects themselves (identity, held strongly while cached) and plain numbers. Every command a
frame issues is recorded in :class:`Stages` with its profiling event and summed per stage.
"""

from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from core.errors import InputError
from renderers.cl import atlas as atlas_module

ATLAS_CACHE_SIZE = 2
VOLUME_CACHE_SIZE = 64
HULL_CACHE_SIZE = 128
MESH_CACHE_SIZE = 128


class Stages:
    """Profiling events of one frame, by stage name."""

    def __init__(self):
        self.events = defaultdict(list)

    def add(self, stage, event):
        self.events[stage].append(event)
        return event

    def seconds(self):
        """Device seconds per stage (call after the queue finished)."""
        return {stage: sum(e.profile.end - e.profile.start for e in events) * 1e-9
                for stage, events in self.events.items()}


@dataclass
class Atlas:
    """The device atlas of some volumes and where each one sits."""

    buffer: object
    layout: atlas_module.Layout
    dtype: np.dtype
    volumes: tuple

    def slot(self, volume):
        for candidate, origin in zip(self.volumes, self.layout.origins):
            if candidate is volume:
                return origin
        raise KeyError(volume.name)

    @property
    def nbytes(self):
        ax, ay, az = self.layout.shape_xyz
        return ax * ay * az * self.dtype.itemsize


@dataclass
class Hull:
    """A closed triangle mesh in object space on the device: ``3 × triangles`` float4 vertices."""

    buffer: object
    triangles: int


def _same(a, b):
    if isinstance(a, (int, float, str, bool)) and isinstance(b, (int, float, str, bool)):
        return a == b
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return a is b


class DeviceCache:
    """Atlases, brick ranges and hulls on one device (see the module notes).

    Parameters
    ----------
    device : renderers.cl.context.Device
    """

    def __init__(self, device):
        self.device = device
        self._entries = {}

    def clear(self):
        """Forget every atlas, brick range, hull and mesh, so that the next frame builds them again."""
        self._entries = {}

    def _get(self, kind, key, capacity, build):
        entries = self._entries.setdefault(kind, [])
        for index, (cached_key, value) in enumerate(entries):
            if _same(cached_key, key):
                entries.insert(0, entries.pop(index))
                return value
        value = build()
        entries.insert(0, (key, value))
        del entries[capacity:]
        return value

    def atlas(self, volumes, stages):
        """The :class:`Atlas` holding ``volumes`` (distinct, in order), uploaded on first use."""
        import pyopencl as cl

        def build():
            dtype = atlas_module.storage_dtype(volumes)
            layout = atlas_module.pack([v.shape_xyz for v in volumes])
            host = atlas_module.fill(volumes, layout, dtype)
            if host.nbytes > self.device.device.max_mem_alloc_size:
                raise InputError(f"scene volumes: the atlas of {len(volumes)} volumes needs {host.nbytes} bytes, more "
                                 f"than one buffer of {self.device.device.name.strip()} holds "
                                 f"({self.device.device.max_mem_alloc_size}); use fewer or smaller volumes")
            buffer = cl.Buffer(self.device.context, cl.mem_flags.READ_ONLY, size=host.nbytes)
            stages.add("upload", cl.enqueue_copy(self.device.queue, buffer, host, is_blocking=False))
            self.device.queue.finish()  # `host` must outlive the transfer
            return Atlas(buffer=buffer, layout=layout, dtype=dtype, volumes=tuple(volumes))

        return self._get("atlas", tuple(volumes), ATLAS_CACHE_SIZE, build)

    def brick_ranges(self, kernels, atlas, volume, brick, stages):
        """``(buffer of float2 per brick, (bx, by, bz))`` for ``volume`` in ``brick³`` bricks."""
        import pyopencl as cl

        def build():
            dims = volume.shape_xyz
            bricks = tuple(-(-n // brick) for n in dims)
            buffer = cl.Buffer(self.device.context, cl.mem_flags.READ_WRITE, size=8 * int(np.prod(bricks)))
            event = kernels["brick_minmax"](self.device.queue, bricks, None, atlas.buffer,
                                         _int4(atlas.layout.shape_xyz), _int4(atlas.slot(volume)), _int4(dims),
                                         np.int32(brick), _int4(bricks), buffer)
            stages.add("bricks", event)
            return buffer, bricks

        return self._get("bricks", (volume, brick), VOLUME_CACHE_SIZE, build)

    def hull(self, kernels, atlas, instance, brick, min_opacity, stages):
        """The :class:`Hull` of ``instance``'s classification: ``brick=None`` gives the box."""
        import pyopencl as cl

        volume, tf = instance.volume, instance.transfer_function
        spacing = np.asarray(volume.spacing)
        extent = np.asarray(volume.extent)
        if brick is None:
            ranges, bricks, brick_extent = None, (1, 1, 1), extent
            key = (volume, "box")
        else:
            ranges, bricks = self.brick_ranges(kernels, atlas, volume, brick, stages)
            brick_extent = brick * spacing
            key = (volume, tf, brick, float(min_opacity))

        def build():
            context, queue = self.device.context, self.device.queue
            visible = np.concatenate([[0], np.cumsum(tf.table[:, 3] > min_opacity)]).astype(np.int32)
            prefix = cl.Buffer(context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=visible)
            count = cl.Buffer(context, cl.mem_flags.READ_WRITE, size=4)
            bx, by, bz = bricks
            capacity = 12 * (bx * by + by * bz + bz * bx)  # the box's faces; concave hulls may need more
            ranges_arg = ranges if ranges is not None else prefix  # unread when every brick counts
            while True:
                vertices = cl.Buffer(context, cl.mem_flags.READ_WRITE, size=max(48 * capacity, 48))
                stages.add("hull", cl.enqueue_fill_buffer(queue, count, np.uint32(0), 0, 4))
                stages.add("hull", kernels["build_hull"](queue, bricks, None, ranges_arg, _int4(bricks),
                                                      _float4(brick_extent), _float4(extent), prefix,
                                                      np.int32(tf.size), np.int32(ranges is None),
                                                      np.uint32(capacity), vertices, count))
                found = np.empty(1, np.uint32)
                stages.add("hull", cl.enqueue_copy(queue, found, count))
                if found[0] <= capacity:
                    return Hull(buffer=vertices, triangles=int(found[0]))
                capacity = int(found[0])

        return self._get("hull", key, HULL_CACHE_SIZE, build)

    def mesh(self, mesh, stages):
        """The :class:`Hull` of ``mesh``'s triangles (object space, float32), uploaded on first use."""
        import pyopencl as cl

        def build():
            corners = np.zeros((mesh.triangle_count, 3, 4), np.float32)
            corners[..., :3] = mesh.vertices[mesh.faces]
            buffer = cl.Buffer(self.device.context, cl.mem_flags.READ_ONLY, size=corners.nbytes)
            stages.add("upload", cl.enqueue_copy(self.device.queue, buffer, corners, is_blocking=True))
            return Hull(buffer=buffer, triangles=mesh.triangle_count)

        return self._get("mesh", mesh, MESH_CACHE_SIZE, build)


def _int4(values):
    import pyopencl.cltypes as cltypes

    return cltypes.make_int4(*(int(v) for v in values), 0)


def _float4(values):
    import pyopencl.cltypes as cltypes

    return cltypes.make_float4(*(float(v) for v in values), 0.0)
