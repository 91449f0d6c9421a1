"""The OpenCL device choice (renderers.cl.context): order, selectors, refusals with the compiler's
message, the unavailable reason and the environment record, on fake platforms (no device needed),
and the choice of this machine's real OpenCL."""

import os
from types import SimpleNamespace

import pytest

import renderers
from core.errors import BackendUnavailableError, InputError
from renderers.cl import context

PYPI_POCL = "OpenCL 3.0 PoCL 3.0-rc2  Linux, Release, RELOC, LLVM 14.0.6, SLEEF, DISTRO, POCL_DEBUG"
DEBIAN_POCL = "OpenCL 3.0 PoCL 3.1+debian  Linux, None+Asserts, RELOC, SPIR, LLVM 15.0.6, SLEEF, DISTRO, POCL_DEBUG"
UNKNOWN_CPU = "error: unknown target CPU 'generic'\nDevice pthread-AMD EPYC failed to build the program\n"

GPU, ACCELERATOR, CPU = 4, 8, 2  # CL_DEVICE_TYPE_* bits


class FakeError(Exception):
    """Stands for ``pyopencl.Error``."""


class FakeDevice:
    """A device whose compiler fails with ``build_log`` (``None``: it builds)."""

    def __init__(self, name, kind=CPU, build_log=None, no_context=False):
        self.name, self.type, self.build_log, self.no_context = name, kind, build_log, no_context
        self.version, self.driver_version = "OpenCL 3.0", "1.0"
        self.max_compute_units, self.global_mem_size, self.local_mem_size = 4, 1 << 30, 1 << 16
        self.builds = 0


class FakePlatform:
    def __init__(self, name, version, devices):
        self.name, self.version, self.devices = name, version, devices

    def get_devices(self):
        if not self.devices:
            raise FakeError("clGetDeviceIDs failed: DEVICE_NOT_FOUND")
        return self.devices


class FakeContext:
    def __init__(self, devices):
        if devices[0].no_context:
            raise FakeError("clCreateContext failed: DEVICE_NOT_AVAILABLE")
        self.devices = devices


class FakeProgram:
    def __init__(self, ctx, source):
        self.device = ctx.devices[0]

    def build(self, options=()):
        self.device.builds += 1
        if self.device.build_log is not None:
            raise FakeError("clBuildProgram failed: BUILD_PROGRAM_FAILURE - clBuildProgram failed: "
                            "BUILD_PROGRAM_FAILURE\n\nBuild on <pyopencl.Device>:\n\n" + self.device.build_log)
        return self

    def get_build_info(self, device, what):
        assert what == "LOG"
        return device.build_log


def fake_cl(*platforms):
    """Just enough of pyopencl for :mod:`renderers.cl.context` over ``platforms``."""
    names = {GPU: "GPU", ACCELERATOR: "ACCELERATOR", CPU: "CPU"}
    return SimpleNamespace(
        get_platforms=lambda: list(platforms), Error=FakeError, Context=FakeContext, Program=FakeProgram,
        CommandQueue=lambda ctx, device, properties: SimpleNamespace(device=device),
        command_queue_properties=SimpleNamespace(PROFILING_ENABLE=1),
        program_build_info=SimpleNamespace(LOG="LOG"),
        device_type=SimpleNamespace(GPU=GPU, ACCELERATOR=ACCELERATOR, CPU=CPU, to_string=lambda t: names[t]),
        VERSION_TEXT="fake")


@pytest.fixture
def machine(monkeypatch):
    """Install fake platforms as this process's pyopencl, with an empty per-process cache."""
    monkeypatch.setattr(context, "_STATE", {"pid": None, "devices": {}, "errors": {}})
    monkeypatch.delenv(context.DEVICE_VARIABLE, raising=False)

    def install(*platforms):
        cl = fake_cl(*platforms)
        monkeypatch.setattr(context, "_opencl", lambda: cl)
        return cl

    return install


def pocl(version, *devices):
    return FakePlatform("Portable Computing Language", version, list(devices))


# ------------------------------------------------------------------------------ order and selectors


def test_gpus_then_accelerators_then_cpus_each_in_platform_order():
    cl = fake_cl(pocl(DEBIAN_POCL, FakeDevice("cpu0")),
                 FakePlatform("Vendor", "OpenCL 3.0", [FakeDevice("acc", ACCELERATOR), FakeDevice("gpu1", GPU)]),
                 FakePlatform("Other", "OpenCL 1.2", [FakeDevice("gpu2", GPU), FakeDevice("cpu2")]))
    found = context.enumerate_devices(cl)
    assert [c.device.name for c in found] == ["cpu0", "acc", "gpu1", "gpu2", "cpu2"]
    ordered = context.candidates(found, "")
    assert [(c.device.name, c.index) for c in ordered] == [
        ("gpu1", "1:1"), ("gpu2", "2:0"), ("acc", "1:0"), ("cpu0", "0:0"), ("cpu2", "2:1")]


def test_selectors_name_devices_by_index_or_substring_and_errors_list_them():
    cl = fake_cl(pocl(DEBIAN_POCL, FakeDevice("pthread-skylake-avx512")), pocl(PYPI_POCL, FakeDevice("pthread")),
                 FakePlatform("NVIDIA CUDA", "OpenCL 3.0 CUDA 12.2", [FakeDevice("NVIDIA H100", GPU)]))
    found = context.enumerate_devices(cl)
    assert [c.index for c in context.candidates(found, "1:0")] == ["1:0"]
    assert [c.device.name for c in context.candidates(found, "NVIDIA")] == ["NVIDIA H100"]
    # The platform version is part of what a name matches: "pocl 3.0" is PyPI's PoCL alone.
    assert [c.index for c in context.candidates(found, "pocl 3.0")] == ["1:0"]
    assert [c.index for c in context.candidates(found, "pocl")] == ["0:0", "1:0"]
    with pytest.raises(InputError, match=r"'3:0': no such platform:device index; available: 0:0 "
                                         r"pthread-skylake-avx512 \(Portable Computing Language: PoCL 3.1\+debian, "
                                         r"LLVM 15.0.6\) CPU; 1:0 .*2:0 NVIDIA H100 \(NVIDIA CUDA: OpenCL 3.0 CUDA "
                                         r"12.2\) GPU"):
        context.candidates(found, "3:0")
    with pytest.raises(InputError, match="'amd': matches no device; available: 0:0"):
        context.candidates(found, "amd")


def test_versions_and_compiler_messages_are_parsed():
    assert context.platform_versions(PYPI_POCL) == {"pocl": "3.0-rc2", "llvm": "14.0.6"}
    assert context.platform_versions(DEBIAN_POCL) == {"pocl": "3.1+debian", "llvm": "15.0.6"}
    assert context.platform_versions("OpenCL 3.0 CUDA 12.2.140") == {"pocl": None, "llvm": None}
    # Error lines first, at most two, whatever the log holds around them.
    log = "warning: a\n<source>:3:5: error: use of undeclared identifier 'x'\n  x = 1;\n  ^\n" * 20
    assert context.compiler_message(log, FakeError("ignored")) == (
        "<source>:3:5: error: use of undeclared identifier 'x' / <source>:3:5: error: use of undeclared identifier 'x'")
    assert context.compiler_message(UNKNOWN_CPU, FakeError("ignored")) == "error: unknown target CPU 'generic'"
    assert context.compiler_message("", FakeError("clBuildProgram failed: OUT_OF_HOST_MEMORY\nmore")) == (
        "clBuildProgram failed: OUT_OF_HOST_MEMORY")


# ------------------------------------------------------------------- the probe builds before it chooses


def test_a_device_whose_build_fails_is_refused_with_its_message_and_the_next_is_taken(machine):
    broken = FakeDevice("pthread-AMD EPYC", build_log=UNKNOWN_CPU)
    working = FakeDevice("pthread-skylake-avx512-AMD EPYC")
    machine(pocl(PYPI_POCL, broken), pocl(DEBIAN_POCL, working))
    assert context.probe("") == (True, "")
    entry = context.shared("")
    assert entry.device is working and entry.index == "1:0"
    assert entry.refused == ("0:0 pthread-AMD EPYC (Portable Computing Language: PoCL 3.0-rc2, LLVM 14.0.6): "
                             "error: unknown target CPU 'generic'",)
    facts = context.environment("")
    assert facts["cl_device"] == "pthread-skylake-avx512-AMD EPYC" and facts["cl_device_index"] == "1:0"
    assert facts["cl_pocl_version"] == "3.1+debian" and facts["cl_llvm_version"] == "15.0.6"
    assert facts["cl_platform_version"] == DEBIAN_POCL and facts["cl_refused"] == entry.refused[0]
    # Chosen once per process: no second build on either device.
    context.probe("")
    assert (broken.builds, working.builds) == (1, 1)


def test_a_gpu_is_taken_before_a_cpu_and_a_gpu_that_cannot_build_falls_back(machine):
    gpu, cpu = FakeDevice("NVIDIA H100", GPU), FakeDevice("pthread")
    machine(pocl(DEBIAN_POCL, cpu), FakePlatform("NVIDIA CUDA", "OpenCL 3.0 CUDA", [gpu]))
    assert context.shared("").device is gpu and cpu.builds == 0
    gpu = FakeDevice("NVIDIA H100", GPU, no_context=True)
    machine(pocl(DEBIAN_POCL, cpu), FakePlatform("NVIDIA CUDA", "OpenCL 3.0 CUDA", [gpu]))
    context._STATE["pid"] = None  # a new process
    entry = context.shared("")
    assert entry.device is cpu
    assert entry.refused == ("1:0 NVIDIA H100 (NVIDIA CUDA: OpenCL 3.0 CUDA): no context: clCreateContext failed: "
                             "DEVICE_NOT_AVAILABLE",)


def test_with_no_device_that_builds_the_backend_is_unavailable_with_the_compilers_message(machine):
    machine(pocl(PYPI_POCL, FakeDevice("pthread-AMD EPYC", build_log=UNKNOWN_CPU)), pocl(DEBIAN_POCL))
    ok, reason = context.probe("")
    assert not ok
    assert reason.startswith("no OpenCL device here builds a kernel: 0:0 pthread-AMD EPYC (Portable Computing "
                             "Language: PoCL 3.0-rc2, LLVM 14.0.6): error: unknown target CPU 'generic'; ")
    assert "failed to build the program" not in reason and "BUILD_PROGRAM_FAILURE" not in reason
    assert reason.endswith("install Debian's pocl-opencl-icd (`make setup` does), whose PoCL builds kernels on any "
                           "x86-64 CPU, or name a device that builds them with VOLBENCH_CL_DEVICE")
    with pytest.raises(BackendUnavailableError, match="unknown target CPU 'generic'"):
        context.shared("")
    row = {info.name: info for info in renderers.available()}["cl-tiled"]
    assert row.available is False and "unknown target CPU 'generic'" in row.reason
    with pytest.raises(BackendUnavailableError, match="not available here: no OpenCL device here builds"):
        renderers.get("cl-tiled")


def test_a_named_device_that_cannot_build_is_not_replaced(machine, monkeypatch):
    broken = FakeDevice("pthread-AMD EPYC", build_log=UNKNOWN_CPU)
    working = FakeDevice("pthread-skylake-avx512-AMD EPYC")
    machine(pocl(PYPI_POCL, broken), pocl(DEBIAN_POCL, working))
    ok, reason = context.probe("0:0")
    assert not ok and reason.startswith("OpenCL device selector '0:0': no device it names builds a kernel: 0:0 "
                                        "pthread-AMD EPYC (Portable Computing Language: PoCL 3.0-rc2, LLVM 14.0.6): "
                                        "error: unknown target CPU 'generic'; name another device")
    assert working.builds == 0
    # The backend's device option is a selector too: unavailable when the backend is made, before any run.
    with pytest.raises(BackendUnavailableError, match="'0:0': no device it names builds"):
        renderers.get("cl-tiled", device="0:0", fragments="global")
    monkeypatch.setenv(context.DEVICE_VARIABLE, "0:0")
    assert renderers.backend_class("cl-tiled").probe() == (False, reason)
    assert context.probe("1:0") == (True, "") and context.shared("1:0").device is working


def test_no_platform_at_all_says_what_to_install(machine, monkeypatch):
    cl = machine()

    def none():
        raise FakeError("clGetPlatformIDs failed: PLATFORM_NOT_FOUND_KHR")

    monkeypatch.setattr(cl, "get_platforms", none)
    ok, reason = context.probe("")
    assert not ok and reason == ("no OpenCL platform (clGetPlatformIDs failed: PLATFORM_NOT_FOUND_KHR); install "
                                 "Debian's pocl-opencl-icd (`make setup` does), whose PoCL builds kernels on any "
                                 "x86-64 CPU")


def test_a_forked_process_chooses_again(machine):
    device = FakeDevice("pthread")
    machine(pocl(DEBIAN_POCL, device))
    first = context.shared("")
    assert context.shared("") is first and device.builds == 1
    context._STATE["pid"] = -1  # as in a forked child: OpenCL objects do not survive a fork
    assert context.shared("") is not first and device.builds == 2


# -------------------------------------------------------------------------------- this machine's OpenCL


@pytest.mark.skipif(not context.probe(context.selector_for(None))[0] and not os.environ.get("VOLBENCH_REQUIRE_OPENCL"),
                    reason="no OpenCL device here builds a kernel")
def test_this_machines_choice_builds_and_is_recorded():
    selector = context.selector_for(None)
    facts = context.environment(selector)
    assert facts["cl_device"] and facts["cl_device_index"] and facts["cl_platform_version"]
    entry = context.shared(selector)
    assert context.kernels(entry, context.PROBE_KERNEL)["volbench_probe"].function_name == "volbench_probe"
    if "pocl" in facts["cl_platform_version"].lower():
        assert facts["cl_pocl_version"] and facts["cl_llvm_version"]
