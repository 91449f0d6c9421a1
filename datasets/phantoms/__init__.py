"""Phantom generators, one module per family; each ``generator(size, seed, **params) -> Volume``.

* :mod:`.heads`: ``mri_head``, ``ct_skull``, ``folded_brain``
* :mod:`.vessels`: ``aneurysm`` and the vessel-tree builder the torso shares
* :mod:`.foot`, :mod:`.engine`, :mod:`.torso`
* :mod:`.controls`: ``sphere``, ``constant_cube``, ``checkerboard``, ``fbm_control``
* :mod:`.clouds`: ``smoke_cloud``, ``golden_lady``
* :mod:`.geology`: ``seismic``; :mod:`.bonsai`: ``bonsai_like``
* :mod:`.tubes`: ``tube``, the thin-feature control of iso-surfaces

They are registered, with presets and targets, in :mod:`datasets.registry`; load them through
:func:`datasets.load`, which caches them.

Orientation follows the scanners and the real scans: anatomy runs along z (feet → crown, the
slice axis), the face looks towards −y, and the engine's short axis is z. The default camera is
y-up, so a scene that wants a head upright rotates it −90° about x.
"""
