"""The datasets package: registry, phantom generation, the cache and the real-data folder."""

import functools
import json
from dataclasses import replace

import numpy as np
import pytest

import datasets
from datasets import real
from datasets.registry import DATASETS
from core.errors import InputError
from core.transfer import Preset

REQUIRED_PHANTOMS = ("mri_head", "ct_skull", "folded_brain", "aneurysm", "foot", "engine", "torso", "sphere",
                     "constant_cube", "checkerboard", "fbm_control", "smoke_cloud")
EXPECTED_SHAPES_AT_32 = {"engine": (16, 32, 32), "torso": (20, 32, 32), "folded_brain": (21, 32, 32)}
REAL_DIR = real.resolve_data_dir()


def test_registry_lists_every_required_phantom_and_the_real_scans():
    phantoms = datasets.names(kind="phantom")
    assert set(REQUIRED_PHANTOMS) <= set(phantoms)
    assert {"cthead", "mrihead", "engine_real", "bonsai", "tooth", "headsq", "neghip", "nucleon",
            "brainsmall"} <= set(datasets.names(kind="real"))
    assert datasets.names() == [*phantoms, *datasets.names(kind="real")]
    for name in datasets.names():
        spec = datasets.get(name)
        assert isinstance(spec.preset(), Preset)
        assert set(spec.papers) <= set(datasets.PAPERS)


def test_unknown_names_and_kinds_are_rejected_with_the_choices():
    with pytest.raises(InputError, match="unknown data set 'nope'.*ct_skull"):
        datasets.get("nope")
    with pytest.raises(InputError, match="kind"):
        datasets.names(kind="synthetic")
    with pytest.raises(InputError, match="no preset 'nope'.*bone"):
        datasets.preset("ct_skull", "nope")
    assert datasets.preset("ct_skull") is datasets.get("ct_skull").presets["bone"]


@pytest.mark.parametrize("name", datasets.names(kind="phantom"))
def test_every_phantom_generates_small_with_content_under_its_default_preset(name):
    volume = datasets.load(name, size=32, cache_dir=False)
    assert volume.data.dtype == np.uint8
    assert volume.data.shape == EXPECTED_SHAPES_AT_32.get(name, (32, 32, 32))
    assert volume.name == name and volume.meta["seed"] == 0 and volume.meta["size"] == 32
    stats = datasets.statistics(volume, datasets.preset(name))
    assert stats["nonzero_fraction"] > 0
    if name != "constant_cube":
        assert volume.data.min() < volume.data.max()


@pytest.mark.parametrize("name", ["ct_skull", "aneurysm", "smoke_cloud", "torso"])
def test_same_seed_same_bytes_other_seed_other_bytes(name):
    first = datasets.load(name, size=32, seed=3, cache_dir=False)
    again = datasets.load(name, size=32, seed=3, cache_dir=False)
    other = datasets.load(name, size=32, seed=4, cache_dir=False)
    assert first.content_hash() == again.content_hash()
    assert first.content_hash() != other.content_hash()


def test_anatomy_does_not_depend_on_size():
    """The tree topology comes from the seed alone: a 128³ aneurysm box-averaged to 64³ is close to
    the 64³ one (and far from another seed's), though Murray's-law twigs thinner than a voxel differ."""
    small = datasets.load("aneurysm", size=64, cache_dir=False).data.astype(float)
    large = datasets.load("aneurysm", size=128, cache_dir=False).data.astype(float)
    other = datasets.load("aneurysm", size=64, seed=1, cache_dir=False).data.astype(float)
    pooled = large.reshape(64, 2, 64, 2, 64, 2).mean(axis=(1, 3, 5)).ravel()
    assert np.corrcoef(small.ravel(), pooled)[0, 1] > 0.9
    assert np.corrcoef(other.ravel(), pooled)[0, 1] < 0.5


def test_cache_hit_returns_equal_data_without_regenerating(tmp_path, monkeypatch):
    spec = DATASETS["ct_skull"]
    calls = []

    @functools.wraps(spec.generator)
    def counting(*args, **kwargs):
        calls.append(args)
        return spec.generator(*args, **kwargs)

    monkeypatch.setitem(DATASETS, "ct_skull", replace(spec, generator=counting))
    first = datasets.load("ct_skull", size=32, cache_dir=tmp_path)
    second = datasets.load("ct_skull", size=32, cache_dir=tmp_path)
    assert len(calls) == 1
    assert first.meta["cache"]["hit"] is False and second.meta["cache"]["hit"] is True
    np.testing.assert_array_equal(first.data, second.data)
    assert second.spacing == first.spacing and second.value_range == first.value_range
    key = datasets.cache_key("ct_skull", size=32)
    assert (tmp_path / f"{key}.npy").is_file() and (tmp_path / f"{key}.json").is_file()
    assert not list(tmp_path.glob("*.tmp")), "temporary files must be renamed into place"
    assert json.loads((tmp_path / f"{key}.json").read_text())["meta"]["seed"] == 0


def test_cache_regenerates_a_damaged_entry_and_honours_the_environment(tmp_path, monkeypatch):
    monkeypatch.setenv("VOLBENCH_CACHE", str(tmp_path))
    volume = datasets.load("sphere", size=16)
    key = datasets.cache_key("sphere", size=16)
    (tmp_path / f"{key}.npy").write_bytes(b"not a numpy file")
    again = datasets.load("sphere", size=16)
    assert again.meta["cache"]["hit"] is False
    np.testing.assert_array_equal(volume.data, again.data)


def test_labels_survive_the_cache(tmp_path):
    volume = datasets.load("torso", size=32, cache_dir=tmp_path)
    cached = datasets.load("torso", size=32, cache_dir=tmp_path)
    assert cached.meta["cache"]["hit"]
    np.testing.assert_array_equal(volume.labels, cached.labels)
    labels = volume.meta["labels"]
    present = set(np.unique(volume.labels))
    assert {labels["bone"], labels["vessel"], labels["fat"], labels["liver"]} <= present


def test_cache_key_is_stable_and_covers_size_seed_and_parameters():
    key = datasets.cache_key("constant_cube", size=32)
    assert key == datasets.cache_key("constant_cube", size=32, seed=0, value=128)
    assert all(c in "0123456789abcdef" for c in key)
    assert len({key, datasets.cache_key("constant_cube", size=33), datasets.cache_key("constant_cube", size=32, seed=1),
                datasets.cache_key("constant_cube", size=32, value=7)}) == 4
    assert datasets.cache_key("cthead") == datasets.cache_key("cthead")
    with pytest.raises(InputError, match="no parameter colour.*value"):
        datasets.cache_key("constant_cube", colour=3)


@pytest.mark.parametrize("kwargs, match", [
    ({"size": 4}, "size"), ({"seed": -1}, "seed"), ({"size": 16, "value": 300}, "value"),
    ({"size": 16, "value": [1]}, "value"),
])
def test_bad_phantom_requests_are_rejected(kwargs, match):
    with pytest.raises(InputError, match=match):
        datasets.load("constant_cube", cache_dir=False, **kwargs)


def test_phantom_parameters_change_the_volume():
    cube = datasets.load("constant_cube", size=8, value=7, cache_dir=False)
    assert (cube.data == 7).all()
    board = datasets.load("checkerboard", size=16, block=4, value=200, cache_dir=False)
    assert board.data[0, 0, 0] == 0 and board.data[0, 0, 4] == 200
    small = datasets.load("folded_brain", size=32, decimate=2, cache_dir=False)
    assert small.data.shape == (21, 32, 32)
    with pytest.raises(InputError, match="decimate"):
        datasets.load("folded_brain", size=32, decimate=0, cache_dir=False)
    with pytest.raises(InputError, match="bores"):
        datasets.load("engine", size=32, bores=9, cache_dir=False)


def test_real_data_sets_refuse_phantom_options():
    with pytest.raises(InputError, match="takes no size"):
        datasets.load("cthead", size=64)


@pytest.mark.skipif(not (REAL_DIR / "volumes.json").is_file(), reason=f"real-data folder {REAL_DIR} is absent")
@pytest.mark.parametrize("name", [n for n in datasets.names(kind="real") if n != "brainsmall"])
def test_real_scans_load_from_the_data_folder(name):
    entry = real.read_manifest()[datasets.get(name).source]
    volume = datasets.load(name)
    x, y, z = entry["dims"]
    assert volume.data.shape == (z, y, x)
    assert volume.spacing == tuple(float(s) for s in entry.get("spacing", (1, 1, 1)))
    if "range" in entry:
        assert volume.value_range == tuple(float(v) for v in entry["range"])
    stats = datasets.statistics(volume, datasets.preset(name))
    assert 0 < stats["nontransparent_fraction"] < 1


@pytest.mark.skipif(not real.DEBIAN_BRAINSMALL.is_file(), reason="libvolpack1-dev's brainsmall.den is not installed")
def test_brainsmall_is_vol_packs_128_by_128_by_84_brain():
    volume = datasets.load("brainsmall")
    assert volume.data.shape == (84, 128, 128) and volume.data.dtype == np.uint8
    assert volume.meta["orig_len"] == (256, 256, 109)


def test_missing_real_data_raises_data_unavailable_with_a_remedy(tmp_path, monkeypatch):
    with pytest.raises(datasets.DataUnavailableError, match="VOLBENCH_REAL_DATA") as info:
        datasets.load("cthead", data_dir=tmp_path / "nowhere")
    assert isinstance(info.value, InputError) and "nowhere" in str(info.value)

    (tmp_path / "volumes.json").write_text(json.dumps(
        {"cthead": {"file": "cthead_4x4x2_uint8.raw", "dims": [4, 4, 2], "dtype": "uint8"}}))
    monkeypatch.setenv("VOLBENCH_REAL_DATA", str(tmp_path))
    with pytest.raises(datasets.DataUnavailableError, match="cthead_4x4x2_uint8.raw"):
        datasets.load("cthead")
    with pytest.raises(datasets.DataUnavailableError, match="no entry"):
        datasets.load("nucleon")

    (tmp_path / "cthead_4x4x2_uint8.raw").write_bytes(bytes(31))
    with pytest.raises(InputError, match="31 bytes does not match 4x4x2 uint8 = 32 bytes") as info:
        datasets.load("cthead")
    assert not isinstance(info.value, datasets.DataUnavailableError)

    monkeypatch.setattr(real, "DEBIAN_BRAINSMALL", tmp_path / "missing.den")
    with pytest.raises(datasets.DataUnavailableError, match="libvolpack1-dev"):
        datasets.load("brainsmall")


def test_extra_manifest_entries_become_real_data_sets(tmp_path, monkeypatch):
    data = np.arange(2 * 3 * 4, dtype=np.uint16).reshape(4, 3, 2)
    data.astype("<u2").tofile(tmp_path / "blob_2x3x4_uint16.raw")
    (tmp_path / "volumes.json").write_text(json.dumps({
        "_about": "comment",
        "engine": {"file": "engine_256x256x128_uint8.raw", "dims": [256, 256, 128], "dtype": "uint8"},
        "blob": {"file": "blob_2x3x4_uint16.raw", "dims": [2, 3, 4], "dtype": "uint16", "spacing": [1, 2, 3],
                 "range": [0, 23]}}))
    monkeypatch.setenv("VOLBENCH_REAL_DATA", str(tmp_path))
    assert "blob" in datasets.names(kind="real") and "engine" not in datasets.names(kind="real")
    assert datasets.get("engine").kind == "phantom"
    volume = datasets.load("blob")
    np.testing.assert_array_equal(volume.data, data)
    assert volume.spacing == (1.0, 2.0, 3.0) and volume.value_range == (0.0, 23.0)
    assert datasets.get("blob").kind == "real"


def test_targets_name_statistics_that_exist():
    volume = datasets.load("sphere", size=16, cache_dir=False)
    keys = set(datasets.statistics(volume, datasets.preset("sphere")))
    for name in datasets.names(kind="phantom"):
        spec = datasets.get(name)
        for preset_name, targets in spec.targets_by_preset.items():
            assert preset_name in spec.presets
            assert set(targets) <= keys
        assert spec.targets == spec.targets_by_preset.get(spec.default_preset, {})


def test_band_limited_edges_keep_the_volume_of_a_shape():
    from datasets.shapes import Grid, Sphere

    grid = Grid.for_aspect(48)
    region = grid.region(Sphere((0.02, -0.03, 0.01), 0.3))
    assert region.cov.sum() * grid.h**3 == pytest.approx(4 / 3 * np.pi * 0.3**3, rel=0.01)
    centre = tuple(n // 2 for n in region.cov.shape)
    assert region.cov[centre] == 1.0 and region.cov[0, 0, 0] == 0.0


def test_fbm_is_standardised_and_defined_in_normalised_coordinates():
    from datasets import noise
    from datasets.shapes import Grid

    # Both octaves are above the band limit at 32 and at 64, so the two fields are the same function.
    small = noise.fbm(Grid.for_aspect(32), np.random.default_rng(5), wavelength=0.6, octaves=2)
    large = noise.fbm(Grid.for_aspect(64), np.random.default_rng(5), wavelength=0.6, octaves=2)
    assert abs(float(large.mean())) < 1e-5 and float(large.std()) == pytest.approx(1, abs=1e-4)
    pooled = large.reshape(32, 2, 32, 2, 32, 2).mean(axis=(1, 3, 5))
    assert np.corrcoef(small.ravel(), pooled.ravel())[0, 1] > 0.95


def test_cache_key_includes_the_generator_source_digest(monkeypatch):
    from datasets import cache

    key = datasets.cache_key("constant_cube", size=16)
    spec = datasets.get("constant_cube")
    assert cache.source_digest(spec.generator.__module__) in json.dumps(
        {"code": cache.source_digest(spec.generator.__module__)})
    monkeypatch.setattr(cache, "source_digest", lambda module_name: "edited-generator")
    edited = datasets.cache_key("constant_cube", size=16)
    assert edited != key  # editing a generator's source names a new cache entry
    monkeypatch.setattr(cache, "source_digest", lambda module_name: "edited-again")
    assert datasets.cache_key("constant_cube", size=16) not in (key, edited)


def test_cache_of_an_edited_generator_is_not_reused(tmp_path, monkeypatch):
    from datasets import cache

    first = datasets.load("constant_cube", size=16, cache_dir=tmp_path)
    monkeypatch.setattr(cache, "source_digest", lambda module_name: "edited-generator")
    second = datasets.load("constant_cube", size=16, cache_dir=tmp_path)
    assert second.meta["cache"]["hit"] is False and second.meta["key"] != first.meta["key"]
