"""The rebuilt phantoms: determinism, sizes, CT/MR-like value ranges, anatomy, Murray's law, the
statistics of small versions against the real scans, and the in-box statistics transform."""

import numpy as np
import pytest

import datasets
from core.volume import Volume
from datasets.phantoms.heads import _Head, _cortex
from datasets.phantoms.vessels import grow_tree
from datasets.shapes import Grid
from datasets.stats import BOX_STATISTICS, in_box, statistics
from core.errors import InputError

REBUILT = ("mri_head", "ct_skull", "folded_brain", "foot", "engine", "torso", "golden_lady", "bonsai_like", "aneurysm")


@pytest.mark.parametrize("name", REBUILT)
def test_rebuilt_phantoms_are_deterministic_uint8_of_their_box(name):
    first = datasets.load(name, size=40, seed=2, cache_dir=False)
    again = datasets.load(name, size=40, seed=2, cache_dir=False)
    assert first.content_hash() == again.content_hash()
    assert first.data.dtype == np.uint8 and max(first.shape_xyz) == 40
    assert first.meta["generation_seconds"] > 0


def test_ct_skull_has_air_soft_tissue_bone_and_enamel_at_ct_levels():
    data = datasets.load("ct_skull", size=64, cache_dir=False).data
    hist = np.bincount(data.ravel(), minlength=256)
    assert data[0, 0, 0] < 15                              # air in the corner
    assert hist[80:100].sum() > 0.1 * data.size            # soft tissue and brain
    assert hist[180:].sum() > 0.01 * data.size             # cortical bone and teeth
    assert hist[15:60].sum() < hist[80:100].sum()          # partial volume, not a third class


def test_mri_head_background_is_rayleigh_not_zero():
    data = datasets.load("mri_head", size=48, cache_dir=False).data
    corner = data[-4:, :4, :4].astype(float)
    assert 4 < corner.mean() < 14 and corner.std() > 1


def test_skull_anatomy_is_where_the_face_is():
    """Orbits are soft tissue inside bone at eye level in front; the teeth are the densest voxels."""
    volume = datasets.load("ct_skull", size=128, cache_dir=False)
    data = volume.data.astype(int)
    nz, ny, nx = data.shape
    z_eye, y_front = int(nz * (0.5 + 0.025 * 1.06 - 0.015)), int(ny * (0.5 - 0.265 * 1.06))
    orbit = data[z_eye, y_front - 2:y_front + 3, nx // 2 + 10:nx // 2 + 14]
    assert 40 < orbit.mean() < 110                         # orbital fat, not bone or air
    z_teeth = int(nz * (0.5 - 0.215 * 1.06 - 0.015))
    assert data[z_teeth - 3:z_teeth + 4].max() >= 240


def test_cortex_is_a_folded_surface_not_a_smooth_blob():
    """Sulci and the midline fissure give the cortex over 20 % more surface than its envelope
    (voxels within half a voxel of each surface), and the folds change with the seed."""
    grid, head = Grid.for_aspect(96), _Head()
    band = np.float32(0.5 / 96)
    folded = _cortex(grid, np.random.default_rng(0), head)
    smooth = head.brain.sdf(*grid.coords())
    assert np.count_nonzero(np.abs(folded) < band) > 1.2 * np.count_nonzero(np.abs(smooth) < band)
    other = _cortex(grid, np.random.default_rng(1), head)
    assert np.count_nonzero((folded < 0) != (other < 0)) > 0.02 * np.count_nonzero(smooth < 0)


def test_vessel_radii_follow_murrays_law():
    rng = np.random.default_rng(0)
    branches = grow_tree(rng, (0, 0, -0.4), (0, 0, 1), radius=0.03, length=0.2, generations=3, limit=2)
    ends = {tuple(np.round(b.points[0], 9)): [] for b in branches}
    for b in branches:
        ends[tuple(np.round(b.points[0], 9))].append(b)
    checked = 0
    for parent in branches:
        children = ends.get(tuple(np.round(parent.points[-1], 9)), [])
        if len(children) == 2:
            assert sum(c.radii[0] ** 3 for c in children) == pytest.approx(parent.radii[-1] ** 3, rel=1e-9)
            checked += 1
    assert checked >= 3
    radii = sorted(b.radii[0] for b in branches)
    assert radii[-1] / radii[0] > 2                          # calibres taper from trunk to twig


def test_golden_lady_figure_stands_out_of_the_haze():
    data = datasets.load("golden_lady", size=64, cache_dir=False).data
    assert np.count_nonzero(data > 180) > 0.01 * data.size   # the figure
    haze = data[(data > 25) & (data < 80)]
    assert haze.size > 0.3 * data.size                     # the haze around it


def test_in_box_is_exact_for_a_block_aligned_embedding():
    rng = np.random.default_rng(1)
    small = (rng.random((24, 16, 32)) > 0.7).astype(np.uint8) * 200
    box = np.zeros((48, 48, 64), np.uint8)
    box[8:32, 16:32, 16:48] = small
    preset = datasets.preset("sphere", "binary")
    embedded = statistics(Volume(box), preset)
    predicted = in_box(statistics(Volume(small), preset), (64, 48, 48))
    for stat in BOX_STATISTICS:
        assert predicted[stat] == pytest.approx(embedded[stat], rel=1e-12)


def test_in_box_rejects_a_volume_that_does_not_fit_and_incomplete_statistics():
    stats = statistics(Volume(np.zeros((8, 8, 16), np.uint8)), datasets.preset("sphere", "binary"))
    with pytest.raises(InputError, match="does not fit"):
        in_box(stats, (8, 8, 8))
    with pytest.raises(InputError, match="lack"):
        in_box({"nx": 8}, (8, 8, 8))


SMALL = {"ct_skull": ("cthead", "bone", {}), "engine": ("engine_real", "surfaces", {}),
         "bonsai_like": ("bonsai", "tree", {}), "mri_head": ("mrihead", "skin", {})}


@pytest.mark.parametrize("phantom", sorted(SMALL))
def test_small_stand_ins_keep_the_real_scans_box_statistics(phantom):
    """At a quarter of the size the stand-in's fractions stay near the real scan's, box-averaged
    by four and placed in the same box (runs shrink with the resolution on both sides alike)."""
    real_name, preset, params = SMALL[phantom]
    try:
        real = datasets.load(real_name)
    except datasets.DataUnavailableError as exc:
        pytest.skip(str(exc))
    data = real.data.astype(np.float32)
    nz, ny, nx = (n // 4 * 4 for n in data.shape)
    pooled = data[:nz, :ny, :nx].reshape(nz // 4, 4, ny // 4, 4, nx // 4, 4).mean(axis=(1, 3, 5))
    small_real = Volume(np.rint(pooled).astype(np.uint8), spacing=real.spacing)
    size = max(real.shape_xyz) // 4
    mine = statistics(datasets.load(phantom, size=size, cache_dir=False, **params), datasets.preset(phantom, preset))
    theirs = in_box(statistics(small_real, datasets.preset(real_name, preset)), (mine["nx"], mine["ny"], mine["nz"]))
    for stat in ("nontransparent_fraction", "empty_block_fraction"):
        assert mine[stat] == pytest.approx(theirs[stat], rel=0.4, abs=0.01), stat


@pytest.mark.parametrize("radius", [4.0, 1.0, 0.5, 0.25])
def test_tube_iso_surface_has_its_radius_however_thin(radius):
    """The reference's walk of the trilinear field, out from the middle tube's axis along x and y, crosses the
    isovalue 0.5 within 0.01 voxel of the radius; along z the tube runs on, ending in a cap inside the box."""
    from iso_shapes import reference_crossings

    volume = datasets.load("tube", size=32, cache_dir=False, radius=radius)
    assert volume.data.dtype == np.uint8 and volume.data.shape == (32, 32, 32)
    iso = datasets.preset("tube").effective_isovalue
    assert iso == 0.5
    axis = np.array([16.0, 16.0, 16.0])  # x, y, z: the middle tube's axis passes through this voxel centre
    slopes = np.array([[6.0, 0, 0], [-6.0, 0, 0], [0, 6.0, 0], [0, -6.0, 0], [0, 0, 15.0]])
    hits = reference_crossings(volume.normalized(np.float64), np.tile(axis, (5, 1)), slopes, iso)
    assert hits[:4] * 6 == pytest.approx([radius] * 4, abs=0.01)
    assert 15 * hits[4] == pytest.approx(31 - 5 - 16 + radius, abs=0.01)  # the axis ends 5 voxels before the last slice


def test_tube_row_keeps_its_tubes_apart_inside_the_box():
    from datasets.phantoms.tubes import TUBE_SPACING, tube_axes

    assert tube_axes(24) == [12] and tube_axes(48) == [14, 24, 34] and len(tube_axes(128)) == 11
    data = datasets.load("tube", size=48, cache_dir=False, radius=4.0).data
    row = data[24, 24]  # along x through the axes
    assert [x for x in range(48) if row[x] == 255 and (x - 14) % TUBE_SPACING == 0] == [14, 24, 34]
    assert row[[19, 29]].tolist() == [0, 0]  # the ramps (zero from R + 1 = 5 voxels out) do not meet
    assert not data[0].any() and not data[-1].any() and not data[:, :, 0].any() and not data[:, :, -1].any()


def test_tube_is_deterministic_cached_and_checks_its_radius(tmp_path):
    first = datasets.load("tube", size=24, cache_dir=tmp_path, radius=0.5)
    again = datasets.load("tube", size=24, cache_dir=tmp_path, radius=0.5)
    assert (first.meta["cache"]["hit"], again.meta["cache"]["hit"]) == (False, True)
    assert first.content_hash() == again.content_hash() == datasets.load("tube", size=24, seed=5, cache_dir=False,
                                                                         radius=0.5).content_hash()
    assert datasets.cache_key("tube", size=24, radius=0.5) != datasets.cache_key("tube", size=24, radius=0.25)
    for bad in (0, 0.01, 4.5, True, "1"):
        with pytest.raises(InputError, match="tube radius: expected voxels from 0.05"):
            datasets.load("tube", size=16, cache_dir=False, radius=bad)
