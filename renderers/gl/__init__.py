"""OpenGL backends (moderngl, headless EGL): the multi-pass GPU ray caster of Krüger & Westermann
2003 (``gl-raycast``), view-aligned 3D-texture slicing (``gl-slicer``) and the depth-peeling
multi-volume caster that Kainz et al. 2009 measure against (``gl-peel``, :mod:`.peeling` with its
shaders in :mod:`.peeling_glsl`).

Layout, so that later GL backends (early-z iso slicing, lens volumes) reuse the pieces:

* :mod:`.context`: the process's one context, its checks, facts and compiled programs;
* :mod:`.glsl`: the GLSL that defines a sample (reconstruction, classification, opacity
  correction, shading, pixel rays), shared by every program;
* :mod:`.resources`: volume, gradient, min–max and transfer-function textures, cached per volume
  and classification, their uploads timed apart from the frame;
* :mod:`.emptyspace`: the min–max block grid and CT table (NumPy);
* :mod:`.view`: matrices, ray uniforms, step and box mesh of a frame;
* :mod:`.timing`: per-pass device timing and fragment counts;
* :mod:`.base`: :class:`GLRenderer`, the backends' common base.

Importing this package imports neither moderngl nor a context; both come with the first frame
(or :func:`context.probe`).
"""
