"""Fast classification for shear-warp (thesis §4.3, §4.4): the min-max octree, the summed-area
table's conservative verdicts, the octree-built RLE (byte-identical to the brute-force build),
the per-frame octree mode (bit-identical images) and the renderer's options, stages and counters."""

import numpy as np
import pytest

import datasets
from core.camera import Camera
from core.errors import InputError
from core.scene import Scene, Shading, VolumeInstance
from core.transfer import GradientOpacity, TransferFunction
from core.volume import Volume
from datasets.registry import DATASETS
from renderers.shearwarp import classify as C
from renderers.shearwarp import octree as O
from renderers.shearwarp.renderer import ShearWarpRenderer

FIELDS = ("lengths", "run_offsets", "data_offsets", "voxels", "gradients")


def random_volume(seed, shape=(19, 26, 23)):
    """Smooth blobs plus noise plus a zero slab: uniform regions, edges and odd sizes (not multiples of 4)."""
    rng = np.random.default_rng(seed)
    z, y, x = np.meshgrid(*(np.arange(n) for n in shape), indexing="ij")
    field = np.zeros(shape)
    for _ in range(3):
        c = rng.uniform(0, 1, 3) * shape
        field += np.exp(-((z - c[0]) ** 2 + (y - c[1]) ** 2 + (x - c[2]) ** 2) / rng.uniform(10, 40))
    field = np.clip(field / field.max() + rng.normal(0, 0.03, shape), 0, 1)
    field[:, : shape[1] // 4] = 0.0
    return (field * 255).round().astype(np.uint8)


def random_tf(rng):
    """A random piecewise-linear opacity with zero stretches (so that nodes can be transparent)."""
    knots = np.sort(rng.uniform(0, 1, 4))
    alphas = rng.choice([0.0, 0.0, 0.03, 0.05, 0.2, 0.8], size=4)
    points = [(0.0, 1, 1, 1, 0.0)] + [(k, rng.uniform(), rng.uniform(), rng.uniform(), a)
                                     for k, a in zip(knots, alphas)] + [(1.0, 1, 1, 1, rng.choice([0.0, 0.6]))]
    return TransferFunction.from_points(points, size=int(rng.choice([64, 256])))


def random_go(rng):
    if rng.uniform() < 0.3:
        return None
    u = np.sort(rng.uniform(0, 0.6, 2))
    return GradientOpacity.from_points([(0, 0.0), (u[0], 0.0), (u[1], 1.0), (1, 1.0)])


@pytest.mark.parametrize("seed", range(6))
def test_octree_verdicts_never_hide_a_nontransparent_voxel(seed):
    rng = np.random.default_rng(seed)
    data = random_volume(seed)
    spacing = tuple(rng.choice([1.0, 0.7, 1.5], 3))
    scalars = Volume(data).normalized(np.float32)
    tree = O.build_octree(scalars, spacing, threshold=int(rng.choice([0, 4, 16])))
    hidden_any = flagged_any = transparent_any = 0
    for _ in range(4):
        tf, go = random_tf(rng), random_go(rng)
        min_opacity = float(rng.choice([0.0, 0.05, 0.1]))
        step = float(rng.choice([1.0, 0.7]))
        brute = C.classify(scalars, spacing, tf, go, step, min_opacity, gradients=True)
        verdict = O.classify_octree(tree, tf, go, step, min_opacity)
        hidden = O.transparent_voxel_mask(tree, verdict)
        # Octree classification equals brute-force classification: nothing non-transparent is hidden ...
        assert not np.any(hidden & (brute.records != 0))
        hidden_any += int(hidden.sum())
        # The lazy classification's per-voxel bin test is conservative too, on the octree's binning rule.
        nz, ny, nx = data.shape
        voxels = tree.voxels[:, :ny, :nx]
        np.testing.assert_array_equal(voxels["scalar_bin"], np.minimum(np.floor(scalars * 256.0), 255))
        flagged = verdict.voxel_visible[voxels["scalar_bin"], voxels["gradient_bin"]] == 0
        assert not np.any(flagged & (brute.records != 0))
        flagged_any += int(flagged.sum())
        transparent_any += int((brute.records == 0).sum())
        # ... and the octree-built encodings are the brute-force ones, byte for byte.
        for axis in range(3):
            built, stats = O.encode(tree, verdict, axis, exact=True, gradients=True)
            reference = C.encode(brute, axis)
            for field in FIELDS:
                np.testing.assert_array_equal(getattr(built, field), getattr(reference, field), err_msg=field)
            assert stats.nontransparent == brute.nontransparent or min_opacity == 0.0
            assert stats.classified == data.size - int(hidden.sum())
            # The conservative (per-frame) runs decode to the same records.
            loose, _ = O.encode(tree, verdict, axis, exact=False)
            np.testing.assert_array_equal(C.decode(loose), C.standard_order(brute.records, axis))
            assert loose.gradients.shape == (0, 3)
            # The lazy mode's runs, one list per block of scanlines, are every scanline's conservative runs.
            runs = O.voxel_runs(tree, verdict, axis)
            scan_k, scan_j = runs.scanline_tables()
            ni, nj, nk = runs.shape_ijk
            assert runs.candidates == int(loose.data_offsets[-1])
            for sl in range(0, nk * nj, 5):
                k, j = divmod(sl, nj)
                t = scan_k[k] + scan_j[j]
                np.testing.assert_array_equal(runs.lengths[runs.run_offsets[t]:runs.run_offsets[t + 1]],
                                              loose.lengths[loose.run_offsets[sl]:loose.run_offsets[sl + 1]])
                np.testing.assert_array_equal(runs.extents[t], loose.extents[sl])
    assert hidden_any > 0  # the octree did skip something for these volumes
    assert flagged_any > 0.5 * transparent_any  # and the bin test decides most transparent voxels without tables


def test_octree_structure_pruning_and_bins():
    data = np.zeros((20, 12, 9), np.uint8)
    data[8:, :, :] = 200
    tree = O.build_octree(Volume(data).normalized(np.float32), (1.0, 1.0, 1.0))
    assert tree.root_size == 32 and tree.levels == 4  # 9×12×20 → 3×3×5 base nodes → … → 1
    assert tree.gradient_max > 0 and tree.nbytes == tree.nodes * (4 * 1 + 4)
    leaves = tree.child < 0
    # Every node with children is not uniform: some parameter varies by more than the threshold.
    inner = ~leaves
    spread = np.maximum(tree.smax.astype(int) - tree.smin, tree.gmax.astype(int) - tree.gmin)
    assert np.all(spread[inner] > 4)
    # A constant volume is one root leaf.
    flat = O.build_octree(np.full((10, 10, 10), 0.5, np.float32), (1.0, 1.0, 1.0))
    assert flat.nodes == 1 and flat.smin[0] == flat.smax[0] == 128 and flat.gmax[0] == 0
    # Threshold 0 keeps the whole pyramid down to the base nodes where values vary.
    fine = O.build_octree(Volume(data).normalized(np.float32), (1.0, 1.0, 1.0), threshold=0, base_size=2)
    assert fine.nodes > tree.nodes
    for bad in ({"base_size": 0}, {"threshold": -1}, {"threshold": 1.5}, {"bins": 1}):
        with pytest.raises(InputError):
            O.build_octree(np.zeros((4, 4, 4), np.float32), (1, 1, 1), **bad)


def test_sat_box_sums_match_a_direct_count():
    tree = O.build_octree(Volume(random_volume(3)).normalized(np.float32), (1.0, 1.0, 1.0))
    tf = TransferFunction.ramp(0.3, 0.6)
    go = GradientOpacity.from_points([(0, 0.0), (0.2, 1.0), (1, 1.0)])
    verdict = O.classify_octree(tree, tf, go, 1.0, 0.05)
    indicator = np.diff(np.diff(verdict.sat, axis=0), axis=1)
    assert set(np.unique(indicator)) <= {0, 1}
    rng = np.random.default_rng(0)
    for _ in range(50):
        a, b = np.sort(rng.integers(0, 256, 2))
        c, d = np.sort(rng.integers(0, 256, 2))
        assert verdict.box_sum(a, b, c, d) == indicator[a:b + 1, c:d + 1].sum()
    # Scalars below the ramp (bins < 0.3·256) are transparent for every gradient.
    assert indicator[:70].sum() == 0 and indicator[160:, 255].all()
    assert indicator[200, 0] == 0  # zero gradient: g = 0


def blob_scene(az=30.0, el=20.0, tf=None, go=None, shading="none"):
    data = random_volume(7, (28, 24, 30))
    tf = tf or TransferFunction.from_points([(0, 1, 0.5, 0.2, 0), (0.3, 1, 0.5, 0.2, 0), (0.6, 0.3, 0.8, 1, 0.6),
                                             (1, 1, 1, 1, 0.9)])
    return Scene((VolumeInstance(Volume(data, name="blobs"), tf, gradient_opacity=go),),
                 camera=Camera(azimuth=az, elevation=el), width=48, height=48, shading=Shading(model=shading))


@pytest.mark.parametrize("az, el, shading", [(30.0, 20.0, "phong"), (100.0, 10.0, "none"), (10.0, 80.0, "phong")])
def test_octree_mode_renders_the_same_bits_as_the_classified_rle(az, el, shading):
    go = GradientOpacity.from_points([(0, 0.3), (0.1, 1.0), (1, 1.0)])
    scene = blob_scene(az, el, go=go, shading=shading)
    for options in ({}, {"early_termination": False}, {"shading": "procedural"}):
        rle = ShearWarpRenderer(**options).render(scene)
        fast = ShearWarpRenderer(classification="octree", **options).render(scene)
        np.testing.assert_array_equal(fast.image, rle.image)
        # Conservative runs resample at least as many positions (the thesis's 2× cost).
        assert fast.counters["samples"] >= rle.counters["samples"]
        classified, candidates = fast.counters["classified_on_the_fly"], fast.counters["candidate_voxels"]
        assert 0 < classified and candidates < scene.volumes[0].volume.data.size
        if options.get("shading") == "procedural" and shading == "phong":
            # Procedural shading needs each voxel's gradient: every candidate is classified before compositing.
            assert classified == candidates and "octree_classify" in fast.timings
            assert fast.info["nontransparent_fraction"] == pytest.approx(rle.info["nontransparent_fraction"])
        else:
            # Lazily, in the compositing loop: each voxel at most once for each of the two rows reading it.
            assert "octree_runs" in fast.timings and "octree_classify" not in fast.timings
            assert fast.info["nontransparent_fraction"] is None and classified <= 2 * candidates


def test_lazy_classification_skips_what_early_termination_hides():
    # An opaque cube seen head-on: behind its first slices every pixel is opaque and no voxel is classified.
    cube = np.zeros((40, 40, 40), np.uint8)
    cube[4:-4, 4:-4, 4:-4] = 200  # on octree node boundaries: the candidate runs are the cube's
    scene = Scene((VolumeInstance(Volume(cube, name="cube"), TransferFunction.ramp(0.5, 0.6)),),
                  camera=Camera(azimuth=5.0, elevation=5.0), width=40, height=40)
    fast = ShearWarpRenderer(classification="octree").render(scene)
    np.testing.assert_array_equal(fast.image, ShearWarpRenderer().render(scene).image)
    everything = ShearWarpRenderer(classification="octree", early_termination=False).render(scene)
    assert fast.counters["classified_on_the_fly"] < 0.3 * everything.counters["classified_on_the_fly"]
    assert fast.counters["candidate_voxels"] == everything.counters["candidate_voxels"]
    for options in ({}, {"shading": "procedural"}):
        rle = ShearWarpRenderer(**options).render(scene)
        switch = ShearWarpRenderer(octree_rle_build=True, **options).render(scene)
        np.testing.assert_array_equal(switch.image, rle.image)
        assert switch.counters["samples"] == rle.counters["samples"]


def test_octree_stages_caches_and_counters():
    backend = ShearWarpRenderer(classification="octree")
    scene = blob_scene()
    first = backend.render(scene)
    assert {"octree_build", "sat_build", "octree_runs"} <= set(first.timings)
    assert "classify" not in first.timings and "rle_build" not in first.timings
    assert first.counters["octree_nodes"] > 0 and first.counters["octree_bytes"] > 0
    second = backend.render(scene.with_camera(azimuth=120.0))
    assert "octree_build" not in second.timings and "sat_build" not in second.timings
    assert "octree_runs" in second.timings and second.timings["octree_runs"] <= second.timings["total"]
    # A transfer-function edit rebuilds the SAT only, not the octree.
    edited = scene.volumes[0].__class__(scene.volumes[0].volume, TransferFunction.ramp(0.5, 0.9))
    third = backend.render(Scene((edited,), camera=scene.camera, width=48, height=48))
    assert "sat_build" in third.timings and "octree_build" not in third.timings
    np.testing.assert_array_equal(third.image, ShearWarpRenderer().render(
        Scene((edited,), camera=scene.camera, width=48, height=48)).image)
    # The mode switch: the RLE copies come from the octree, timed as rle_build, cached afterwards.
    switch = ShearWarpRenderer(octree_rle_build=True)
    built = switch.render(scene)
    assert {"octree_build", "sat_build", "rle_build"} <= set(built.timings) and "classify" not in built.timings
    assert built.counters["classified_on_the_fly"] > 0
    assert built.counters["rle_bytes"] == ShearWarpRenderer().render(scene).counters["rle_bytes"]
    again = switch.render(scene.with_camera(azimuth=70.0))
    assert "rle_build" not in again.timings and again.counters["classified_on_the_fly"] == 0
    plain = ShearWarpRenderer().render(scene)
    assert "octree_nodes" not in plain.counters


def test_options_are_validated_and_recorded():
    backend = ShearWarpRenderer(classification="octree", octree_threshold=0, octree_base_size=2)
    assert backend.options["classification"] == "octree" and backend.options["octree_rle_build"] is False
    assert backend.options["octree_threshold"] == 0 and backend.options["octree_base_size"] == 2
    for bad, match in [({"classification": "sat"}, "classification"), ({"octree_rle_build": 1}, "octree_rle_build"),
                       ({"octree_threshold": -1}, "octree_threshold"), ({"octree_base_size": 0}, "octree_base_size"),
                       ({"classification": "octree", "rle": False}, "rle=False"),
                       ({"octree_rle_build": True, "rle": False}, "rle=False"),
                       ({"classification": "octree", "octree_rle_build": True}, "octree_rle_build")]:
        with pytest.raises(InputError, match=match):
            ShearWarpRenderer(**bad)


def test_a_uniform_volume_is_not_classified_away():
    # A constant cube's root node covers one scalar bin and one gradient bin: its SAT box holds
    # exactly one non-transparent parameter pair, which must not be taken for none.
    cube = datasets.load("constant_cube", size=16, cache_dir=False)
    preset = DATASETS["constant_cube"].preset()
    tree = O.build_octree(cube.normalized(np.float32), cube.spacing)
    verdict = O.classify_octree(tree, preset.transfer_function, None, 1.0, 0.05)
    assert tree.nodes == 1 and verdict.box_sum(tree.smin[0], tree.smax[0], tree.gmin[0], tree.gmax[0]) == 1
    assert verdict.status[0] == O.NONTRANSPARENT
    scene = Scene((VolumeInstance(cube, preset.transfer_function),), camera=Camera(azimuth=30.0, elevation=20.0),
                  width=32, height=32)
    rle = ShearWarpRenderer().render(scene)
    fast = ShearWarpRenderer(classification="octree").render(scene)
    assert rle.image[..., 3].max() > 0.5  # α = 128/255 per voxel: the cube is all but opaque
    np.testing.assert_array_equal(fast.image, rle.image)
