"""The environment stamped on every result (CONVENTIONS, Results).

Cheap facts (CPU, Python, package versions, git commit) are read in every process; the OpenGL and
OpenCL devices are probed by :func:`probe_devices`, which the pipeline runs once per run of the
workflow (creating a GL context and initialising OpenCL costs seconds) and backends that use a
device add their own context's facts to their records.
"""

import functools
import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path

KEY_PACKAGES = (
    "numpy", "numba", "scipy", "scikit-image", "pandas", "matplotlib", "OpenImageIO",
    "flip-evaluator", "snakemake", "moderngl", "pyopencl", "pocl-binary-distribution", "vtk",
)
REPO_ROOT = Path(__file__).resolve().parent.parent


def cpu_model():
    """The CPU's marketing name from /proc/cpuinfo (falls back to ``platform.processor()``)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def package_versions(packages=KEY_PACKAGES):
    """``{package: version}`` of the resolved installed versions (``None`` if absent)."""
    versions = {}
    for name in packages:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def git_commit(repo=REPO_ROOT):
    """``HEAD`` of the project, with ``+dirty`` when the work tree has uncommitted changes."""
    try:
        commit = subprocess.run(["git", "-C", str(repo), "rev-parse", "HEAD"], capture_output=True,
                                text=True, check=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(repo), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return commit + ("+dirty" if dirty else "")


@functools.cache
def host_environment():
    """Facts every result row carries, flat ``{column: value}``."""
    env = {
        "cpu_model": cpu_model(),
        "cpu_cores": os.cpu_count(),
        "hostname": platform.node(),
        "os": platform.platform(),
        "python": platform.python_version(),
        "git_commit": git_commit(),
    }
    env.update({f"pkg_{name}": version for name, version in package_versions().items()})
    return env


def probe_opengl():
    """``{gl_renderer, gl_version, gl_vendor}`` of a headless EGL context, or the failure reason."""
    try:
        import moderngl

        ctx = moderngl.create_standalone_context(backend="egl")
        try:
            info = ctx.info
            return {"gl_renderer": info["GL_RENDERER"], "gl_version": info["GL_VERSION"],
                    "gl_vendor": info["GL_VENDOR"]}
        finally:
            ctx.release()
    except Exception as exc:  # any failure here means "no OpenGL", which is a fact to record
        return {"gl_renderer": None, "gl_version": None, "gl_vendor": None,
                "gl_error": f"{type(exc).__name__}: {exc}"}


def probe_opencl():
    """``{cl_platform, cl_device}`` of the first OpenCL device, or the failure reason."""
    try:
        import pyopencl as cl

        platforms = cl.get_platforms()
        devices = [(p, d) for p in platforms for d in p.get_devices()]
        if not devices:
            return {"cl_platform": None, "cl_device": None, "cl_error": "no OpenCL device"}
        platform_, device = devices[0]
        return {"cl_platform": f"{platform_.name} {platform_.version}", "cl_device": device.name.strip()}
    except Exception as exc:  # as above: recorded, not raised
        return {"cl_platform": None, "cl_device": None, "cl_error": f"{type(exc).__name__}: {exc}"}


def probe_devices():
    """OpenGL and OpenCL facts (each probed in this process)."""
    return {**probe_opengl(), **probe_opencl()}
