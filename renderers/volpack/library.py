"""ctypes binding to the VolPack C library (Debian ``libvolpack1``), no compiled extension.

Only what the backend uses is declared. Constants are those of ``/usr/include/volpack.h``
(VolPack 1.0b3, header revision 1.27). Every call that returns a ``vpResult`` goes through
:meth:`VolPack.check`, which turns a non-zero code into :class:`VolPackError` with VolPack's own
message (``vpGetErrorString``) and the name of the call.
"""

import ctypes
import ctypes.util
import subprocess

LIBRARY_NAMES = ("libvolpack.so.1", "libvolpack.so")
INSTALL_HINT = "apt-get install libvolpack1 (Debian/Ubuntu; libvolpack1-dev adds the header and the brainsmall example)"

# volpack.h constants --------------------------------------------------------------------------
VP_OK = 0
HEADER_VERSION = "1.1"  # VP_VERSION in volpack.h (the Debian package is 1.0b3)
VP_MAX_VOLUME_DIM = 1024
VP_XLEN, VP_YLEN, VP_ZLEN = 1000, 1001, 1002
VP_MIN_VOXEL_OPACITY = 1014
VP_CONCAT_MODE = 1038
VP_MAX_RAY_OPACITY = 1043
VP_VIEW_AXIS = 1044
VP_INTERMEDIATE_WIDTH = 1045
VP_INTERMEDIATE_HEIGHT = 1046
VP_VIEW_X_SIZE, VP_VIEW_Y_SIZE, VP_VIEW_Z_SIZE = 1053, 1054, 1055
VP_MMOCTREE_SIZE = 1057
VP_LIGHT_BOTH_SIDES = 1029
VP_DEPTH_CUE = 1031
VP_CLAMP_SHADE_TABLE = 1078
VP_LIGHT0 = 2000
VP_COLOR, VP_DIRECTION = 2100, 2101
VP_MATERIAL0 = 2200
VP_AMBIENT, VP_DIFFUSE, VP_SPECULAR, VP_SHINYNESS = 2300, 2301, 2302, 2303
VP_BOTH_SIDES = 3
VP_MODEL, VP_VIEW, VP_PROJECT = 0, 1, 2
VP_CONCAT_RIGHT, VP_CONCAT_LEFT = 2600, 2601
VP_RGBA = 5004
VP_NORM_MAX = 7923
VP_SCALAR_MAX = 255
VP_GRAD_MAX = 221
VP_MAX_MATERIAL = 6

VPTIMER_NAMES = ("shade", "composite", "depthcue", "warp", "traverse_runs", "process_voxels", "ert",
                 "classify_octree", "traverse_octree", "render", "clear")
"""``VPTIMER_*`` codes 0..10 in order (volpack.h)."""


class VolPackError(RuntimeError):
    """A VolPack call returned an error code."""


class VolPackUnavailable(RuntimeError):
    """The shared library cannot be loaded."""


_LIB = None


def _declare(lib):
    p, i, d, u8p, fp = ctypes.c_void_p, ctypes.c_int, ctypes.c_double, ctypes.c_void_p, ctypes.c_void_p
    signatures = {
        "vpCreateContext": (p, []),
        "vpDestroyContext": (None, [p]),
        "vpSetVolumeSize": (ctypes.c_uint, [p, i, i, i]),
        "vpSetVoxelSize": (ctypes.c_uint, [p, i, i, i, i]),
        "vpSetVoxelField": (ctypes.c_uint, [p, i, i, i, i]),
        "vpSetRawVoxels": (ctypes.c_uint, [p, p, i, i, i, i]),
        "vpVolumeNormals": (ctypes.c_uint, [p, u8p, i, i, i, i]),
        "vpSetClassifierTable": (ctypes.c_uint, [p, i, i, fp, i]),
        "vpClassifyVolume": (ctypes.c_uint, [p]),
        "vpDestroyClassifiedVolume": (ctypes.c_uint, [p]),
        "vpMinMaxOctreeThreshold": (ctypes.c_uint, [p, i, i]),
        "vpCreateMinMaxOctree": (ctypes.c_uint, [p, i, i]),
        "vpDestroyMinMaxOctree": (ctypes.c_uint, [p]),
        "vpSetLookupShader": (ctypes.c_uint, [p, i, i, i, fp, i, i, fp, i]),
        "vpSetMaterial": (ctypes.c_uint, [p, i, i, i, d, d, d]),
        "vpSetLight": (ctypes.c_uint, [p, i, i, d, d, d]),
        "vpShadeTable": (ctypes.c_uint, [p]),
        "vpCurrentMatrix": (ctypes.c_uint, [p, i]),
        "vpIdentityMatrix": (ctypes.c_uint, [p]),
        "vpSetMatrix": (ctypes.c_uint, [p, p]),
        "vpGetMatrix": (ctypes.c_uint, [p, i, p]),
        "vpSetImage": (ctypes.c_uint, [p, p, i, i, i, i]),
        "vpEnable": (ctypes.c_uint, [p, i, i]),
        "vpSeti": (ctypes.c_uint, [p, i, i]),
        "vpSetd": (ctypes.c_uint, [p, i, d]),
        "vpGeti": (ctypes.c_uint, [p, i, ctypes.POINTER(ctypes.c_int)]),
        "vpGetd": (ctypes.c_uint, [p, i, ctypes.POINTER(ctypes.c_double)]),
        "vpGetTimer": (ctypes.c_uint, [p, i, ctypes.POINTER(ctypes.c_int)]),
        "vpClearTimer": (ctypes.c_uint, [p, i]),
        "vpRenderClassifiedVolume": (ctypes.c_uint, [p]),
        "vpRenderRawVolume": (ctypes.c_uint, [p]),
        "vpGetError": (ctypes.c_uint, [p]),
        "vpGetErrorString": (ctypes.c_char_p, [ctypes.c_uint]),
    }
    for name, (restype, argtypes) in signatures.items():
        function = getattr(lib, name)
        function.restype = restype
        function.argtypes = argtypes
    return lib


def load():
    """The loaded library (cached); raises :class:`VolPackUnavailable` with the install hint."""
    global _LIB
    if _LIB is not None:
        return _LIB
    errors = []
    candidates = list(LIBRARY_NAMES)
    found = ctypes.util.find_library("volpack")
    if found and found not in candidates:
        candidates.append(found)
    for name in candidates:
        try:
            lib = ctypes.CDLL(name)
        except OSError as exc:
            errors.append(f"{name}: {exc}")
            continue
        try:
            _LIB = _declare(lib)
        except AttributeError as exc:
            errors.append(f"{name}: missing symbol ({exc})")
            continue
        return _LIB
    raise VolPackUnavailable(f"the VolPack shared library cannot be loaded ({'; '.join(errors)}); "
                             f"install it with: {INSTALL_HINT}")


def package_version():
    """The Debian package version of libvolpack1 (``None`` where dpkg does not know it)."""
    try:
        out = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "libvolpack1"],
                             capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() or None if out.returncode == 0 else None


def library_path():
    """Path of the loaded shared object (from /proc/self/maps; ``None`` if not found)."""
    load()
    try:
        with open("/proc/self/maps") as maps:
            for line in maps:
                if "libvolpack" in line:
                    return line.split()[-1]
    except OSError:
        pass
    return None


class Context:
    """One ``vpContext``, destroyed with :meth:`close` (or when garbage-collected).

    Arrays handed to VolPack (raw voxels, classifier, shading and weight tables, the image) are
    referenced from ``self.keep`` so that they outlive every call that may read them: VolPack
    stores the pointers, not copies.
    """

    def __init__(self):
        self.lib = load()
        self.handle = self.lib.vpCreateContext()
        if not self.handle:
            raise VolPackError("vpCreateContext returned NULL (out of memory?)")
        self.keep = {}

    def check(self, code, call):
        if code != VP_OK:
            message = self.lib.vpGetErrorString(code)
            text = message.decode() if message else "unknown error"
            raise VolPackError(f"VolPack {call} failed: {text} (code {code})")

    def call(self, name, *args):
        """Call ``vpName(vpc, *args)`` and raise on an error code."""
        self.check(getattr(self.lib, name)(self.handle, *args), name)

    def geti(self, option):
        value = ctypes.c_int()
        self.call("vpGeti", option, ctypes.byref(value))
        return value.value

    def getd(self, option):
        value = ctypes.c_double()
        self.call("vpGetd", option, ctypes.byref(value))
        return value.value

    def timer_us(self, code):
        value = ctypes.c_int()
        self.call("vpGetTimer", code, ctypes.byref(value))
        return value.value

    def set_matrix(self, which, matrix):
        import numpy as np

        m = np.ascontiguousarray(matrix, dtype=np.float64)
        self.call("vpCurrentMatrix", which)
        self.call("vpSetMatrix", m.ctypes.data)

    def close(self):
        if self.handle:
            self.lib.vpDestroyContext(self.handle)
            self.handle = None
        self.keep.clear()

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass
