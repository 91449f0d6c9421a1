"""The OpenCL device, context and queue of a process, chosen once per device selector.

Every OpenCL backend runs through :func:`shared`. The device is picked by a *selector*: the
backend's ``device`` option, else the environment variable :data:`DEVICE_VARIABLE`, else the
first GPU of any platform and, failing that, the first device at all (here: PoCL on the CPU).
A selector is ``"<platform>:<device>"`` (indices, as ``clinfo -l`` lists them) or a
case-insensitive substring of ``"<platform name> <device name>"`` (``"pocl"``, ``"nvidia"``).

Creating a context and compiling programs cost seconds on PoCL, so each selector's context,
its profiling queue and every program built for it (:func:`kernels`, keyed by source text and
build options) are kept for the life of the process. A process forked after a context was made
(the pipeline renders in child processes) makes its own, since OpenCL objects do not survive a
fork. A selector that fails is remembered with its reason, and :func:`probe` reports it as
``(False, reason)`` instead of raising.
"""

import os
from dataclasses import dataclass, field
from pathlib import Path

from core.errors import BackendUnavailableError, InputError

DEVICE_VARIABLE = "VOLBENCH_CL_DEVICE"
"""Environment variable naming the OpenCL device when the backend's ``device`` option is unset."""

KERNEL_DIR = Path(__file__).resolve().parent / "kernels"


@dataclass
class Device:
    """One selected device with its context, profiling queue and compiled programs."""

    platform: object
    device: object
    context: object
    queue: object
    programs: dict = field(default_factory=dict)


_STATE = {"pid": None, "devices": {}, "errors": {}}


def _all_devices(cl):
    """``[(platform index, device index, platform, device), ...]`` over every platform."""
    found = []
    for p_index, platform in enumerate(cl.get_platforms()):
        try:
            devices = platform.get_devices()
        except cl.Error:  # a platform without devices raises CL_DEVICE_NOT_FOUND
            continue
        found.extend((p_index, d_index, platform, device) for d_index, device in enumerate(devices))
    return found


def _pick(cl, selector):
    """The ``(platform, device)`` a selector names (see the module notes)."""
    found = _all_devices(cl)
    if not found:
        raise BackendUnavailableError("no OpenCL platform with a device (pyopencl found none; install an ICD "
                                      "such as pocl-binary-distribution)")
    listing = "; ".join(f"{p}:{d} {platform.name.strip()} / {device.name.strip()}"
                        for p, d, platform, device in found)
    if not selector:
        gpus = [entry for entry in found if entry[3].type & cl.device_type.GPU]
        _, _, platform, device = (gpus or found)[0]
        return platform, device
    head, _, tail = selector.partition(":")
    if head.isdigit() and tail.isdigit():
        for p, d, platform, device in found:
            if (p, d) == (int(head), int(tail)):
                return platform, device
        raise InputError(f"OpenCL device {selector!r}: no such platform:device index; available: {listing}")
    matches = [(platform, device) for _, _, platform, device in found
               if selector.lower() in f"{platform.name} {device.name}".lower()]
    if not matches:
        raise InputError(f"OpenCL device {selector!r}: matches no device; available: {listing}")
    return matches[0]


def selector_for(option):
    """The selector in force: the ``device`` option, else :data:`DEVICE_VARIABLE`, else ``""`` (default)."""
    if option is not None:
        return option
    return os.environ.get(DEVICE_VARIABLE, "")


def shared(selector=""):
    """The :class:`Device` for ``selector``, created on first use in this process.

    Raises
    ------
    InputError
        The selector names no device (the message lists those available).
    BackendUnavailableError
        pyopencl is missing or no context could be created; remembered for the process.
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
        import pyopencl as cl
    except ImportError as exc:
        _STATE["errors"][selector] = f"pyopencl cannot be imported: {exc}"
        raise BackendUnavailableError(_STATE["errors"][selector]) from exc
    try:
        platform, device = _pick(cl, selector)
        context = cl.Context([device])
        queue = cl.CommandQueue(context, device, properties=cl.command_queue_properties.PROFILING_ENABLE)
    except BackendUnavailableError as exc:
        _STATE["errors"][selector] = str(exc)
        raise
    except cl.Error as exc:
        _STATE["errors"][selector] = f"OpenCL context on {selector or 'the default device'} failed: {exc}"
        raise BackendUnavailableError(_STATE["errors"][selector]) from exc
    entry = Device(platform=platform, device=device, context=context, queue=queue)
    _STATE["devices"][selector] = entry
    return entry


def probe(selector=""):
    """``(True, "")`` if a context for ``selector`` can be made here, else ``(False, reason)``; never raises."""
    try:
        shared(selector)
    except (BackendUnavailableError, InputError) as exc:
        return False, str(exc)
    return True, ""


def environment(selector=""):
    """Facts about the selected device for result records."""
    import pyopencl as cl

    entry = shared(selector)
    device = entry.device
    return {
        "cl_platform": f"{entry.platform.name.strip()} {entry.platform.version.strip()}",
        "cl_device": device.name.strip(),
        "cl_device_type": cl.device_type.to_string(device.type),
        "cl_device_version": device.version.strip(),
        "cl_driver_version": device.driver_version.strip(),
        "cl_compute_units": device.max_compute_units,
        "cl_global_mem_bytes": device.global_mem_size,
        "cl_local_mem_bytes": device.local_mem_size,
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
    return built
