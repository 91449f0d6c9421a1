"""The OpenCL device, context and queue of a process, chosen once per device selector.

Every OpenCL backend runs through :func:`shared`. A device is chosen by a *selector*: the
backend's ``device`` option, else the environment variable :data:`DEVICE_VARIABLE`, else ``""``
(volbench chooses). A selector is ``"<platform>:<device>"`` (indices, as ``clinfo -l`` lists
them), which names one device, or a case-insensitive substring of ``"<platform name> <platform
version> <device name>"`` (``"nvidia"``, ``"pocl 3.1"``), which names every device it matches.

Why a device must *build* before it is chosen
---------------------------------------------
An OpenCL device that makes a context can still be unable to compile a kernel. PyPI's PoCL
(``pocl-binary-distribution`` 3.0: PoCL 3.0-rc2 on LLVM 14) hands LLVM the CPU name that LLVM's
own host detection gives; a CPU newer than that LLVM (AMD Zen 5, for one) comes out as
``'generic'``, which LLVM 14 then rejects, so every build fails with ``unknown target CPU
'generic'`` although the context was fine. Debian's PoCL (``pocl-opencl-icd``, installed by
``make setup``) picks one of the kernel libraries it ships (sse2 up to avx512) by the CPU's
feature flags and gives LLVM that library's CPU name, so it builds on any x86-64 CPU, newer
than its LLVM or not. Both can be installed side by side (pyopencl's ICD loader lists both).

So the probe tries the candidate devices in order and, on each, creates a context and builds
:data:`PROBE_KERNEL`; the first device whose compiler builds it is chosen, and every device
refused on the way is remembered with the compiler's own message (:func:`compiler_message`).
The order is GPUs first, then accelerators, then CPUs (and any other kind), each kind in
platform order and, within a platform, in device order (:func:`candidates`): a GPU is what an
OpenCL renderer is written for, and a CPU device is the fallback that runs anywhere.

A selector limits the candidates to the devices it names and is never replaced by another
device: if none of them builds, the backend is unavailable with their compilers' messages.
With no device that builds, :func:`probe` answers ``(False, reason)``: the reason quotes each
refused device's compiler message with its platform's PoCL and LLVM versions and says what to
do. :func:`environment` records the device chosen, its platform's versions and the devices
refused.

Caching
-------
Creating a context and compiling programs cost seconds on PoCL, so each selector's device (or
the reason there is none), its profiling queue and every program built for it (:func:`kernels`,
keyed by source text and build options) are kept for the life of the process. A process forked
after a context was made (the pipeline renders in child processes) probes again, since OpenCL
objects do not survive a fork.
"""

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from core.errors import BackendUnavailableError, InputError
from renderers.base import compilation

DEVICE_VARIABLE = "VOLBENCH_CL_DEVICE"
"""Environment variable naming the OpenCL device when the backend's ``device`` option is unset."""

KERNEL_DIR = Path(__file__).resolve().parent / "kernels"

PROBE_KERNEL = """
__kernel void volbench_probe(__global float *values, __global uint *count) {
    size_t i = get_global_id(0);
    values[i] = sqrt(values[i]) * 0.5f;
    atomic_inc(count);
}
"""
"""What a device's compiler must build before the device is chosen (see the module notes): float
arithmetic and a 32-bit global atomic, as the backend's kernels use."""

DEBIAN_POCL_HINT = "install Debian's pocl-opencl-icd (`make setup` does), whose PoCL builds kernels on any x86-64 CPU"
INSTALL_HINT = f"{DEBIAN_POCL_HINT}, or name a device that builds them with {DEVICE_VARIABLE}"
"""What to do when no device builds (the end of the probe's reason)."""

KIND_ORDER = ("GPU", "ACCELERATOR", "CPU")
"""Device kinds in the order they are tried; any other kind comes after these."""

MESSAGE_LINES = 2
"""Lines of a compiler's build log quoted in a refusal (its error lines first)."""


@dataclass(frozen=True)
class Candidate:
    """One OpenCL device as enumerated: its indices, kind, and pyopencl platform and device."""

    platform_index: int
    device_index: int
    kind: str
    platform: object
    device: object

    @property
    def index(self):
        """``"<platform>:<device>"``, the selector that names exactly this device."""
        return f"{self.platform_index}:{self.device_index}"

    @property
    def label(self):
        """``"<platform name> <platform version> <device name>"``, what a substring selector is matched against."""
        return f"{self.platform.name.strip()} {self.platform.version.strip()} {self.device.name.strip()}"

    def describe(self):
        """``"1:0 pthread-AMD EPYC (Portable Computing Language: PoCL 3.0-rc2, LLVM 14.0.6)"``."""
        versions = platform_versions(self.platform.version)
        found = [f"{name} {value}" for name, value in (("PoCL", versions["pocl"]), ("LLVM", versions["llvm"]))
                 if value]
        detail = ", ".join(found) or self.platform.version.strip()
        return f"{self.index} {self.device.name.strip()} ({self.platform.name.strip()}: {detail})"


@dataclass
class Device:
    """The chosen device with its context, profiling queue, compiled programs and the devices refused."""

    platform: object
    device: object
    context: object
    queue: object
    index: str = ""
    refused: tuple = ()
    programs: dict = field(default_factory=dict)


class Refused(Exception):
    """A candidate device cannot be used; the message is its compiler's (or driver's) own."""


_STATE = {"pid": None, "devices": {}, "errors": {}}


def platform_versions(version):
    """``{"pocl": ..., "llvm": ...}`` parsed from a platform version string (``None`` where absent).

    PoCL's reads e.g. ``"OpenCL 3.0 PoCL 3.1+debian  Linux, None+Asserts, RELOC, SPIR, LLVM 15.0.6, SLEEF"``.
    """
    pocl = re.search(r"\bPoCL (\S+)", version, re.IGNORECASE)
    llvm = re.search(r"\bLLVM (\d+(?:\.\d+)*)", version)
    return {"pocl": pocl.group(1) if pocl else None, "llvm": llvm.group(1) if llvm else None}


def compiler_message(log, error):
    """The first useful lines of a build ``log`` (error lines first), else the first line of ``error``."""
    lines = [line.strip() for line in (log or "").splitlines() if line.strip()]
    errors = [line for line in lines if "error" in line.lower()]
    quoted = (errors or lines)[:MESSAGE_LINES]
    if not quoted:
        quoted = [next((line.strip() for line in str(error).splitlines() if line.strip()), type(error).__name__)]
    return " / ".join(quoted)


def device_kind(cl, device):
    """``"GPU"``, ``"ACCELERATOR"``, ``"CPU"`` (the first of these the device's type has), else ``"OTHER"``."""
    return next((kind for kind in KIND_ORDER if device.type & getattr(cl.device_type, kind)), "OTHER")


def enumerate_devices(cl):
    """Every device of every platform, as :class:`Candidate` in enumeration order.

    Raises
    ------
    BackendUnavailableError
        No OpenCL platform (no ICD installed) or no device on any.
    """
    try:
        platforms = cl.get_platforms()
    except cl.Error as exc:  # no ICD at all: the loader reports PLATFORM_NOT_FOUND_KHR
        raise BackendUnavailableError(f"no OpenCL platform ({compiler_message('', exc)}); {DEBIAN_POCL_HINT}") from exc
    found = []
    for p_index, platform in enumerate(platforms):
        try:
            devices = platform.get_devices()
        except cl.Error:  # a platform without devices raises CL_DEVICE_NOT_FOUND
            continue
        found.extend(Candidate(p_index, d_index, device_kind(cl, device), platform, device)
                     for d_index, device in enumerate(devices))
    if not found:
        raise BackendUnavailableError(f"no OpenCL platform has a device; {DEBIAN_POCL_HINT}")
    return found


def candidates(found, selector):
    """The devices to try for ``selector``, in the order they are tried (see the module notes).

    Raises
    ------
    InputError
        The selector names no device; the message lists those available.
    """
    ordered = sorted(found, key=lambda c: (KIND_ORDER.index(c.kind) if c.kind in KIND_ORDER else len(KIND_ORDER),
                                           c.platform_index, c.device_index))
    if not selector:
        return ordered
    listing = "; ".join(f"{c.describe()} {c.kind}" for c in found)
    head, _, tail = selector.partition(":")
    if head.isdigit() and tail.isdigit():
        named = [c for c in ordered if (c.platform_index, c.device_index) == (int(head), int(tail))]
        if not named:
            raise InputError(f"OpenCL device {selector!r}: no such platform:device index; available: {listing}")
        return named
    named = [c for c in ordered if selector.lower() in c.label.lower()]
    if not named:
        raise InputError(f"OpenCL device {selector!r}: matches no device; available: {listing}")
    return named


def open_device(cl, candidate):
    """A :class:`Device` on ``candidate`` once its compiler has built :data:`PROBE_KERNEL`.

    Raises
    ------
    Refused
        The context could not be made or the build failed; the message is the driver's or the
        compiler's (:func:`compiler_message`).
    """
    try:
        context = cl.Context([candidate.device])
    except cl.Error as exc:
        raise Refused(f"no context: {compiler_message('', exc)}") from exc
    program = cl.Program(context, PROBE_KERNEL)
    try:
        program.build()
    except cl.Error as exc:
        raise Refused(compiler_message(program.get_build_info(candidate.device, cl.program_build_info.LOG),
                                       exc)) from exc
    queue = cl.CommandQueue(context, candidate.device, properties=cl.command_queue_properties.PROFILING_ENABLE)
    return Device(platform=candidate.platform, device=candidate.device, context=context, queue=queue,
                  index=candidate.index)


def choose(cl, selector):
    """The first device of :func:`candidates` that builds, with the ones refused before it.

    Raises
    ------
    InputError
        The selector names no device.
    BackendUnavailableError
        No candidate builds; the message quotes each one's compiler and says what to do.
    """
    refused = []
    for candidate in candidates(enumerate_devices(cl), selector):
        try:
            entry = open_device(cl, candidate)
        except Refused as exc:
            refused.append(f"{candidate.describe()}: {exc}")
            continue
        entry.refused = tuple(refused)
        return entry
    if selector:
        raise BackendUnavailableError(f"OpenCL device selector {selector!r}: no device it names builds a kernel: "
                                      f"{'; '.join(refused)}; name another device or unset it to let volbench "
                                      f"choose, or {DEBIAN_POCL_HINT}")
    raise BackendUnavailableError(f"no OpenCL device here builds a kernel: {'; '.join(refused)}; {INSTALL_HINT}")


def _opencl():
    """The pyopencl module (:class:`BackendUnavailableError` if it cannot be imported)."""
    try:
        import pyopencl
    except ImportError as exc:
        raise BackendUnavailableError(f"pyopencl cannot be imported: {exc}") from exc
    return pyopencl


def selector_for(option):
    """The selector in force: the ``device`` option, else :data:`DEVICE_VARIABLE`, else ``""`` (volbench chooses)."""
    if option is not None:
        return option
    return os.environ.get(DEVICE_VARIABLE, "")


def shared(selector=""):
    """The :class:`Device` for ``selector``, chosen on first use in this process (see the module notes).

    Raises
    ------
    InputError
        The selector names no device (the message lists those available).
    BackendUnavailableError
        pyopencl is missing or no device that the selector allows builds a kernel; remembered
        for the process.
    """
    pid = os.getpid()
    if _STATE["pid"] != pid:
        _STATE.update(pid=pid, devices={}, errors={})
    entry = _STATE["devices"].get(selector)
    if entry is not None:
        return entry
    if selector in _STATE["errors"]:
        raise BackendUnavailableError(_STATE["errors"][selector])
    try:
        entry = choose(_opencl(), selector)
    except BackendUnavailableError as exc:
        _STATE["errors"][selector] = str(exc)
        raise
    _STATE["devices"][selector] = entry
    return entry


def probe(selector=""):
    """``(True, "")`` if a device for ``selector`` builds kernels here, else ``(False, reason)``; never raises."""
    try:
        shared(selector)
    except (BackendUnavailableError, InputError) as exc:
        return False, str(exc)
    return True, ""


def environment(selector=""):
    """Facts about the chosen device for result records, and the devices refused on the way."""
    cl = _opencl()
    entry = shared(selector)
    device, platform = entry.device, entry.platform
    versions = platform_versions(platform.version)
    return {
        "cl_platform": platform.name.strip(),
        "cl_platform_version": platform.version.strip(),
        "cl_pocl_version": versions["pocl"],
        "cl_llvm_version": versions["llvm"],
        "cl_device": device.name.strip(),
        "cl_device_index": entry.index,
        "cl_device_type": cl.device_type.to_string(device.type),
        "cl_device_version": device.version.strip(),
        "cl_driver_version": device.driver_version.strip(),
        "cl_compute_units": device.max_compute_units,
        "cl_global_mem_bytes": device.global_mem_size,
        "cl_local_mem_bytes": device.local_mem_size,
        "cl_refused": "; ".join(entry.refused),
        "pyopencl": cl.VERSION_TEXT,
    }


def kernel_source(*names):
    """The text of the ``.cl`` files ``names`` under :data:`KERNEL_DIR`, joined in order."""
    return "\n".join((KERNEL_DIR / name).read_text() for name in names)


def kernels(entry, source, options=()):
    """``{name: pyopencl.Kernel}`` of ``source`` built for ``entry``'s device with ``options``.

    Built once per process and pair; the kernel objects are kept too, since retrieving a kernel
    from a program creates a new one each time.
    """
    import pyopencl as cl

    key = (source, tuple(options))
    built = entry.programs.get(key)
    if built is None:
        program = cl.Program(entry.context, source).build(options=list(options))
        built = {kernel.function_name: kernel for kernel in program.all_kernels()}
        entry.programs[key] = built
        compilation.record()  # the timing harness's cold frame compiled (renderers.base.compilation)
    return built
