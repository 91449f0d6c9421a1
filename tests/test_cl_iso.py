"""cl-tiled's exact iso-surfaces (renderers/cl/kernels/iso.cl) against the reference's cell walk: the crossing and its
normal on random cells, what a sampled hit misses (a one-voxel sheet, a tube thinner than a step), whole frames of
one volume and of overlapping volumes with their own isovalues, and a perspective eye inside a volume."""

from dataclasses import replace

import numpy as np
import pytest

import renderers
from core.camera import Camera
from core.errors import InputError
from core.mesh import HomogeneousMedium, Mesh, MeshInstance, SurfaceMaterial
from core.scene import CsgNode, Scene, Shading, VolumeInstance
from core.volume import Volume
from datasets import meshes
from iso_shapes import normal_angles, random_rays, reference_crossings, sheet, thin_scene, tube
from renderers.cl import context
from renderers.cl.scene import OBJECT_DTYPE
from renderers.cl.tiled import ClTiledRenderer, _atlas_defines
from renderers.reference.renderer import ReferenceRenderer
from reports.metrics import psnr
from test_cl_tiled import SMOOTH, blob, multi_scene, needs_cl

CROSSINGS = """
__kernel void crossings(__constant Object* objects, __global const ATLAS_T* atlas, int4 atlas_dims,
                        __global const float4* origins, __global const float4* directions, __global float4* out) {
    int i = get_global_id(0);
    int state = -1;
    uint walked = 0, solved = 0;
    float3 origin = origins[i].xyz, direction = directions[i].xyz;
    float t = iso_walk(0.0f, 1.0f, &objects[0], origin, direction, atlas, atlas_dims, &state, &walked, &solved);
    float3 g = (float3)(0.0f);
    if (t < ISO_FAR) {
        float3 u = origin + t * direction;
        const float3 ex = (float3)(1.0f, 0.0f, 0.0f), ey = (float3)(0.0f, 1.0f, 0.0f), ez = (float3)(0.0f, 0.0f, 1.0f);
        int4 slot = (int4)(0);
        g = (float3)(trilinear(atlas, atlas_dims, slot, objects[0].dims, u + ex)
                     - trilinear(atlas, atlas_dims, slot, objects[0].dims, u - ex),
                     trilinear(atlas, atlas_dims, slot, objects[0].dims, u + ey)
                     - trilinear(atlas, atlas_dims, slot, objects[0].dims, u - ey),
                     trilinear(atlas, atlas_dims, slot, objects[0].dims, u + ez)
                     - trilinear(atlas, atlas_dims, slot, objects[0].dims, u - ez));
    }
    out[i] = (float4)(t, (float)walked, 0.0f, 0.0f);
    out[count_offset(i)] = (float4)(g, 0.0f);
}
"""


def cl_crossings(volume, base, slope, iso):
    """The OpenCL walk's first crossing on ``t`` in [0, 1] of each ray ``base + t·slope`` (lattice coordinates of
    ``volume``, z-y-x: one object whose world is its lattice), ``inf`` where there is none, the cell segments it
    walked, and the hit's central differences (the normal cl-tiled shades with)."""
    import pyopencl as cl

    entry = context.shared(context.selector_for(None))
    count = len(base)
    source = (context.kernel_source("common.cl", "iso.cl", "pixel.cl")
              + f"\nint count_offset(int i) {{ return i + {count}; }}\n" + CROSSINGS)
    kernels = context.kernels(entry, source, [*_atlas_defines(np.float32), "-DISO", "-DMAXF=1", "-DPHONG"])
    record = np.zeros(1, OBJECT_DTYPE)
    record["to_voxel"] = np.eye(3, 4)
    nz, ny, nx = volume.shape
    record["dims"] = (nx, ny, nz, 0)
    record["params"] = (1, 0, iso, 0)
    flags = cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR

    def buffer(array):
        return cl.Buffer(entry.context, flags, hostbuf=np.ascontiguousarray(array))

    rays = [np.c_[values, np.zeros(count)].astype(np.float32) for values in (base, slope)]
    out = np.zeros((2 * count, 4), np.float32)
    out_buffer = cl.Buffer(entry.context, cl.mem_flags.WRITE_ONLY, out.nbytes)
    kernels["crossings"](entry.queue, (count,), None, buffer(record), buffer(volume.astype(np.float32)),
                         np.array([nx, ny, nz, 0], np.int32), buffer(rays[0]), buffer(rays[1]), out_buffer)
    cl.enqueue_copy(entry.queue, out, out_buffer, is_blocking=True)
    t = out[:count, 0].astype(float)
    return np.where(np.isinf(t), np.inf, t), out[:count, 1].astype(int), out[count:, :3].astype(float)


@needs_cl
def test_the_crossing_is_the_references_within_a_ten_thousandth_of_a_voxel_on_random_cells():
    volume, base, slope = random_rays(7, (5, 4, 6))
    found, cells, _ = cl_crossings(volume, base, slope, 0.5)
    truth = reference_crossings(volume, base, slope, 0.5)
    both = np.isfinite(truth) & np.isfinite(found)
    assert np.array_equal(np.isfinite(found), np.isfinite(truth))  # the same rays hit
    assert both.sum() > len(base) // 2
    assert (np.abs(found[both] - truth[both]) * np.linalg.norm(slope[both], axis=1)).max() < 1e-4
    assert (cells >= 1).all()


@needs_cl
def test_the_normal_at_the_hit_is_the_references_within_half_a_degree():
    volume, base, slope = random_rays(11, (6, 5, 7))
    found, _, normals = cl_crossings(volume, base, slope, 0.5)
    truth = reference_crossings(volume, base, slope, 0.5)
    angles = normal_angles(volume, base + truth[:, None] * slope, normals, np.isfinite(truth) & np.isfinite(found))
    assert len(angles) > len(base) // 3
    assert angles.max() < 0.5


@needs_cl
@pytest.mark.parametrize("make, camera", [(sheet, {}), (tube, {"elevation": 80.0, "size": 64})],
                         ids=["one-voxel sheet", "tube thinner than a step"])
def test_thin_features_are_hit_where_the_exact_reference_hits_them(make, camera):
    scene = thin_scene(make(), **camera)
    truth = ReferenceRenderer().render(scene).image[..., 3] > 0.5
    result = ClTiledRenderer().render(scene)
    assert truth.sum() > 20
    assert ((result.image[..., 3] > 0.5) != truth).sum() <= 2  # grazing rays: float32 against float64
    assert result.counters["crossings"] == (result.image[..., 3] > 0.5).sum()


@needs_cl
@pytest.mark.parametrize("shading", ["none", "phong"])
def test_one_volume_is_the_references_at_any_step(shading):
    """Measured (PoCL, 40²): 138 dB with Blinn–Phong, identical unshaded. The step samples nothing here."""
    scene = Scene((VolumeInstance(blob(), SMOOTH, isovalue=0.3),), camera=Camera(azimuth=30, elevation=20),
                  width=40, height=40, shading=Shading(model=shading), mode="iso")
    truth = ReferenceRenderer().render(scene).image
    coarse = ClTiledRenderer(step_factor=1.0).render(scene)
    fine = ClTiledRenderer(step_factor=0.25).render(scene)
    assert psnr(truth, coarse.image) >= 100
    assert np.array_equal(coarse.image, fine.image) and coarse.info["step"] is None
    counters = coarse.counters
    assert counters["crossings"] == np.count_nonzero(truth[..., 3]) > 100
    assert 0 < counters["iso_cells_solved"] < counters["samples"] and counters["early_terminations"] == 0


@needs_cl
@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_overlapping_volumes_with_their_own_isovalues_are_the_references(projection):
    """Three overlapping instances (transforms, anisotropic spacing, 8-bit and float data), each with its own
    isovalue and colour: the nearest first crossing of any of them. Measured (PoCL, 40²): 141 and 137 dB."""
    base = multi_scene(projection=projection)
    scene = replace(base, mode="iso",
                    volumes=tuple(replace(v, isovalue=iso) for v, iso in zip(base.volumes, (0.4, 0.5, 0.3))))
    truth = ReferenceRenderer().render(scene)
    result = ClTiledRenderer().render(scene)
    assert psnr(truth.image, result.image) >= 100
    # Hits of more than one volume: the colours at the isovalues differ per instance.
    colours = {tuple(np.round(p, 1)) for p in result.image[result.image[..., 3] > 0][:, :3]}
    assert len(colours) > 3 and result.counters["crossings"] == np.count_nonzero(truth.image[..., 3])


@needs_cl
def test_a_perspective_eye_inside_a_volume_takes_its_state_there():
    """The eye inside the blob's surface: the rays start above the isovalue, so the crossing is where they leave it
    (the surface seen from inside), as the reference's state at the ray's start defines it."""
    scene = Scene((VolumeInstance(blob(), SMOOTH, isovalue=0.3),), width=32, height=32, mode="iso",
                  camera=Camera(projection="perspective", fov_y=60.0, azimuth=20, elevation=10, distance=0.01))
    assert scene.camera_inside_volume()
    truth = ReferenceRenderer().render(scene).image
    assert np.count_nonzero(truth[..., 3]) == 32 * 32
    assert psnr(truth, ClTiledRenderer().render(scene).image) >= 100


def test_iso_sweeps_one_setting_since_no_option_trades_accuracy_there():
    assert ClTiledRenderer.quality_sweep_for("iso") == ({},)
    assert ClTiledRenderer.quality_sweep_for("dvr") == ClTiledRenderer.quality_sweep
    assert "iso" in renderers.backend_class("cl-tiled").capabilities.modes


# ------------------------------------------------------------------ iso with boundaries, CSG, surfaces and media
@pytest.fixture(scope="module")
def sphere():
    return meshes.noisy_sphere(subdivisions=3, amplitude=0.1)          # 1280 triangles, radius about 1


def iso_blob(**instance):
    return VolumeInstance(blob(), SMOOTH, isovalue=0.3, **instance)


def iso_scene(volumes, **scene):
    return Scene(tuple(volumes), camera=Camera(azimuth=30, elevation=20), width=48, height=48,
                 shading=Shading(model="phong"), mode="iso", **scene)


@needs_cl
def test_a_boundary_that_cuts_nothing_changes_nothing_in_the_reference_and_in_cl_tiled(sphere):
    """The reference's geometry walk against its volume-only kernel, and cl-tiled against both, where the boundary
    (a sphere around the whole box) cuts nothing."""
    around = Mesh(sphere.vertices * 40 + 16, sphere.faces, name="around")
    plain, bounded = iso_scene([iso_blob()]), iso_scene([iso_blob(boundary=around)])
    truth = ReferenceRenderer().render(plain).image
    assert psnr(truth, ReferenceRenderer().render(bounded).image) >= 120
    assert psnr(truth, ClTiledRenderer().render(bounded).image) >= 100


@needs_cl
def test_a_boundary_through_the_surface_shows_its_cut_face_as_the_reference_does():
    """A ball (its surface at radius 8.4 voxels) cut in half by a box boundary, seen head-on from the cut side: inside
    the surface the ray's state differs from its box entry's, so the cut face is the hit, a flat cap (every central
    pixel at one depth). Measured (PoCL, 32²): 171 dB against the reference."""
    n = 32
    z, y, x = np.meshgrid(*(np.arange(n) + 0.5,) * 3, indexing="ij")
    ball = np.clip(1 - np.sqrt((x - 16) ** 2 + (y - 16) ** 2 + (z - 16) ** 2) / 12, 0, 1).astype(np.float32)
    cube = meshes.boxes_in_a_row(count=1)
    half = Mesh(cube.vertices * (20, 40, 40) + (6, 16, 16), cube.faces, name="half")   # object x in [-4, 16]
    scene = Scene((VolumeInstance(Volume(ball, name="ball"), SMOOTH, isovalue=0.3, boundary=half),),
                  camera=Camera(azimuth=90, elevation=0), width=32, height=32, shading=Shading(model="phong"),
                  mode="iso")
    truth = ReferenceRenderer(depth=True).render(scene)
    centre = truth.info["depth"][13:19, 13:19]
    assert np.isfinite(centre).all() and np.ptp(centre) < 1e-9
    assert psnr(truth.image, ClTiledRenderer().render(scene).image) >= 100


CENTRED = np.array([[1, 0, 0, -16], [0, 1, 0, -16], [0, 0, 1, -16], [0, 0, 0, 1.0]])
"""The blob's box [0, 32]³ centred on the origin."""


@needs_cl
@pytest.mark.parametrize("operation", ["intersection", "difference"])
def test_csg_carves_the_iso_surface_as_the_reference_does(sphere, operation):
    """Measured (PoCL, 48²): 146 and 141 dB against the reference; the carving costs the uncut image 21 and 27 dB."""
    carver = MeshInstance(sphere, transform=np.diag([9.0, 9.0, 9.0, 1.0]), name="carver",
                          surface=SurfaceMaterial(colour=(0.9, 0.8, 0.2)))
    scene = iso_scene([iso_blob(name="v", transform=CENTRED)], meshes=(carver,),
                      csg=(CsgNode(operation, ("v", "carver")),))
    truth = ReferenceRenderer().render(scene).image
    assert psnr(ReferenceRenderer().render(replace(scene, meshes=(), csg=())).image, truth) < 30   # it is carved
    assert psnr(truth, ClTiledRenderer().render(scene).image) >= 100


@needs_cl
def test_a_translucent_surface_and_a_medium_in_front_of_the_iso_surface(sphere):
    glass = MeshInstance(sphere, transform=np.array([[9.0, 0, 0, 0], [0, 9.0, 0, 0], [0, 0, 9.0, 14.0], [0, 0, 0, 1]]),
                         surface=SurfaceMaterial(colour=(0.3, 0.5, 0.9), alpha=0.4),
                         medium=HomogeneousMedium(colour=(0.9, 0.4, 0.2), extinction=0.05), name="glass")
    scene = replace(iso_scene([iso_blob(transform=CENTRED)]), meshes=(glass,), camera=Camera(azimuth=0, elevation=0))
    truth = ReferenceRenderer().render(scene).image
    assert psnr(ReferenceRenderer().render(replace(scene, meshes=())).image, truth) < 30   # the glass shows
    assert psnr(truth, ClTiledRenderer().render(scene).image) >= 50


def test_mip_still_refuses_geometry_and_iso_takes_it():
    volume = iso_blob()
    cube = meshes.boxes_in_a_row(count=1)
    assert Scene((volume,), meshes=(MeshInstance(cube),), mode="iso").mode == "iso"
    with pytest.raises(InputError, match="modes 'dvr' and 'iso'"):
        Scene((volume,), meshes=(MeshInstance(cube),), mode="mip")
