"""volbench's base package: the contract every other package builds on.

Errors, validation helpers, :class:`~core.volume.Volume`, transfer functions and presets' types
(:mod:`core.transfer`), :class:`~core.camera.Camera`, :class:`~core.scene.Shading` and
:class:`~core.scene.Scene`, and the papers' ids (:mod:`core.papers`). It imports none of the
other top-level packages: ``datasets``, ``renderers`` and ``reports`` import it and libraries
only, and ``pipeline`` (scene files, experiments, jobs, CLI) sits on top of them all.
"""
