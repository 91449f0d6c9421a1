"""Readers for volume files: headerless raw, VolPack ``.den`` and NRRD.

Every reader checks the header and the file size against each other first and raises
:class:`~core.errors.InputError` naming the file and the mismatch before it reads any data
(CONVENTIONS, Errors). All return a :class:`~core.volume.Volume` indexed ``[z, y, x]`` with x
fastest, the order all three formats store.
"""

import bz2
import gzip
import math
import re
import struct
from pathlib import Path

import numpy as np

from core.volume import Volume
from core.errors import InputError
from core.resources import check_memory
from core.validation import SUPPORTED_DTYPES, check_positive_vector

RAW_NAME = re.compile(r"^(?P<stem>.+)_(?P<x>\d+)x(?P<y>\d+)x(?P<z>\d+)_(?P<dtype>[a-z0-9]+)\.raw$")
"""``<name>_<X>x<Y>x<Z>_<dtype>.raw``, the naming used by the real-data folder and open-scivis."""


def _existing(path):
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: {'is a folder, not a volume file' if path.is_dir() else 'no such file'}")
    return path


def _check_fits(path, dims, dtype):
    """Refuse a volume this machine cannot hold before reading it: its values and one converted copy."""
    count = math.prod(dims)
    check_memory(2 * count * dtype.itemsize, what=f"{path}: a {'×'.join(map(str, dims))} {dtype.name} volume",
                 detail="its values and one converted copy", fix="read it on a machine with more memory, or crop it")


def _dims(dims, where):
    try:
        values = tuple(int(d) for d in dims)
    except (TypeError, ValueError):
        raise InputError(f"{where}: dims must be three positive integers (x, y, z), got {dims!r}") from None
    if len(values) != 3 or min(values) < 1:
        raise InputError(f"{where}: dims must be three positive integers (x, y, z), got {dims!r}")
    return values


RAW_DTYPES = {"uint8": np.dtype(np.uint8), "uint16": np.dtype(np.uint16), "float32": np.dtype(np.float32)}
"""Dtype names a raw file name or a ``dtype=`` string may use: exactly the supported dtypes' names.

An explicit table rather than numpy's parser, which accepts loose spellings (``u1``, ``f``,
``ubyte``) and reads ``u8`` as uint64 (8 *bytes*), not the uint8 a user writing it means.
"""

_DTYPE_HINTS = {"u8": "uint8", "u1": "uint8", "ubyte": "uint8", "uchar": "uint8", "b": "uint8", "byte": "uint8",
                "u16": "uint16", "u2": "uint16", "ushort": "uint16",
                "f32": "float32", "f4": "float32", "f": "float32", "float": "float32", "single": "float32"}


def _dtype(dtype, where):
    """The numpy dtype of a raw volume: a name of :data:`RAW_DTYPES` or a supported numpy dtype."""
    if isinstance(dtype, str):
        name = dtype.strip().lower()
        if name in RAW_DTYPES:
            return RAW_DTYPES[name]
        hint = f" (did you mean {_DTYPE_HINTS[name]!r}?)" if name in _DTYPE_HINTS else ""
        raise InputError(f"{where}: unknown dtype name {dtype!r}{hint}; use one of {', '.join(RAW_DTYPES)}")
    try:
        dt = np.dtype(dtype)
    except TypeError:
        raise InputError(f"{where}: unknown dtype {dtype!r}; use one of {', '.join(RAW_DTYPES)}") from None
    if dt.newbyteorder("=") not in SUPPORTED_DTYPES:
        raise InputError(f"{where}: dtype {dt.name} is not supported; use uint8, uint16 or float32")
    return dt.newbyteorder("=")


def _size_error(path, actual, dims, dtype, expected, extra=""):
    x, y, z = dims
    return InputError(f"{path}: file size {actual} bytes does not match {x}x{y}x{z} {dtype.name}{extra} "
                      f"= {expected} bytes")


def load_raw(path, *, dims=None, dtype=None, spacing=(1.0, 1.0, 1.0), value_range=None, name=None):
    """Read a headerless little-endian raw volume, x fastest.

    Parameters
    ----------
    path : str or Path
        ``<name>_<X>x<Y>x<Z>_<dtype>.raw`` gives the dimensions and dtype; otherwise pass them.
    dims : tuple of int, optional
        ``(nx, ny, nz)``. Must agree with the file name when both are given.
    dtype : str or numpy.dtype, optional
        ``"uint8"``, ``"uint16"`` or ``"float32"`` (:data:`RAW_DTYPES`; the file name uses the
        same names, no numpy shorthands such as ``u1`` or ``u8``). Must agree with the file name
        when both are given.
    spacing : tuple of float, optional
        ``(sx, sy, sz)``.
    value_range : tuple of float, optional
        Normalisation range when it is not the dtype's (e.g. ``(0, 4095)`` for 12-bit CT).
    name : str, optional
        Defaults to the file name's ``<name>`` part (or the stem).

    Returns
    -------
    Volume
    """
    path = _existing(path)
    match = RAW_NAME.match(path.name)
    if match:
        named_dims = (int(match["x"]), int(match["y"]), int(match["z"]))
        named_dtype = match["dtype"]
        _dtype(named_dtype, f"{path}: file name")  # a bad name is an error even when dtype= is given
        if dims is not None and _dims(dims, str(path)) != named_dims:
            raise InputError(f"{path}: dims={tuple(dims)} disagree with the file name's {named_dims}")
        if dtype is not None and _dtype(dtype, str(path)) != _dtype(named_dtype, str(path)):
            raise InputError(f"{path}: dtype={_dtype(dtype, str(path)).name} disagrees with the file name's {named_dtype}")
        dims = named_dims if dims is None else dims
        dtype = named_dtype if dtype is None else dtype
    if dims is None or dtype is None:
        raise InputError(f"{path}: the name does not follow <name>_<X>x<Y>x<Z>_<dtype>.raw; pass dims and dtype")
    dims = _dims(dims, str(path))
    dtype = _dtype(dtype, str(path))
    spacing = check_positive_vector(spacing, length=3, name=f"{path} spacing")
    expected = int(np.prod(dims)) * dtype.itemsize
    actual = path.stat().st_size
    if actual != expected:
        raise _size_error(path, actual, dims, dtype, expected)
    _check_fits(path, dims, dtype)
    x, y, z = dims
    data = np.fromfile(path, dtype=dtype.newbyteorder("<"), count=x * y * z).reshape(z, y, x)
    name = name or (match["stem"] if match else path.stem)
    return Volume(data.astype(dtype, copy=False), spacing=spacing, value_range=value_range, name=name,
                  meta={"path": str(path), "format": "raw"})


# ---------------------------------------------------------------------------------------------
# VolPack .den (examples/denfile.c)

DEN_FIELDS = "h3h3h3h3h3h3h3h3h3hhi"
"""``map_version``, then orig/extr/map ``min``, ``max``, ``len`` (3 shorts each), ``map_warps``,
``map_length``, packed in the writer's byte order; the densities (uint8) follow."""
DEN_HEADER_SIZE = struct.calcsize("<" + DEN_FIELDS)  # 62, as VolPack's BRAIN_HEADER


def load_den(path, *, spacing=(1.0, 1.0, 1.0), name=None):
    """Read a VolPack ``.den`` density file (the format of ``brainsmall.den``).

    The header is written field by field in the writing machine's byte order; the magic
    ``map_version`` (1) tells which. The densities are uint8, x fastest, ``map_len`` gives
    ``(nx, ny, nz)`` and ``map_length`` must equal their product.

    Parameters
    ----------
    path : str or Path
    spacing : tuple of float, optional
        The format stores none; VolPack renders the voxels as cubes.
    name : str, optional
        Defaults to the file stem.

    Returns
    -------
    Volume
        uint8; ``meta`` holds the header (original and extracted extents, warps).
    """
    path = _existing(path)
    actual = path.stat().st_size
    if actual < DEN_HEADER_SIZE:
        raise InputError(f"{path}: file is {actual} bytes, shorter than the {DEN_HEADER_SIZE}-byte .den header")
    with open(path, "rb") as f:
        raw = f.read(DEN_HEADER_SIZE)
    for order in "<>":
        fields = struct.unpack(order + DEN_FIELDS, raw)
        if fields[0] == 1:
            break
    else:
        magic = struct.unpack("<h", raw[:2])[0]
        raise InputError(f"{path}: not a VolPack .den file (map_version is {magic}, expected 1 in either byte order)")
    orig_min, orig_max, orig_len, extr_min, extr_max, extr_len, map_min, map_max, map_len = (
        tuple(fields[1 + 3 * i: 4 + 3 * i]) for i in range(9))
    warps, length = fields[28], fields[29]
    if min(map_len) < 1:
        raise InputError(f"{path}: .den header map_len {map_len} must be positive")
    if length != int(np.prod(map_len)):
        raise InputError(f"{path}: .den header is inconsistent: map_length {length} != "
                         f"{map_len[0]}x{map_len[1]}x{map_len[2]} = {int(np.prod(map_len))}")
    if actual != DEN_HEADER_SIZE + length:
        raise _size_error(path, actual, map_len, np.dtype(np.uint8), DEN_HEADER_SIZE + length,
                          extra=f" plus the {DEN_HEADER_SIZE}-byte header")
    x, y, z = map_len
    data = np.fromfile(path, dtype=np.uint8, count=length, offset=DEN_HEADER_SIZE).reshape(z, y, x)
    meta = {"path": str(path), "format": "den", "byte_order": "little" if order == "<" else "big",
            "orig_len": orig_len, "extr_min": extr_min, "extr_max": extr_max, "extr_len": extr_len,
            "map_warps": warps}
    return Volume(data, spacing=spacing, name=name or path.stem, meta=meta)


# ---------------------------------------------------------------------------------------------
# NRRD (http://teem.sourceforge.net/nrrd/format.html)

NRRD_TYPES = {
    **dict.fromkeys(("uchar", "unsigned char", "uint8", "uint8_t"), "u1"),
    **dict.fromkeys(("ushort", "unsigned short", "unsigned short int", "uint16", "uint16_t"), "u2"),
    **dict.fromkeys(("short", "short int", "signed short", "signed short int", "int16", "int16_t"), "i2"),
    "float": "f4",
}
"""NRRD type names read; ``int16`` is accepted when every value is non-negative (stored as uint16)."""

NRRD_ENCODINGS = {"raw": "raw", "gzip": "gzip", "gz": "gzip", "bzip2": "bzip2", "bz2": "bzip2",
                  "ascii": "ascii", "text": "ascii", "txt": "ascii"}


def _nrrd_header(path):
    """Parse the header: ``(fields, data_offset)``; field names lower-case."""
    fields = {}
    with open(path, "rb") as f:
        magic = f.readline()
        if not magic.startswith(b"NRRD000"):
            raise InputError(f"{path}: not a NRRD file (first line {magic[:20]!r}, expected NRRD000X)")
        while True:
            line = f.readline()
            if not line or not line.strip():
                break
            text = line.decode("latin-1").rstrip("\r\n")
            if text.startswith("#") or ":=" in text.split(": ", 1)[0]:
                continue
            if ": " not in text:
                raise InputError(f"{path}: malformed NRRD header line {text!r}")
            key, value = text.split(": ", 1)
            fields[key.strip().lower()] = value.strip()
        return fields, f.tell()


def _nrrd_spacing(fields, path):
    if "spacings" in fields:
        try:
            values = [float(v) for v in fields["spacings"].split()]
        except ValueError:
            raise InputError(f"{path}: cannot parse spacings {fields['spacings']!r}") from None
        return check_positive_vector(values, length=3, name=f"{path} spacings")
    if "space directions" in fields:
        vectors = re.findall(r"\(([^)]*)\)", fields["space directions"])
        if len(vectors) != 3:
            raise InputError(f"{path}: space directions must give three vectors, got {fields['space directions']!r}")
        try:
            norms = [float(np.linalg.norm([float(c) for c in v.split(",")])) for v in vectors]
        except ValueError:
            raise InputError(f"{path}: cannot parse space directions {fields['space directions']!r}") from None
        return check_positive_vector(norms, length=3, name=f"{path} space directions")
    return (1.0, 1.0, 1.0)


def load_nrrd(path, *, value_range=None, name=None):
    """Read a 3-D NRRD volume: attached (``.nrrd``) or detached (``.nhdr`` + data file) header.

    Supported: types uchar/ushort/float (and non-negative short), encodings raw, gzip, bzip2 and
    ascii, ``endian``, ``byte skip`` (``-1`` for raw: data at the end), ``line skip``, ``sizes``
    and the spacing from ``spacings`` or the lengths of ``space directions``. Orientation (the
    directions themselves, ``space origin``) is kept in ``meta`` but not applied.

    Parameters
    ----------
    path : str or Path
    value_range : tuple of float, optional
        Normalisation range when it is not the dtype's; float data outside [0, 1] needs one.
    name : str, optional
        Defaults to the file stem.

    Returns
    -------
    Volume
    """
    path = _existing(path)
    fields, header_end = _nrrd_header(path)
    for required in ("type", "dimension", "sizes", "encoding"):
        if required not in fields:
            raise InputError(f"{path}: NRRD header lacks the required field {required!r}")
    kind = NRRD_TYPES.get(fields["type"].lower())
    if kind is None:
        raise InputError(f"{path}: NRRD type {fields['type']!r} is not supported; use uchar, ushort, short or float")
    if fields["dimension"] != "3":
        raise InputError(f"{path}: NRRD dimension {fields['dimension']} is not supported; volumes are 3-D")
    try:
        dims = _dims(fields["sizes"].split(), str(path))
    except InputError:
        raise InputError(f"{path}: NRRD sizes {fields['sizes']!r} must be three positive integers") from None
    encoding = NRRD_ENCODINGS.get(fields["encoding"].lower())
    if encoding is None:
        raise InputError(f"{path}: NRRD encoding {fields['encoding']!r} is not supported; use raw, gzip, bzip2 or ascii")
    dtype = np.dtype(kind)
    if dtype.itemsize > 1 and encoding != "ascii":
        endian = fields.get("endian", "").lower()
        if endian not in ("little", "big"):
            raise InputError(f"{path}: NRRD endian must be 'little' or 'big' for {fields['type']} data, got {endian or 'none'!r}")
        dtype = dtype.newbyteorder("<" if endian == "little" else ">")
    spacing = _nrrd_spacing(fields, path)
    try:
        byte_skip = int(fields.get("byte skip", 0))
        line_skip = int(fields.get("line skip", 0))
    except ValueError:
        raise InputError(f"{path}: NRRD byte skip / line skip must be integers") from None
    if byte_skip < -1 or line_skip < 0 or (byte_skip == -1 and encoding != "raw"):
        raise InputError(f"{path}: NRRD byte skip {byte_skip} / line skip {line_skip} out of range")

    data_file = fields.get("data file", fields.get("datafile"))
    if data_file is None:
        if path.suffix.lower() == ".nhdr":
            raise InputError(f"{path}: a detached header (.nhdr) needs a 'data file' field")
        source, offset = path, header_end
    else:
        if data_file.split()[0] == "LIST" or "%" in data_file:
            raise InputError(f"{path}: NRRD multi-file data ({data_file!r}) is not supported")
        source = Path(data_file) if Path(data_file).is_absolute() else path.parent / data_file
        if not source.is_file():
            raise InputError(f"{path}: data file {source} does not exist")
        offset = 0
    count = int(np.prod(dims))
    expected = count * dtype.itemsize
    # Before reading: a compressed payload is inflated whole, whatever its header claims.
    _check_fits(path, dims, dtype)
    with open(source, "rb") as f:
        f.seek(offset)
        for _ in range(line_skip):
            f.readline()
        offset = f.tell()
        if encoding == "raw":
            available = source.stat().st_size - offset
            if byte_skip == -1:
                if available < expected:
                    raise _size_error(source, available, dims, dtype, expected, extra=" (data at the end)")
                offset += available - expected
            elif available - byte_skip != expected:
                raise _size_error(source, available - byte_skip, dims, dtype, expected,
                                  extra=f" after the header{' and byte skip' if byte_skip else ''}")
            else:
                offset += byte_skip
            values = np.fromfile(source, dtype=dtype, count=count, offset=offset)
        else:
            payload = f.read()
            if encoding in ("gzip", "bzip2"):
                try:
                    payload = gzip.decompress(payload) if encoding == "gzip" else bz2.decompress(payload)
                except (OSError, EOFError, ValueError) as exc:
                    raise InputError(f"{source}: cannot decompress the {encoding} data: {exc}") from None
                payload = payload[byte_skip:]
                if len(payload) != expected:
                    raise _size_error(source, len(payload), dims, dtype, expected, extra=f" ({encoding}, decompressed)")
                values = np.frombuffer(payload, dtype=dtype)
            else:
                try:
                    values = np.array(payload.split(), dtype=np.float64)
                except ValueError:
                    raise InputError(f"{source}: ascii NRRD data holds something that is not a number") from None
                if values.size != count:
                    raise InputError(f"{source}: ascii NRRD data has {values.size} values, sizes need {count}")
    native = dtype.newbyteorder("=")
    if native.kind == "i":
        if values.min() < 0:
            raise InputError(f"{path}: signed NRRD data has negative values; volbench reads unsigned or float volumes")
        native = np.dtype(np.uint16)
    x, y, z = dims
    data = np.ascontiguousarray(values.reshape(z, y, x).astype(native))
    meta = {"path": str(path), "format": "nrrd", "encoding": encoding,
            **{key: fields[key] for key in ("space", "space directions", "space origin", "content") if key in fields}}
    return Volume(data, spacing=spacing, value_range=value_range, name=name or path.name.split(".")[0], meta=meta)
