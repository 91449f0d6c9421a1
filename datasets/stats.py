"""The data-set statistics the papers report, computed under a classification preset.

* Lacroute (note 003, Table 5.1 and §5.3): the fraction of non-transparent voxels (opacity above
  the minimum-opacity threshold, 0.05 in the thesis) and the coherence ``c_v``, the mean number
  of non-transparent voxel runs per scanline (VolPack run-length encodes along x).
* Krüger & Westermann (note 000 §6): the fraction of empty 8³ blocks, i.e. blocks that
  empty-space skipping can drop because no voxel in them has opacity above zero.

Classification follows CONVENTIONS.md exactly: the normalised scalar is looked up in the preset's
RGBA table by linear interpolation between entries (:meth:`TransferFunction.lookup`), and when
the preset has a :class:`GradientOpacity` the opacity is multiplied by ``g(u)`` with
``u = |∇s|·Δ0 / (√3/2)``, the gradient by central differences in object space with clamp-to-edge
neighbours (what a 3-D texture fetch gives at the border).
"""

import numpy as np

from core.volume import Volume
from core.errors import InputError
from core.transfer import MAX_GRADIENT, Preset
from core.validation import check_positive_int, check_scalar


def _interpolate(table, x):
    """Linear interpolation of ``table`` (entry ``i`` at ``i/(N-1)``) at ``x`` in [0, 1], float32."""
    n = table.size
    pos = np.clip(x, 0, 1) * np.float32(n - 1)
    i0 = np.minimum(pos.astype(np.int32), n - 2)
    w = pos - i0
    t = table.astype(np.float32)
    return t[i0] * (1 - w) + t[i0 + 1] * w


def _tf_opacity(volume, transfer_function):
    """Opacity of the scalar classification alone, float32, shape of the volume.

    Integer volumes are classified once per distinct raw value with
    :meth:`TransferFunction.lookup` (float64) and the result is gathered, which is exact and fast;
    float volumes are interpolated voxel by voxel in float32.
    """
    data = volume.data
    lo, hi = volume.value_range
    if data.dtype.kind == "u":
        raw = np.arange(np.iinfo(data.dtype).max + 1, dtype=np.float64)
        s = np.clip((raw - lo) / (hi - lo), 0.0, 1.0)
        lut = transfer_function.lookup(s)[:, 3].astype(np.float32)
        return lut[data]
    return _interpolate(transfer_function.table[:, 3], volume.normalized())


def gradient_magnitude(volume):
    """``|∇s|`` of the normalised scalar in object units: central differences, clamp-to-edge."""
    s = np.pad(volume.normalized(), 1, mode="edge")  # the missing neighbour repeats the edge voxel
    magnitude = np.zeros(volume.data.shape, dtype=np.float32)
    for axis, spacing in zip((2, 1, 0), volume.spacing):
        ahead, behind = [slice(1, -1)] * 3, [slice(1, -1)] * 3
        ahead[axis], behind[axis] = slice(2, None), slice(None, -2)
        diff = s[tuple(ahead)] - s[tuple(behind)]
        diff *= np.float32(0.5 / spacing)
        magnitude += diff * diff
    return np.sqrt(magnitude, out=magnitude)


def opacity(volume, preset):
    """Per-voxel opacity (per reference step) of ``volume`` under ``preset``, float32.

    Parameters
    ----------
    volume : Volume
    preset : core.transfer.Preset

    Returns
    -------
    numpy.ndarray
        Shape ``(nz, ny, nx)``, values in [0, 1].
    """
    if not isinstance(volume, Volume):
        raise InputError(f"statistics: expected a Volume, got {type(volume).__name__}")
    if not isinstance(preset, Preset):
        raise InputError(f"statistics: expected a Preset, got {type(preset).__name__}")
    alpha = _tf_opacity(volume, preset.transfer_function)
    if preset.gradient_opacity is not None:
        step = preset.transfer_function.reference_step or volume.min_spacing
        u = gradient_magnitude(volume)
        u *= np.float32(step / MAX_GRADIENT)
        alpha *= _interpolate(preset.gradient_opacity.table, u)
    return alpha


def _blocks_with(mask, block):
    """Number of ``block``³ blocks (partial ones at the far faces included) with any True voxel."""
    nz, ny, nx = mask.shape
    bz, by, bx = (-(-n // block) for n in mask.shape)
    padded = np.zeros((bz * block, by * block, bx * block), dtype=bool)
    padded[:nz, :ny, :nx] = mask
    occupied = padded.reshape(bz, block, by, block, bx, block).any(axis=(1, 3, 5))
    return int(occupied.sum()), bz * by * bx


def statistics(volume, preset, *, threshold=0.05, block=8):
    """Statistics of ``volume`` classified by ``preset``, as the papers report them.

    Parameters
    ----------
    volume : Volume
    preset : core.transfer.Preset
    threshold : float, optional
        Minimum opacity: a voxel with opacity at or below it is transparent (Lacroute's 0.05).
    block : int, optional
        Edge of the empty-space-skipping blocks (Krüger & Westermann's 8).

    Returns
    -------
    dict
        Flat ``name → number`` (ready to become CSV columns):

        ``nx, ny, nz, voxels, megabytes``
            Dimensions and raw size in MiB (2²⁰ bytes, as the thesis's Table 5.1).
        ``sx, sy, sz``
            The voxel spacing (what :func:`in_box` needs to place the volume in another box).
        ``value_mean, value_std, value_min, value_max``
            Raw voxel values; ``scalar_mean`` is the mean normalised scalar.
        ``nonzero_fraction``
            Voxels with opacity > 0.
        ``nontransparent_fraction``, ``nontransparent_voxels``
            Voxels with opacity > ``threshold``.
        ``mean_opacity``
            Mean opacity of the non-transparent voxels (the thesis's third axis of Fig. 5.18).
        ``empty_block_fraction``
            ``block``³ blocks with no voxel of opacity > 0 (what empty-space skipping drops).
        ``empty_block_fraction_threshold``
            Blocks with no voxel above ``threshold``.
        ``runs``, ``runs_per_scanline``, ``runs_per_occupied_scanline``
            Runs of consecutive non-transparent voxels along x (VolPack's scanlines): the total,
            the mean over all ``ny·nz`` scanlines (``c_v``) and over the scanlines that hold any.
        ``mean_run_length``
            Non-transparent voxels per run.
        ``threshold``, ``block``
            The parameters used.
        ``generation_seconds``
            Phantoms only: how long the generator took (from ``volume.meta``).

    Notes
    -----
    Memory stays at a few float32 copies of the volume, so 256³ takes about a second.
    """
    threshold = check_scalar(threshold, name="statistics threshold", low=0, high=1, high_open=True)
    block = check_positive_int(block, name="statistics block")
    alpha = opacity(volume, preset)
    data = volume.data
    nz, ny, nx = data.shape
    voxels = data.size

    solid = alpha > threshold
    count = int(np.count_nonzero(solid))
    runs = int(np.count_nonzero(solid[..., 0]) + np.count_nonzero(solid[..., 1:] > solid[..., :-1]))
    occupied_lines = int(np.count_nonzero(solid.any(axis=2)))
    occupied_any, blocks = _blocks_with(alpha > 0, block)
    occupied_solid, _ = _blocks_with(solid, block)
    lo, hi = volume.value_range
    mean = float(data.mean(dtype=np.float64))
    vmin, vmax = float(data.min()), float(data.max())
    if lo <= vmin and vmax <= hi:
        scalar_mean = (mean - lo) / (hi - lo)
    else:  # some values are clipped by the range: average what the renderers see
        scalar_mean = float(volume.normalized().mean(dtype=np.float64))
    return {
        "nx": nx, "ny": ny, "nz": nz, "voxels": int(voxels),
        "sx": float(volume.spacing[0]), "sy": float(volume.spacing[1]), "sz": float(volume.spacing[2]),
        "megabytes": data.nbytes / 2**20,
        "value_mean": mean,
        "value_std": float(data.std(dtype=np.float64)),
        "value_min": vmin,
        "value_max": vmax,
        "scalar_mean": scalar_mean,
        "nonzero_fraction": float(np.count_nonzero(alpha > 0) / voxels),
        "nontransparent_fraction": count / voxels,
        "nontransparent_voxels": count,
        "mean_opacity": float(alpha[solid].mean(dtype=np.float64)) if count else 0.0,
        "empty_block_fraction": 1 - occupied_any / blocks,
        "empty_block_fraction_threshold": 1 - occupied_solid / blocks,
        "runs": runs,
        "runs_per_scanline": runs / (ny * nz),
        "runs_per_occupied_scanline": runs / occupied_lines if occupied_lines else 0.0,
        "mean_run_length": count / runs if runs else 0.0,
        "threshold": threshold,
        "block": block,
        **({"generation_seconds": float(volume.meta["generation_seconds"])}
           if "generation_seconds" in volume.meta else {}),
    }


BOX_STATISTICS = ("nontransparent_fraction", "empty_block_fraction", "runs_per_scanline", "mean_run_length")
"""The statistics the stand-ins are compared on: what the papers' speed-ups depend on."""


def in_box(stats, box, *, voxel=None):
    """The statistics a volume would have, centred in a larger box of transparent background.

    A real scan is cropped to its subject while a phantom fills a box of the papers' size, so
    their statistics compare only in one box at one voxel size. This places the measured volume
    (``stats`` from :func:`statistics`, which records its dimensions and spacing) in ``box``
    voxels of edge ``voxel`` (default: the volume's finest spacing), padding with voxels of
    opacity 0, and returns the four :data:`BOX_STATISTICS` (and ``nonzero_fraction``) exactly as
    :func:`statistics` would measure them there when the volume's spacing equals ``voxel`` and it sits at a multiple of
    the block size: the fractions scale by the volume's share of the box, runs per scanline by
    its share of the scanlines, run lengths by the spacing along x. An anisotropic volume is
    counted as if resampled to ``voxel`` (its native 8³ blocks are then taller than the box's;
    the empty-block fraction is the one estimate).

    Parameters
    ----------
    stats : dict
        Output of :func:`statistics` (``nx, ny, nz, sx, sy, sz`` and the four statistics).
    box : sequence of 3 int
        ``(nx, ny, nz)`` of the box.
    voxel : float, optional
        Edge of the box's voxels in the volume's units.

    Returns
    -------
    dict
        The five statistics in the box.

    Raises
    ------
    InputError
        ``stats`` lacks a key, or the volume does not fit in the box.
    """
    missing = [k for k in ("nx", "ny", "nz", "sx", "sy", "sz", *BOX_STATISTICS) if k not in stats]
    if missing:
        raise InputError(f"in_box: stats lack {', '.join(missing)}; pass the dict statistics() returns")
    if len(box) != 3:
        raise InputError(f"in_box box: expected (nx, ny, nz), got {box!r}")
    box = [check_positive_int(n, name="in_box box") for n in box]
    spacing = np.array([stats["sx"], stats["sy"], stats["sz"]], dtype=np.float64)
    voxel = float(spacing.min()) if voxel is None else check_scalar(voxel, name="in_box voxel", low=0, low_open=True)
    extent = np.array([stats["nx"], stats["ny"], stats["nz"]]) * spacing / voxel
    if np.any(extent > np.array(box) + 0.5):
        raise InputError(f"in_box: a volume of {np.round(extent, 1).tolist()} voxels does not fit in the box {box}; "
                         f"measure the phantom at a larger size")
    fill = float(np.prod(extent) / np.prod(box))
    return {
        "nontransparent_fraction": stats["nontransparent_fraction"] * fill,
        **({"nonzero_fraction": stats["nonzero_fraction"] * fill} if "nonzero_fraction" in stats else {}),
        "empty_block_fraction": 1 - (1 - stats["empty_block_fraction"]) * fill,
        "runs_per_scanline": stats["runs_per_scanline"] * extent[1] * extent[2] / (box[1] * box[2]),
        "mean_run_length": stats["mean_run_length"] * spacing[0] / voxel,
    }
