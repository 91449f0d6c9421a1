"""Seeded stand-ins for the meshes of Kainz et al. 2009 (reproduction guide 002, §6).

Each generator returns a closed, two-manifold, consistently oriented :class:`core.mesh.Mesh`
(outward winding), deterministic for its parameters and seed:

=====================  =====================================================================
``phantom_isosurface``  marching cubes (scikit-image) of a registered phantom at a level (C6)
``vessel_tree``         procedural branching tubes, tapered, unioned as one implicit surface (C7)
``helical_screw``       a threaded rod: a helical thread of triangular profile on a core (S3)
``boxes_in_a_row``      axis-aligned cubes along z, 12 triangles each (S2)
``rod``                 a closed n-gon prism, ``4n − 4`` triangles (76 for n = 20, Fig. 1(4))
``noisy_sphere``        an icosphere displaced radially by smooth seeded noise (C7's tumour)
=====================  =====================================================================

``triangles`` (where a generator takes it) decimates to about that many triangles with
fast-simplification's quadric decimation; the result is within :data:`TRIANGLE_TOLERANCE` of the
request. Meshes are repaired with trimesh (merged vertices, degenerate and duplicate faces
dropped, winding made consistent and outward) and checked; one that stays open or non-manifold
raises :class:`~core.errors.InputError` rather than being used.
"""

import fast_simplification
import numpy as np
import trimesh
from skimage.measure import marching_cubes

from core.errors import InputError
from core.mesh import Mesh
from core.resources import check_memory, largest_fitting
from core.validation import check_positive_int, check_scalar

TRIANGLE_TOLERANCE = 0.02
"""Largest relative difference between a decimated mesh's triangle count and the request."""

MESH_BYTES_PER_TRIANGLE = 1024
"""Peak memory of building a mesh, in bytes per triangle before decimation: the raw arrays,
trimesh's repair (merged vertices, unique faces, winding) and the closed-surface check hold
several copies (tracemalloc: 750 to 800 bytes a triangle at 60 000–160 000 triangles)."""

VESSEL_BYTES_PER_CELL = 160
"""Peak memory of :func:`vessel_tree`'s grid, in bytes per cell: float64 coordinates, the field
and one segment's distances (tracemalloc: 137 bytes a cell at 64³ and 96³)."""


def _check_triangles(count, *, what, fix, shown=None):
    """Refuse a mesh of ``count`` triangles that this machine cannot build, before building it.

    ``fix`` receives the largest triangle count that fits; ``shown`` replaces the count in the
    message where it is a formula.
    """
    check_memory(count * MESH_BYTES_PER_TRIANGLE, what=f"{what}: {shown or count} triangles",
                 detail=f"{MESH_BYTES_PER_TRIANGLE} bytes a triangle while it is built and repaired",
                 fix=lambda limit: fix(limit // MESH_BYTES_PER_TRIANGLE))


def closed_mesh(vertices, faces, *, name, meta=None):
    """A :class:`Mesh` from raw triangles, repaired with trimesh and checked closed and two-manifold.

    Raises
    ------
    InputError
        The surface is still open or non-manifold after the repair.
    """
    surface = trimesh.Trimesh(np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.int64), process=True)
    surface.update_faces(surface.nondegenerate_faces())
    surface.update_faces(surface.unique_faces())
    surface.remove_unreferenced_vertices()
    trimesh.repair.fix_normals(surface)
    if not (surface.is_watertight and surface.is_winding_consistent):
        raise InputError(f"mesh {name!r}: not a closed, consistently oriented two-manifold after repair "
                         f"({len(surface.faces)} triangles); change the generator's parameters (finer grid, "
                         "more triangles)")
    return Mesh(surface.vertices, surface.faces, name=name, meta=dict(meta or {}, triangles=len(surface.faces)))


def decimate(vertices, faces, triangles, *, name, meta=None):
    """Quadric decimation to about ``triangles`` triangles, then :func:`closed_mesh`.

    ``None`` or a count at or above the input's keeps the input. Quadric decimation does not
    preserve topology: where it pinches two sheets into a non-manifold edge, the targets within
    :data:`TRIANGLE_TOLERANCE` of the request are tried in turn before giving up.
    """
    if triangles is not None:
        triangles = check_positive_int(triangles, name=f"mesh {name!r} triangles", minimum=4)
    faces = np.asarray(faces, dtype=np.int64)
    meta = dict(meta or {}, triangles_before_decimation=len(faces))
    if triangles is None or triangles >= len(faces):
        return closed_mesh(vertices, faces, name=name, meta=meta)
    problem = None
    for shift in (0.0, -0.005, 0.005, -0.01, 0.01, -0.015, 0.015):
        points, simplified = fast_simplification.simplify(np.asarray(vertices, dtype=np.float64), faces.astype(np.int32),
                                                          target_count=round(triangles * (1 + shift)))
        try:
            return closed_mesh(points, simplified, name=name, meta=meta)
        except InputError as error:
            problem = error
    raise problem


def _isosurface(field, level, spacing, origin, *, name, triangles, meta):
    """Closed marching-cubes surface of ``field`` (``[z, y, x]``, padded so it cannot touch the border)."""
    pad = np.pad(field, 1, constant_values=min(float(field.min()), level) - 1.0)
    if not pad.min() < level < pad.max():
        raise InputError(f"mesh {name!r}: level {level} is outside the field's range "
                         f"[{float(field.min()):.4g}, {float(field.max()):.4g}], so there is no surface")
    sx, sy, sz = spacing
    vertices, faces, _, _ = marching_cubes(pad, level=level, spacing=(sz, sy, sx))
    # (z, y, x) → (x, y, z); padded index j sits at origin + (j − 1)·s.
    vertices = vertices[:, ::-1] - np.array([sx, sy, sz]) + np.asarray(origin)
    return decimate(vertices, faces, triangles, name=name, meta=meta)


def phantom_isosurface(*, dataset="sphere", size=64, seed=0, level=0.5, smoothing=1.5, triangles=None,
                       cache_dir=None):
    """Marching cubes of a registered phantom's normalised scalars at ``level`` (C6's bone surface).

    ``smoothing`` is the σ, in voxels, of a Gaussian blur before polygonising (0: none): it
    removes the one-voxel plates and noise that decimation would pinch into non-manifold edges.
    Vertices are in the volume's object space (voxel ``i`` at ``(i + ½)·s``), so the mesh fits a
    :class:`~core.scene.VolumeInstance` of the same phantom as a ``boundary`` or sits on it with
    the same transform.
    """
    import datasets
    from scipy.ndimage import gaussian_filter

    level = check_scalar(level, name="phantom_isosurface level", low=0, high=1, low_open=True, high_open=True)
    smoothing = check_scalar(smoothing, name="phantom_isosurface smoothing", low=0)
    spec = datasets.get(dataset)
    if spec.kind == "phantom":
        spec.check_memory(check_positive_int(size, name="phantom_isosurface size", minimum=datasets.MIN_SIZE),
                          where="phantom_isosurface size")
    volume = datasets.load(dataset, size=size, seed=seed, cache_dir=cache_dir)
    field = gaussian_filter(volume.normalized(np.float32), smoothing) if smoothing else volume.normalized(np.float32)
    spacing = volume.spacing
    return _isosurface(field, level, spacing, 0.5 * np.asarray(spacing), name=f"{dataset}_iso", triangles=triangles,
                       meta={"generator": "phantom_isosurface", "dataset": dataset, "size": size, "seed": seed,
                             "level": level, "smoothing": smoothing})


def vessel_tree(*, depth=4, seed=0, resolution=64, radius=0.08, triangles=None):
    """Recursively branching tapered tubes in the unit cube, one closed surface (C7's portal veins).

    Each segment splits in two at its end, turned by a seeded random angle, shorter and thinner
    by a factor 0.7; the tubes are the zero level of ``max_i (r_i(p) − dist_i(p))`` over the
    segments (their union), polygonised on a ``resolution``³ grid.
    """
    depth = check_positive_int(depth, name="vessel_tree depth")
    resolution = check_positive_int(resolution, name="vessel_tree resolution", minimum=8)
    radius = check_scalar(radius, name="vessel_tree radius", low=0, high=0.25, low_open=True)
    check_memory(resolution ** 3 * VESSEL_BYTES_PER_CELL, what=f"vessel_tree resolution {resolution}",
                 detail=f"{resolution}³ cells × {VESSEL_BYTES_PER_CELL} bytes",
                 fix=lambda limit: f"use resolution ≤ {largest_fitting(limit, VESSEL_BYTES_PER_CELL, power=3)}")
    # Every level doubles the segments and each takes a pass over the whole grid; a level whose
    # tubes are thinner than half a cell adds that work without adding a surface.
    thinnest = radius * 0.7 ** (depth - 1)
    if depth > 1 and thinnest < 0.5 / resolution:
        deepest = max(1, 1 + int(np.floor(np.log(0.5 / (resolution * radius)) / np.log(0.7))))
        raise InputError(f"vessel_tree depth {depth}: the last level's tubes are {thinnest:.2g} wide, thinner than "
                         f"half a cell of the {resolution}³ grid ({0.5 / resolution:.2g}), so marching cubes cannot "
                         f"show them and the 2^{depth - 1} segments of that level only cost time; use depth ≤ {deepest} "
                         "or a larger resolution or radius")
    rng = np.random.default_rng(seed)
    segments = []

    def grow(start, direction, length, r, level):
        end = start + direction * length
        segments.append((start, end, r, 0.7 * r))
        if level == depth:
            return
        for side in (-1.0, 1.0):
            axis = np.cross(direction, rng.normal(size=3))
            axis /= np.linalg.norm(axis)
            angle = side * rng.uniform(0.35, 0.7)
            turned = direction * np.cos(angle) + np.cross(axis, direction) * np.sin(angle)
            grow(end, turned / np.linalg.norm(turned), 0.7 * length, 0.7 * r, level + 1)

    grow(np.array([0.5, 0.5, 0.05]), np.array([0.0, 0.0, 1.0]), 0.3, radius, 1)
    h = 1.0 / resolution
    z, y, x = np.mgrid[0:resolution, 0:resolution, 0:resolution] * h + 0.5 * h
    points = np.stack([x, y, z], axis=-1)
    field = np.full(x.shape, -np.inf)
    for start, end, r0, r1 in segments:
        axis = end - start
        s = np.clip(((points - start) @ axis) / (axis @ axis), 0.0, 1.0)
        distance = np.linalg.norm(points - (start + s[..., None] * axis), axis=-1)
        field = np.maximum(field, r0 + (r1 - r0) * s - distance)
    return _isosurface(field, 0.0, (h, h, h), (0.5 * h,) * 3, name="vessel_tree", triangles=triangles,
                       meta={"generator": "vessel_tree", "depth": depth, "seed": seed, "resolution": resolution,
                             "radius": radius, "segments": len(segments)})


def helical_screw(*, turns=40, pitch=0.1, core_radius=0.3, thread_depth=0.15, sides=24, rows_per_turn=12,
                  triangles=None):
    """A threaded rod along z: radius ``core + depth·tri(z/pitch − φ/2π)`` with ``tri`` a triangle wave.

    Seen along its axis, a ray between the core and the crest crosses the thread twice per turn,
    so ``turns = 40`` gives a depth complexity of about 81 (guide S3). Without ``triangles`` the
    mesh has ``2·sides·(rows + 1)`` triangles, ``rows = turns·rows_per_turn``.
    """
    turns = check_positive_int(turns, name="helical_screw turns")
    sides = check_positive_int(sides, name="helical_screw sides", minimum=3)
    rows_per_turn = check_positive_int(rows_per_turn, name="helical_screw rows_per_turn", minimum=2)
    pitch = check_scalar(pitch, name="helical_screw pitch", low=0, low_open=True)
    core_radius = check_scalar(core_radius, name="helical_screw core_radius", low=0, low_open=True)
    thread_depth = check_scalar(thread_depth, name="helical_screw thread_depth", low=0)
    rows = turns * rows_per_turn
    _check_triangles(2 * sides * (rows + 1), what=f"helical_screw turns {turns}, rows_per_turn {rows_per_turn}, "
                     f"sides {sides}", fix=lambda most: f"make 2·sides·(turns·rows_per_turn + 1) ≤ {most}")
    phi = 2 * np.pi * np.arange(sides) / sides
    z = pitch * turns * np.arange(rows + 1) / rows
    phase = (z[:, None] / pitch - phi[None, :] / (2 * np.pi)) % 1.0
    r = core_radius + thread_depth * (1.0 - np.abs(2.0 * phase - 1.0))
    ring = np.stack([r * np.cos(phi), r * np.sin(phi), np.broadcast_to(z[:, None], r.shape)], axis=-1).reshape(-1, 3)
    vertices = np.concatenate([ring, [[0.0, 0.0, z[0]], [0.0, 0.0, z[-1]]]])
    index = np.arange((rows + 1) * sides).reshape(rows + 1, sides)
    a, b = index[:-1], np.roll(index[:-1], -1, axis=1)
    c, d = index[1:], np.roll(index[1:], -1, axis=1)
    side = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    bottom, top = len(ring), len(ring) + 1
    caps = np.concatenate([np.stack([np.full(sides, bottom), np.roll(index[0], -1), index[0]], -1),
                           np.stack([np.full(sides, top), index[-1], np.roll(index[-1], -1)], -1)])
    return decimate(vertices, np.concatenate([side, caps]), triangles, name="helical_screw",
                    meta={"generator": "helical_screw", "turns": turns, "pitch": pitch, "core_radius": core_radius,
                          "thread_depth": thread_depth, "sides": sides, "rows_per_turn": rows_per_turn})


def boxes_in_a_row(*, count=20, size=1.0, gap=0.5):
    """``count`` axis-aligned cubes of edge ``size`` along z, ``gap`` apart (guide S2: 20 boxes, 240 triangles).

    A ray along z through them crosses ``2·count`` faces. The row is centred on the origin.
    """
    count = check_positive_int(count, name="boxes_in_a_row count")
    _check_triangles(12 * count, what=f"boxes_in_a_row count {count}", fix=lambda most: f"use count ≤ {most // 12}")
    size = check_scalar(size, name="boxes_in_a_row size", low=0, low_open=True)
    gap = check_scalar(gap, name="boxes_in_a_row gap", low=0, low_open=True)
    cube = trimesh.creation.box(extents=(size, size, size))
    offset = (np.arange(count) - (count - 1) / 2) * (size + gap)
    vertices = np.concatenate([cube.vertices + (0, 0, dz) for dz in offset])
    faces = np.concatenate([cube.faces + i * len(cube.vertices) for i in range(count)])
    return closed_mesh(vertices, faces, name="boxes_in_a_row",
                       meta={"generator": "boxes_in_a_row", "count": count, "size": size, "gap": gap})


def rod(*, sides=20, radius=0.05, length=1.0):
    """A closed prism along z with a regular ``sides``-gon section: ``4·sides − 4`` triangles.

    ``sides = 20`` gives the 76-polygon rods of the paper's apple scene. Centred on the origin.
    """
    sides = check_positive_int(sides, name="rod sides", minimum=3)
    _check_triangles(4 * sides - 4, what=f"rod sides {sides}", fix=lambda most: f"use sides ≤ {(most + 4) // 4}")
    radius = check_scalar(radius, name="rod radius", low=0, low_open=True)
    length = check_scalar(length, name="rod length", low=0, low_open=True)
    phi = 2 * np.pi * np.arange(sides) / sides
    ring = np.stack([radius * np.cos(phi), radius * np.sin(phi)], -1)
    vertices = np.concatenate([np.c_[ring, np.full(sides, -length / 2)], np.c_[ring, np.full(sides, length / 2)]])
    i = np.arange(sides)
    j = (i + 1) % sides
    side = np.concatenate([np.stack([i, j, j + sides], -1), np.stack([i, j + sides, i + sides], -1)])
    fan = np.arange(1, sides - 1)
    caps = np.concatenate([np.stack([np.zeros_like(fan), fan + 1, fan], -1),
                           np.stack([np.full_like(fan, sides), fan + sides, fan + 1 + sides], -1)])
    return closed_mesh(vertices, np.concatenate([side, caps]), name="rod",
                       meta={"generator": "rod", "sides": sides, "radius": radius, "length": length})


def noisy_sphere(*, radius=1.0, amplitude=0.15, waves=12, seed=0, subdivisions=5, triangles=None):
    """An icosphere displaced radially by ``amplitude`` times a sum of seeded random plane waves.

    ``subdivisions = 5`` has 20480 triangles before ``triangles`` decimates it (5000: C7's tumour).
    ``amplitude < 1`` keeps the radius positive, so the surface stays embedded.
    """
    radius = check_scalar(radius, name="noisy_sphere radius", low=0, low_open=True)
    amplitude = check_scalar(amplitude, name="noisy_sphere amplitude", low=0, high=1, high_open=True)
    waves = check_positive_int(waves, name="noisy_sphere waves")
    subdivisions = check_positive_int(subdivisions, name="noisy_sphere subdivisions", minimum=0)
    # Past 64 subdivisions nothing fits anywhere, and 4**subdivisions of an absurd value takes long to compute.
    _check_triangles(20 * 4 ** min(subdivisions, 64), what=f"noisy_sphere subdivisions {subdivisions}",
                     shown=f"20·4^{subdivisions}",
                     fix=lambda most: f"use subdivisions ≤ {max(int(np.log(max(most / 20, 1)) / np.log(4)), 0)}")
    rng = np.random.default_rng(seed)
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    frequencies = rng.normal(scale=2.5, size=(waves, 3))
    phases = rng.uniform(0, 2 * np.pi, size=waves)
    noise = np.sin(sphere.vertices @ frequencies.T + phases).sum(axis=1) / np.sqrt(2.0 * waves)
    vertices = sphere.vertices * (radius * (1.0 + amplitude * np.clip(noise, -1.0, 1.0)))[:, None]
    return decimate(vertices, sphere.faces, triangles, name="noisy_sphere",
                    meta={"generator": "noisy_sphere", "radius": radius, "amplitude": amplitude, "waves": waves,
                          "seed": seed, "subdivisions": subdivisions})


GENERATORS = {
    "phantom_isosurface": phantom_isosurface,
    "vessel_tree": vessel_tree,
    "helical_screw": helical_screw,
    "boxes_in_a_row": boxes_in_a_row,
    "rod": rod,
    "noisy_sphere": noisy_sphere,
}


def generate(name, **params):
    """The mesh of generator ``name`` with keyword ``params``; bad names and parameters are InputErrors."""
    if name not in GENERATORS:
        raise InputError(f"unknown mesh generator {name!r}; known: {sorted(GENERATORS)}")
    try:
        return GENERATORS[name](**params)
    except TypeError as error:
        import inspect

        accepted = sorted(inspect.signature(GENERATORS[name]).parameters)
        raise InputError(f"mesh generator {name!r}: {error}; it takes {accepted}") from None


def load_mesh(path, *, name=None):
    """A closed mesh read from a file trimesh knows (OBJ, STL, PLY, OFF, glTF, ...), repaired and checked."""
    from pathlib import Path

    path = Path(path)
    if not path.is_file():
        raise InputError(f"mesh file {path}: {'is a folder, not a mesh file' if path.is_dir() else 'does not exist'}")
    try:
        surface = trimesh.load(path, force="mesh")
    except (ValueError, KeyError, OSError) as error:
        raise InputError(f"mesh file {path}: cannot be read as a triangle mesh ({error})") from None
    if len(surface.faces) == 0:
        raise InputError(f"mesh file {path}: holds no triangles")
    return closed_mesh(surface.vertices, surface.faces, name=name or path.stem, meta={"file": str(path)})
