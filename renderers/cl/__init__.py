"""OpenCL backends (pyopencl; PoCL on a CPU, any OpenCL device elsewhere): the tile-based
multi-volume ray caster of Kainz et al. 2009 (``cl-tiled``), with meshes, surfaces, homogeneous
media and CSG, in ``dvr`` and ``mip``.

Layout:

* :mod:`.context`: device selection, the process's contexts, queues and built programs;
* ``kernels/``: the OpenCL C sources (``common.cl``: object record and rays; ``binning.cl``:
  triangle kernel; ``hull.cl``: brick ranges and hulls; ``pixel.cl``: fragment lists and the
  segment walk);
* :mod:`.atlas`: packing volumes into one 3-D atlas;
* :mod:`.scene`: the scene as object records, leaves and the CSG program, tables and camera arguments;
* :mod:`.resources`: the atlas, brick ranges, hulls and mesh triangles cached on the device, profiling stages;
* :mod:`.tiled`: :class:`~renderers.cl.tiled.ClTiledRenderer`.

The registry names this package (not :mod:`.tiled`), so that the pipeline's code digest of a
``cl-tiled`` run covers every file here, the ``.cl`` kernels included. Importing it imports
neither pyopencl nor a context; both come with the first frame (or :func:`context.probe`).
"""

from renderers.cl.tiled import ClTiledRenderer

__all__ = ["ClTiledRenderer"]
