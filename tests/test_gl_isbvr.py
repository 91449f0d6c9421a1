"""gl-isbvr (Xue, Zhang & Crawfis 2005): images against gl-slicer (Basic) for every depth-init mode and both
orders, the depth offset, the coarse surfaces' holes (Fig. 4a), the fragment counters, each depth sequence's
depth buffer against a CPU computation from the cube grids, options and the surface cache."""

import numpy as np
import pytest
from scipy import ndimage

import renderers
from core.errors import InputError
from core.transfer import TransferFunction
from core.volume import Volume
from renderers.gl import context
from renderers.gl.isbvr import ZINIT_MODES, GLIsbvrRenderer, slice_ranges
from renderers.gl.slicer import slice_polygons
from renderers.gl.isosurfaces import boundary_faces, node_classes, phi_p_cubes, phi_t_cubes
from renderers.gl.view import make_view, ray_lengths
from test_gl_slicer import scene_of

GL_OK, GL_REASON = context.probe()
pytestmark = pytest.mark.skipif(not GL_OK, reason=f"no OpenGL 4.3 context through EGL here: {GL_REASON}")

RENDERING_MODES = tuple(mode for mode in ZINIT_MODES if mode not in ("cull-all", "slice-ert"))
"""The modes that must render Basic's image (``slice-ert`` stops at an opacity threshold, tested on its own)."""
SURFACE_MODES = tuple(mode for mode in ZINIT_MODES if mode != "slice-ert")
"""The modes whose depth comes from the init passes (``slice-ert`` writes depth slice by slice, front to back)."""
ORDERS = ("front-to-back", "back-to-front")
ROUNDING = 1e-6
"""Images that should be equal: float32 compositing of the same fragments in the same order."""

HALO = TransferFunction.from_points([(0, 1, 0.5, 0.2, 0), (0.2, 1, 0.5, 0.2, 0), (0.25, 0.2, 0.6, 1, 0.06),
                                     (0.6, 0.2, 0.6, 1, 0.06), (0.8, 1, 1, 1, 1), (1, 1, 1, 1, 1)], name="halo")
"""Empty below 0.2, a faint halo, opaque from 0.8: both of iSBVR's surfaces exist."""


def cored(shape=(28, 32, 36)):
    """An opaque core in a translucent halo with a neck reaching the volume's y = 0 face, empty elsewhere."""
    z, y, x = np.meshgrid(*(np.arange(n) + 0.5 for n in shape), indexing="ij")
    radius = np.sqrt((z - 14.5) ** 2 + (y - 17) ** 2 + ((x - 19) * 0.8) ** 2)
    neck = (np.hypot(z - 14.5, x - 19) < 3) & (y < 17)
    field = np.where(radius < 5.5, 1.0, np.where((radius < 8.5) | neck, 0.4, 0.0))
    return Volume((ndimage.gaussian_filter(field, 0.7) * 255).astype(np.uint8), name="cored")


def tilted(n=24):
    """A linear ramp across the box: opaque under :data:`HALO` in its highest corner, against three faces."""
    z, y, x = np.meshgrid(*(np.arange(n) + 0.5,) * 3, indexing="ij")
    return Volume((np.clip((x + 0.6 * y + 0.3 * z) / (1.9 * n), 0, 1) * 255).astype(np.uint8), name="tilted")


_RENDERERS = {}


def isbvr(**options):
    """A shared gl-isbvr renderer per option set (its surfaces stay cached between tests)."""
    key = tuple(sorted(options.items()))
    if key not in _RENDERERS:
        _RENDERERS[key] = renderers.get("gl-isbvr", **options)
    return _RENDERERS[key]


def basic(scene, order="back-to-front"):
    """gl-slicer at gl-isbvr's slice spacing (one voxel): the paper's Basic SBVR."""
    return renderers.get("gl-slicer", step_factor=1.0, order=order, count_contributing=False).render(scene)


@pytest.fixture(scope="module")
def volume():
    return cored()


@pytest.fixture(scope="module")
def scene(volume):
    return scene_of(volume, HALO, size=40, shading="phong")


def test_options_are_validated():
    backend = GLIsbvrRenderer()
    assert renderers.backend_module("gl-isbvr") == "renderers.gl.isbvr"
    paper = {"zinit": "ess+ert", "surfaces": "reduced", "phi_t_node": 8, "phi_p_node": 2, "depth_offset": 1.0,
             "step_factor": 1.0}
    assert {key: backend.options[key] for key in paper} == paper
    node_size = "^gl-isbvr option {}: expected one of 1, 2, 4, 8 voxels, got 3$"
    for options, match in [({"zinit": "ess+front"}, "gl-isbvr option zinit: 'ess\\+front' is not one of"),
                           ({"surfaces": "smooth"}, "gl-isbvr option surfaces"),
                           ({"phi_t_node": 3}, node_size.format("phi_t_node")),
                           ({"phi_p_node": 3}, node_size.format("phi_p_node")),
                           ({"depth_offset": -1}, "gl-isbvr option depth_offset"),
                           ({"order": "random"}, "gl-isbvr option order")]:
        with pytest.raises(InputError, match=match):
            GLIsbvrRenderer(**options)


@pytest.mark.parametrize("order", ORDERS)
def test_every_mode_is_lossless_against_basic(scene, order):
    truth, other = (basic(scene, name).image for name in (order, *set(ORDERS) - {order}))
    assert truth[..., 3].max() == pytest.approx(1.0) and 0.05 < (truth[..., 3] > 0).mean() < 0.5
    between_orders = np.abs(truth - other).max()  # float rounding: the orders sum in different sequences
    for zinit in RENDERING_MODES:
        result = isbvr(zinit=zinit, order=order).render(scene)
        error = np.abs(result.image - truth).max()
        assert error <= ROUNDING and (error < between_orders or between_orders == 0), zinit  # and in this order
        assert result.info["order"] == order and result.info["zinit"] == zinit


@pytest.mark.parametrize("volume_name", ["cored", "dense"])
def test_perspective_views_stay_lossless(volume, volume_name):
    # The dense block (no empty scalar) has material on every face of the box: Φ_t's faces there meet slices
    # at equal depth, which perspective depth resolves coarsely.
    if volume_name == "dense":
        volume = Volume(np.full((20, 24, 28), 110, np.uint8), name="dense")
    for azimuth, elevation in ((30, 20), (200, 10), (75, 60)):
        scene = scene_of(volume, HALO, size=40, projection="perspective", azimuth=azimuth, elevation=elevation)
        truth = basic(scene)
        for zinit in RENDERING_MODES:
            image = isbvr(zinit=zinit).render(scene).image
            assert np.abs(image - truth.image).max() <= ROUNDING, (azimuth, elevation, zinit)


def test_counters(scene, volume):
    truth = basic(scene)
    results = {zinit: isbvr(zinit=zinit).render(scene) for zinit in SURFACE_MODES}
    fragments = {zinit: result.counters["fragments"] for zinit, result in results.items()}
    generated = truth.counters["fragments"]
    for zinit, result in results.items():
        assert result.counters["fragments_generated"] == generated, zinit  # F: every slice fragment
        assert fragments[zinit] <= generated, zinit  # F'_c <= F
    assert fragments["none"] == generated and fragments["cull-all"] == 0
    assert fragments["ess+ert"] < min(fragments["ess"], fragments["ert"]) < generated
    assert fragments["front"] < generated
    assert results["none"].counters["init_fragments"] == results["cull-all"].counters["init_fragments"] == 0
    ess, ert = results["ess"].counters, results["ert"].counters
    assert ess["surface_fragments_t"] > 0 and ess["surface_fragments_p"] == 0 and ess["init_fragments"] > 0
    assert ert["surface_fragments_p"] > 0 and ert["surface_fragments_t"] == 0 and ert["init_fragments"] > 0
    # The init passes draw one side of each surface: the box's and Φ_p's front faces, Φ_t's back faces (F_t).
    box = int((ray_lengths(scene) > 0).sum())
    assert ert["init_fragments"] <= ert["surface_fragments_p"]
    assert ess["init_fragments"] <= box + ess["surface_fragments_t"]
    # The cube sets and meshes are the CPU side's (renderers/gl/isosurfaces.py), at any node sizes.
    normalised, alpha = volume.normalized(np.float32), HALO.table[:, 3]
    for node_t, node_p in ((8, 2), (2, 1)):
        counters = isbvr(zinit="ess+ert", phi_t_node=node_t, phi_p_node=node_p).render(scene).counters
        classes_t, classes_p = node_classes(normalised, alpha, node_t), node_classes(normalised, alpha, node_p)
        assert counters["cubes_t"] == phi_t_cubes(classes_t).sum() > 0
        assert counters["cubes_p"] == phi_p_cubes(classes_p).sum() > 0
        assert counters["surface_triangles_t"] == len(boundary_faces(phi_t_cubes(classes_t), node_t, volume.data.shape,
                                                                     region=classes_t.visible))
        assert counters["surface_triangles_p"] == len(boundary_faces(phi_p_cubes(classes_p), node_p, volume.data.shape,
                                                                     region=classes_p.opaque))


@pytest.mark.parametrize("points, drawn", [
    ([(0, 1, 0.5, 0.2, 0.01), (1, 1, 1, 1, 0.9)], ()),                               # never 0, never 1
    ([(0, 1, 0.5, 0.2, 0), (0.2, 1, 0.5, 0.2, 0), (1, 1, 1, 1, 0.9)], ("front", "ess", "ess+ert")),  # never 1
    ([(0, 1, 0.5, 0.2, 0.05), (0.8, 1, 1, 1, 1), (1, 1, 1, 1, 1)], ("ert", "ess+ert")),           # never 0
])
def test_a_surface_the_transfer_function_lacks_is_not_drawn(volume, points, drawn):
    """No zero-opacity region: no Φ_t passes (not the box's own faces, which cull nothing yet cost their
    passes); never opaque: no Φ_p pass. The paper's "no surfaces, no overhead"; the images stay Basic's."""
    scene = scene_of(volume, TransferFunction.from_points(points, name="partial"), size=32, shading="phong")
    truth = isbvr(zinit="none").render(scene)
    for zinit in RENDERING_MODES:
        result = isbvr(zinit=zinit).render(scene)
        assert np.abs(result.image - truth.image).max() <= ROUNDING, zinit
        assert (result.counters["init_fragments"] > 0) == (zinit in drawn), zinit
        if zinit not in drawn:
            assert result.counters["fragments"] == truth.counters["fragments"], zinit


def test_slice_ranges_split_the_slices_in_drawing_order(scene):
    view = make_view(scene, 1.0)
    eye, forward = np.asarray(scene.camera.eye), -np.asarray(scene.camera.basis()[2])
    triangles, depths = slice_polygons(view.model, eye, forward, view.near, view.step)
    for order in (triangles, triangles[::-1]):
        ranges = slice_ranges(order, view.model, eye, forward, depths)
        assert sum(count for _, count in ranges) == len(order) and len(ranges) == len(depths)
        assert [first for first, _ in ranges] == list(np.cumsum([0] + [count for _, count in ranges[:-1]]))
        for first, count in ranges:
            world = order[first:first + count].reshape(-1, 3) @ view.model[:3, :3].T + view.model[:3, 3]
            assert np.ptp((world - eye) @ forward) < 1e-4 * view.step  # one slice's plane


def test_slice_ert_culls_behind_opaque_pixels_within_its_threshold(scene):
    """The per-slice two-pass termination: every slice drawn twice (F_s = F), an error of at most 1 − T."""
    truth = basic(scene, "front-to-back")
    with pytest.raises(InputError, match="set order='front-to-back'"):
        GLIsbvrRenderer(zinit="slice-ert")
    for threshold in (1.0, 0.9):
        result = isbvr(zinit="slice-ert", order="front-to-back", opaque_threshold=threshold).render(scene)
        error = np.abs(result.image - truth.image).max()
        counters = result.counters
        assert error <= (ROUNDING if threshold == 1.0 else 1.0 - threshold + ROUNDING), threshold
        assert counters["fragments_generated"] == truth.counters["fragments"]
        assert 0 < counters["fragments"] < counters["fragments_generated"], threshold  # F'_c < F
        assert counters["init_fragments"] > 0 and result.timings["init"] > 0
    assert isbvr(zinit="slice-ert", order="front-to-back", opaque_threshold=0.9).render(scene).counters[
        "fragments"] < isbvr(zinit="slice-ert", order="front-to-back", opaque_threshold=1.0).render(scene).counters[
        "fragments"]


def box_front_depth(scene, step_factor=1.0):
    """Window depth of each pixel's ray entering the box (orthographic), and the depth of one step behind it."""
    view = make_view(scene, step_factor)
    origins, directions = scene.camera.rays(scene.width, scene.height)
    to_texture = np.linalg.inv(view.model)
    origin = origins @ to_texture[:3, :3].T + to_texture[:3, 3]
    direction = directions @ to_texture[:3, :3].T
    with np.errstate(divide="ignore", invalid="ignore"):
        near = np.nanmax(np.minimum(-origin / direction, (1 - origin) / direction), axis=-1)
    to_clip = view.mvp @ to_texture

    def depth(t):
        world = origins + t[..., None] * directions
        clip = np.concatenate([world, np.ones(world.shape[:-1] + (1,))], axis=-1) @ to_clip.T
        return (clip[..., 2] / clip[..., 3] + 1) / 2

    front = depth(near)
    return front, depth(near + view.step) - front


def test_depth_offset_zero_loses_the_pixels_where_opaque_material_meets_the_box(scene):
    # Inside the volume a Φ_p face has opaque data in front of it (the blocks' apron): the paper's placement
    # loses nothing here.
    truth = basic(scene)
    assert np.abs(isbvr(zinit="ess+ert", depth_offset=0.0).render(scene).image - truth.image).max() <= ROUNDING
    # Opaque data reaching the box's faces: there Φ_p's face is (within a slice of) the box's face, no slice
    # samples in front of it, and offset 0 culls the first sample inside, which is opaque and carries the colour.
    # One slice of offset keeps it.
    ramp = scene_of(tilted(), HALO, size=40, azimuth=20, elevation=10)
    truth = basic(ramp)
    assert np.abs(isbvr(zinit="ert").render(ramp).image - truth.image).max() <= ROUNDING
    at_face = isbvr(zinit="ert", depth_offset=0.0)
    image = at_face.render(ramp).image
    error = np.abs(image - truth.image).max(axis=-1)
    lost = error > ROUNDING
    assert error.max() > 0.5 and 0.01 < lost.mean() < 0.2  # measured: 3 % of the pixels, lost whole
    assert np.all(image[..., 3] <= truth.image[..., 3] + ROUNDING)  # culling drops samples, never adds
    face = at_face.init_depth(ramp)
    front, one_slice = box_front_depth(ramp)
    assert np.all(face[lost] < front[lost] + one_slice[lost] + 1e-6)


def test_coarse_surfaces_cut_holes(scene):
    """The paper's Fig. 4a: marching cubes on the block maxima (Φ_t) cuts off visible voxels (its Fig. 3's
    voxel B), and the depth passes then cull material that Basic draws."""
    truth = basic(scene)
    assert np.abs(isbvr(zinit="ess+ert").render(scene).image - truth.image).max() <= ROUNDING
    coarse = isbvr(zinit="ess+ert", surfaces="coarse").render(scene)
    error = np.abs(coarse.image - truth.image).max(axis=-1)
    assert error.max() > 0.5 and (error > 1 / 255).mean() > 0.02
    assert np.all(coarse.image[..., 3] <= truth.image[..., 3] + ROUNDING)  # holes: material missing


# ------------------------------------------------------------------------------ depth after the init passes
def expected_depth(scene, backend):
    """The depth buffer after ``backend``'s init passes on an axis-aligned orthographic ``scene``, computed from
    the cube grids: the box's front, the last exit from Φ_t's region (visible blocks) and the first entry into
    Φ_p's region (opaque blocks) pushed ``depth_offset`` steps, per pixel; and a mask of the pixels whose ray
    runs at least a quarter pixel from every edge of the blocks drawn."""
    instance = scene.volumes[0]
    view = make_view(scene, backend.step_factor)
    to_texture = np.linalg.inv(view.model)
    to_clip = view.mvp @ to_texture
    origins, directions = scene.camera.rays(scene.width, scene.height)
    origin = origins @ to_texture[:3, :3].T + to_texture[:3, 3]
    direction = directions[0, 0] @ to_texture[:3, :3].T
    axis = int(np.argmax(np.abs(direction)))
    across = [k for k in range(3) if k != axis]
    assert np.allclose(direction[across], 0) and np.allclose(directions, directions[0, 0])
    n_xyz = np.asarray(instance.volume.data.shape[::-1])
    ascending = direction[axis] > 0
    forward = directions[0, 0]

    def depth_at(plane, push=0.0):
        """Window depth where each pixel's ray meets texture coordinate ``plane`` along ``axis``."""
        point = origin + ((plane - origin[..., axis]) / direction[axis])[..., None] * direction
        world = point @ view.model[:3, :3].T + view.model[:3, 3] + push * forward
        clip = np.concatenate([world, np.ones(world.shape[:-1] + (1,))], axis=-1) @ to_clip.T
        return (clip[..., 2] / clip[..., 3] + 1) / 2

    def crossings(region, node_size):
        """(hit, first entry plane, last exit plane) of each pixel's ray through ``region``'s blocks."""
        grid = np.moveaxis(region.transpose(2, 1, 0), axis, -1)  # [across..., along axis]
        count = grid.shape[-1]
        cells = [np.clip(np.floor(origin[..., k] * n_xyz[k] / node_size).astype(int), 0, grid.shape[i] - 1)
                 for i, k in enumerate(across)]
        column = grid[cells[0], cells[1]]
        if not ascending:
            column = column[..., ::-1]
        hit = column.any(axis=-1)
        first = np.argmax(column, axis=-1)
        last = count - 1 - np.argmax(column[..., ::-1], axis=-1)
        if not ascending:  # back to block indices
            first, last = count - 1 - first, count - 1 - last
        planes = np.minimum(np.arange(count + 1) * node_size / n_xyz[axis], 1.0)  # block k: planes k, k + 1
        if ascending:
            return hit, planes[first], planes[last + 1]
        return hit, planes[first + 1], planes[last]

    normalised, alpha = instance.volume.normalized(np.float32), instance.transfer_function.table[:, 3]
    in_box = np.all((origin[..., across] > 0) & (origin[..., across] < 1), axis=-1)
    hit_t, entry_t, exit_t = crossings(node_classes(normalised, alpha, backend.phi_t_node).visible,
                                       backend.phi_t_node)
    hit_p, entry_p, _ = crossings(node_classes(normalised, alpha, backend.phi_p_node).opaque, backend.phi_p_node)
    box_front = depth_at(0.0 if ascending else 1.0)
    opaque = np.where(in_box & hit_p, depth_at(entry_p, backend.depth_offset * view.step), 1.0)
    exit_based = np.where(in_box, np.where(hit_t, depth_at(exit_t), box_front), 1.0)
    expected = {"none": np.ones(in_box.shape), "cull-all": np.zeros(in_box.shape), "ert": np.minimum(opaque, 1.0),
                "front": np.where(in_box & hit_t, depth_at(entry_t), 1.0), "ess": exit_based,
                "ess+ert": np.minimum(exit_based, opaque)}[backend.zinit]
    # Pixels whose ray passes near an edge of the blocks drawn (or of the box) are left out.
    grids = {"ert": [backend.phi_p_node], "front": [backend.phi_t_node], "ess": [backend.phi_t_node],
             "ess+ert": [backend.phi_t_node, backend.phi_p_node]}.get(backend.zinit, [])
    pixel = max(np.abs(origin[0, 1] - origin[0, 0]).max(), np.abs(origin[1, 0] - origin[0, 0]).max())
    clear = np.ones(in_box.shape, bool)
    for node_size in grids:
        for k in across:
            blocks = origin[..., k] * n_xyz[k] / node_size
            clear &= np.abs(blocks - np.rint(blocks)) * node_size / n_xyz[k] > 0.25 * pixel
    return expected, clear


@pytest.mark.parametrize("azimuth", [0.0, 90.0])
@pytest.mark.parametrize("zinit", SURFACE_MODES)
def test_init_depth_matches_the_cube_grids(volume, zinit, azimuth):
    scene = scene_of(volume, HALO, size=48, azimuth=azimuth, elevation=0.0)
    backend = isbvr(zinit=zinit)
    expected, clear = expected_depth(scene, backend)
    depth = backend.init_depth(scene)
    assert depth.shape == (48, 48) and clear.mean() > 0.4
    assert np.abs(depth - expected)[clear].max() < 1e-5
    if zinit not in ("none", "cull-all"):  # the surfaces cover compared pixels
        assert (expected[clear] < 1).sum() >= 5


def test_init_depth_pushes_phi_p_by_the_offset(volume):
    scene = scene_of(volume, HALO, size=48, azimuth=0.0, elevation=0.0)
    for offset in (0.0, 2.5):
        backend = isbvr(zinit="ess+ert", depth_offset=offset)
        expected, clear = expected_depth(scene, backend)
        assert np.abs(backend.init_depth(scene) - expected)[clear].max() < 1e-5


# ------------------------------------------------------------------------------------------- the cache
def test_drop_caches_rebuilds_the_surfaces(scene):
    backend = GLIsbvrRenderer(zinit="ess+ert")
    try:
        first = backend.render(scene).timings
        assert "phi_t" in first and "phi_p" in first
        cached = backend.render(scene).timings
        assert "phi_t" not in cached and "phi_p" not in cached
        assert backend.caches_preprocessing
        backend.drop_caches()
        again = backend.render(scene).timings
        assert "phi_t" in again and "phi_p" in again
        # A new transfer function is a new classification.
        assert "phi_t" in backend.render(scene_of(scene.volumes[0].volume, TransferFunction.ramp(0.3, 0.6),
                                                  size=40)).timings
        backend.drop_caches()
        backend.drop_caches()  # nothing left to drop
        exit_based = GLIsbvrRenderer(zinit="ess")
        only_t = exit_based.render(scene).timings
        exit_based.close()
        assert "phi_t" in only_t and "phi_p" not in only_t
    finally:
        backend.close()
