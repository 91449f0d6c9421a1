"""Volume file readers: raw, VolPack .den and NRRD (written here independently and read back)."""

import bz2
import gzip
import struct

import numpy as np
import pytest

from datasets import load_den, load_nrrd, load_raw
from core.errors import InputError

RNG = np.random.default_rng(7)
DATA8 = RNG.integers(0, 256, (4, 3, 5), dtype=np.uint8)           # (z, y, x): 5 x 3 x 4
DATA16 = RNG.integers(0, 4096, (4, 3, 5), dtype=np.uint16)


# ------------------------------------------------------------------------------------- raw
@pytest.mark.parametrize("data", [DATA8, DATA16, RNG.random((4, 3, 5), dtype=np.float32)])
def test_raw_round_trip_from_the_file_name(tmp_path, data):
    path = tmp_path / f"thing_5x3x4_{data.dtype.name}.raw"
    data.astype(data.dtype.newbyteorder("<")).tofile(path)
    volume = load_raw(path, spacing=(1, 2, 3))
    np.testing.assert_array_equal(volume.data, data)
    assert volume.data.dtype == data.dtype and volume.name == "thing" and volume.spacing == (1.0, 2.0, 3.0)


def test_raw_with_explicit_dims_and_range(tmp_path):
    path = tmp_path / "scan.bin"
    DATA16.astype("<u2").tofile(path)
    volume = load_raw(path, dims=(5, 3, 4), dtype="uint16", value_range=(0, 4095))
    np.testing.assert_array_equal(volume.data, DATA16)
    assert volume.value_range == (0.0, 4095.0) and volume.name == "scan"


def test_raw_size_mismatch_names_the_file_and_the_numbers(tmp_path):
    path = tmp_path / "short_10x10x11_uint8.raw"
    path.write_bytes(bytes(1000))
    with pytest.raises(InputError) as info:
        load_raw(path)
    message = str(info.value)
    assert str(path) in message
    assert "file size 1000 bytes does not match 10x10x11 uint8 = 1100 bytes" in message


@pytest.mark.parametrize("name, kwargs, match", [
    ("a_5x3x4_uint8.raw", {"dims": (4, 3, 5)}, "disagree"),
    ("a_5x3x4_uint8.raw", {"dtype": "uint16"}, "disagrees"),
    ("plain.raw", {}, "pass dims and dtype"),
    ("a_5x3x4_int8.raw", {}, "unknown dtype name 'int8'; use one of uint8, uint16, float32"),
    ("plain.raw", {"dims": (5, 3), "dtype": "uint8"}, "three positive integers"),
])
def test_raw_bad_requests(tmp_path, name, kwargs, match):
    path = tmp_path / name
    path.write_bytes(bytes(60))
    with pytest.raises(InputError, match=match) as info:
        load_raw(path, **kwargs)
    assert str(path) in str(info.value)


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_raw(tmp_path / "x_1x1x1_uint8.raw")


# ------------------------------------------------------------------------------------- .den
def write_den(path, data, *, order="<", length=None, version=1):
    """VolPack's write_den (examples/denfile.c): 62-byte header, then uint8 densities."""
    z, y, x = data.shape
    dims = (x, y, z)
    zeros, maxes = (0, 0, 0), tuple(d - 1 for d in dims)
    header = struct.pack(order + "h" + "3h" * 9 + "hi", version, *zeros, *maxes, *dims, *zeros, *maxes, *dims,
                         *zeros, *maxes, *dims, 0, x * y * z if length is None else length)
    path.write_bytes(header + data.tobytes())


@pytest.mark.parametrize("order", ["<", ">"])
def test_den_round_trip_in_either_byte_order(tmp_path, order):
    path = tmp_path / "brain.den"
    write_den(path, DATA8, order=order)
    volume = load_den(path)
    np.testing.assert_array_equal(volume.data, DATA8)
    assert volume.name == "brain" and volume.meta["byte_order"] == ("little" if order == "<" else "big")


@pytest.mark.parametrize("kwargs, trim, match", [
    ({"version": 7}, 0, "not a VolPack .den file"),
    ({"length": 59}, 0, "inconsistent"),
    ({}, 1, "does not match 5x3x4 uint8 plus the 62-byte header = 122 bytes"),
])
def test_den_bad_headers(tmp_path, kwargs, trim, match):
    path = tmp_path / "bad.den"
    write_den(path, DATA8, **kwargs)
    path.write_bytes(path.read_bytes()[:len(path.read_bytes()) - trim])
    with pytest.raises(InputError, match=match) as info:
        load_den(path)
    assert str(path) in str(info.value)


def test_den_shorter_than_its_header(tmp_path):
    path = tmp_path / "tiny.den"
    path.write_bytes(b"\x01\x00")
    with pytest.raises(InputError, match="shorter than the 62-byte"):
        load_den(path)


# ------------------------------------------------------------------------------------- NRRD
def nrrd_header(fields):
    return ("NRRD0004\n# written by the test\n" + "".join(f"{k}: {v}\n" for k, v in fields.items())).encode()


def test_nrrd_attached_raw_with_spacings(tmp_path):
    path = tmp_path / "vol.nrrd"
    fields = {"type": "uchar", "dimension": 3, "sizes": "5 3 4", "encoding": "raw", "spacings": "0.5 1 2"}
    path.write_bytes(nrrd_header(fields) + b"key:=value\n\n" + DATA8.tobytes())
    volume = load_nrrd(path)
    np.testing.assert_array_equal(volume.data, DATA8)
    assert volume.spacing == (0.5, 1.0, 2.0) and volume.name == "vol"


def test_nrrd_gzip_big_endian_with_space_directions(tmp_path):
    path = tmp_path / "vol.nrrd"
    fields = {"type": "unsigned short", "dimension": 3, "space": "left-posterior-superior", "sizes": "5 3 4",
              "space directions": "(0,0.7,0) (1.5,0,0) (0,0,2)", "endian": "big", "encoding": "gzip"}
    path.write_bytes(nrrd_header(fields) + b"\n" + gzip.compress(DATA16.astype(">u2").tobytes()))
    volume = load_nrrd(path)
    np.testing.assert_array_equal(volume.data, DATA16)
    assert volume.data.dtype == np.uint16 and volume.spacing == pytest.approx((0.7, 1.5, 2.0))
    assert volume.meta["space"] == "left-posterior-superior"


def test_nrrd_detached_header_with_line_and_byte_skip(tmp_path):
    (tmp_path / "vol.raw").write_bytes(b"a header line\n" + b"XY" + DATA8.tobytes())
    header = tmp_path / "vol.nhdr"
    header.write_bytes(nrrd_header({"type": "uint8", "dimension": 3, "sizes": "5 3 4", "encoding": "raw",
                                    "line skip": 1, "byte skip": 2, "data file": "vol.raw"}))
    np.testing.assert_array_equal(load_nrrd(header).data, DATA8)


def test_nrrd_bzip2_ascii_short_and_data_at_the_end(tmp_path):
    base = {"dimension": 3, "sizes": "5 3 4"}
    bz = tmp_path / "b.nrrd"
    bz.write_bytes(nrrd_header({**base, "type": "float", "endian": "little", "encoding": "bzip2"}) + b"\n"
                   + bz2.compress((DATA8 / 255).astype("<f4").tobytes()))
    np.testing.assert_allclose(load_nrrd(bz).data, DATA8 / 255, rtol=1e-6)
    text = tmp_path / "t.nrrd"
    text.write_bytes(nrrd_header({**base, "type": "uchar", "encoding": "ascii"}) + b"\n"
                     + " ".join(map(str, DATA8.ravel())).encode())
    np.testing.assert_array_equal(load_nrrd(text).data, DATA8)
    short = tmp_path / "s.nrrd"
    short.write_bytes(nrrd_header({**base, "type": "short", "endian": "little", "encoding": "raw", "byte skip": -1})
                      + b"\n" + b"junk" + DATA16.astype("<i2").tobytes())
    volume = load_nrrd(short)
    assert volume.data.dtype == np.uint16
    np.testing.assert_array_equal(volume.data, DATA16)


@pytest.mark.parametrize("fields, payload, match", [
    ({"type": "uchar", "dimension": 3, "encoding": "raw"}, DATA8.tobytes(), "required field 'sizes'"),
    ({"type": "double", "dimension": 3, "sizes": "5 3 4", "encoding": "raw"}, b"", "type 'double'"),
    ({"type": "uchar", "dimension": 2, "sizes": "5 3", "encoding": "raw"}, b"", "dimension 2"),
    ({"type": "ushort", "dimension": 3, "sizes": "5 3 4", "encoding": "raw"}, DATA16.tobytes(), "endian"),
    ({"type": "uchar", "dimension": 3, "sizes": "5 3 4", "encoding": "raw"}, DATA8.tobytes()[:-3],
     "file size 57 bytes does not match 5x3x4 uint8"),
    ({"type": "uchar", "dimension": 3, "sizes": "5 3 4", "encoding": "gzip"}, gzip.compress(DATA8.tobytes()[:-1], mtime=0),
     "59 bytes does not match"),
    ({"type": "uchar", "dimension": 3, "sizes": "5 3 4", "encoding": "gzip"}, b"not gzip", "cannot decompress"),
    ({"type": "short", "dimension": 3, "sizes": "5 3 4", "encoding": "raw", "endian": "little"},
     (-DATA16.astype("<i2")).tobytes(), "negative"),
    ({"type": "uchar", "dimension": 3, "sizes": "5 3 x", "encoding": "raw"}, b"", "sizes"),
])
def test_nrrd_bad_headers_name_the_file(tmp_path, fields, payload, match):
    path = tmp_path / "bad.nrrd"
    path.write_bytes(nrrd_header(fields) + b"\n" + payload)
    with pytest.raises(InputError, match=match) as info:
        load_nrrd(path)
    assert str(path) in str(info.value)


def test_nrrd_magic_and_detached_data_file_are_checked(tmp_path):
    path = tmp_path / "x.nrrd"
    path.write_bytes(b"P5 not a nrrd\n")
    with pytest.raises(InputError, match="not a NRRD file"):
        load_nrrd(path)
    header = tmp_path / "y.nhdr"
    header.write_bytes(nrrd_header({"type": "uchar", "dimension": 3, "sizes": "5 3 4", "encoding": "raw",
                                    "data file": "missing.raw"}))
    with pytest.raises(InputError, match="missing.raw does not exist"):
        load_nrrd(header)


def test_oversized_raw_file_is_refused(tmp_path):
    path = tmp_path / "big_5x3x4_uint8.raw"
    path.write_bytes(DATA8.tobytes() + b"\0")
    with pytest.raises(InputError, match="file size 61 bytes does not match 5x3x4 uint8 = 60 bytes"):
        load_raw(path)
    path.write_bytes(DATA8.tobytes() + bytes(60))  # twice the size: a 16-bit file named 8-bit
    with pytest.raises(InputError, match="120 bytes does not match"):
        load_raw(path)
    with pytest.raises(InputError, match="121 bytes does not match"):
        (tmp_path / "c.raw").write_bytes(bytes(121))
        load_raw(tmp_path / "c.raw", dims=(5, 3, 4), dtype="uint16")


@pytest.mark.parametrize("name, dtype", [("uint8", np.uint8), ("uint16", np.uint16), ("float32", np.float32)])
def test_raw_dtype_names_are_the_documented_ones(tmp_path, name, dtype):
    data = DATA8.astype(dtype) if dtype != np.float32 else (DATA8 / 255).astype(np.float32)
    path = tmp_path / f"v_5x3x4_{name}.raw"
    data.astype(data.dtype.newbyteorder("<")).tofile(path)
    assert load_raw(path).data.dtype == dtype
    assert load_raw(path, dtype=name).data.dtype == dtype
    assert load_raw(path, dtype=np.dtype(dtype)).data.dtype == dtype


@pytest.mark.parametrize("name, hint", [
    ("u8", "did you mean 'uint8'"), ("u1", "did you mean 'uint8'"), ("ubyte", "did you mean 'uint8'"),
    ("f", "did you mean 'float32'"), ("f4", "did you mean 'float32'"), ("u16", "did you mean 'uint16'"),
    ("int16", "use one of uint8, uint16, float32"), ("float64", "use one of uint8, uint16, float32"),
    ("uint64", "use one of"), ("b1", "use one of"),
])
def test_loose_dtype_names_are_refused_clearly(tmp_path, name, hint):
    path = tmp_path / f"v_5x3x4_{name}.raw"
    path.write_bytes(DATA8.tobytes())
    with pytest.raises(InputError, match=f"unknown dtype name '{name}'.*{hint}") as error:
        load_raw(path)
    if name == "u8":
        assert "uint64" not in str(error.value)  # numpy would read u8 as 8 bytes
    with pytest.raises(InputError, match=f"unknown dtype name '{name}'"):
        load_raw(path, dtype="uint8")  # a bad name is an error even with an explicit dtype
    (tmp_path / "plain.raw").write_bytes(DATA8.tobytes())
    with pytest.raises(InputError, match=f"unknown dtype name '{name}'"):
        load_raw(tmp_path / "plain.raw", dims=(5, 3, 4), dtype=name)


def test_a_folder_is_not_a_volume_file(tmp_path):
    (tmp_path / "v_2x2x2_uint8.raw").mkdir()
    with pytest.raises(InputError, match="v_2x2x2_uint8.raw: is a folder, not a volume file"):
        load_raw(tmp_path / "v_2x2x2_uint8.raw")


def test_a_volume_this_machine_cannot_hold_is_refused_before_it_is_read(tmp_path, monkeypatch):
    import core.resources

    np.zeros(32 ** 3, np.uint16).tofile(tmp_path / "v_32x32x32_uint16.raw")
    monkeypatch.setattr(core.resources, "memory_limit", lambda: 100 * 2 ** 10)
    monkeypatch.setattr(np, "fromfile", lambda *a, **k: pytest.fail("the file was read before the check"))
    with pytest.raises(InputError, match=r"v_32x32x32_uint16.raw: a 32×32×32 uint16 volume needs 128 KiB \(its values "
                                         r"and one converted copy\), this machine has 100 KiB"):
        load_raw(tmp_path / "v_32x32x32_uint16.raw")
    header = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4096 4096 4096\nencoding: gzip\n\n"
    (tmp_path / "bomb.nrrd").write_bytes(header.encode() + gzip.compress(b""))
    with pytest.raises(InputError, match=r"bomb.nrrd: a 4096×4096×4096 uint8 volume needs 128 GiB"):
        load_nrrd(tmp_path / "bomb.nrrd")
