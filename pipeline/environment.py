"""The environment stamped on every result (CONVENTIONS, Results).

Cheap facts (CPU, Python, package versions, git commit, the node and the SLURM job it runs in) are
read in every process, so a run executed on a cluster node records that node; the OpenGL and
OpenCL devices are probed by :func:`probe_devices`, which the pipeline runs once per run of the
workflow (creating a GL context and initialising OpenCL costs seconds) and backends that use a
device add their own context's facts to their records. The probes report the devices the
backends choose, by asking the backends' context modules (:mod:`renderers.gl.context`,
:mod:`renderers.cl.context`), not a choice of their own.
"""

import functools
import os
import platform
import subprocess
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path

KEY_PACKAGES = (
    "numpy", "numba", "scipy", "scikit-image", "pandas", "matplotlib", "OpenImageIO",
    "flip-evaluator", "snakemake", "moderngl", "glcontext", "pyopencl", "pocl-binary-distribution", "vtk",
)
"""Python packages whose versions every record carries (glcontext chooses the EGL device; the PoCL
that runs, PyPI's or Debian's, is in the OpenCL facts: ``cl_pocl_version``)."""
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


def memory_bytes():
    """Total physical memory in bytes (``None`` when it cannot be read)."""
    try:
        import psutil

        return int(psutil.virtual_memory().total)
    except Exception:  # a fact we could not read is recorded as missing, not raised
        return None


def numba_threads():
    """The threads Numba's parallel loops use in this process (``NUMBA_NUM_THREADS`` or its default)."""
    if os.environ.get("NUMBA_NUM_THREADS", "").isdigit():
        return int(os.environ["NUMBA_NUM_THREADS"])
    try:
        import numba

        return int(numba.config.NUMBA_NUM_THREADS)
    except Exception:  # numba absent or broken: the reference reports that itself
        return None


def usable_cpus():
    """The CPUs this process may run on (a SLURM allocation or ``taskset`` can give fewer than the node has)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count()


SLURM_FACTS = {
    "slurm_cluster": ("SLURM_CLUSTER_NAME",),
    "slurm_job_id": ("SLURM_JOB_ID",),
    "slurm_partition": ("SLURM_JOB_PARTITION",),
    "slurm_cpus_per_task": ("SLURM_CPUS_PER_TASK",),
    # A job step (srun, as the executor plugin runs every job) sees its own GPUs, a batch script the job's.
    "slurm_gpus": ("SLURM_STEP_GPUS", "SLURM_JOB_GPUS"),
}
"""Column → the environment variables SLURM sets in a job, first found wins: where a cluster run
executed and what it held."""


def slurm_job(environ=None):
    """``{column: value}`` of :data:`SLURM_FACTS` (``None`` each outside a SLURM job)."""
    environ = os.environ if environ is None else environ
    return {column: next((environ[v] for v in variables if environ.get(v)), None)
            for column, variables in SLURM_FACTS.items()}


def node_name(environment):
    """The node a record was measured on: its host name, prefixed by the SLURM cluster's name in a job.

    Host names repeat across clusters (``node001``) and a run under SLURM holds its node on other
    terms than one started by hand, so ``cluster/host`` and ``host`` count as different nodes.
    ``None`` when the record names no host.
    """
    host = environment.get("hostname")
    if host is None or (isinstance(host, float) and host != host):
        return None
    cluster = environment.get("slurm_cluster")
    return f"{cluster}/{host}" if isinstance(cluster, str) and cluster else str(host)


def now_utc():
    """The current date and time, UTC, to the minute (``2025-01-31 14:05``)."""
    return datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M")


@functools.cache
def host_environment():
    """Facts every result row carries, flat ``{column: value}``; ``date`` is when the process started."""
    env = {
        "date": now_utc(),
        "cpu_model": cpu_model(),
        "cpu_cores": os.cpu_count(),
        "memory_bytes": memory_bytes(),
        "numba_threads": numba_threads(),
        "usable_cpus": usable_cpus(),
        "hostname": platform.node(),
        "os": platform.platform(),
        "python": platform.python_version(),
        "git_commit": git_commit(),
    }
    env.update(slurm_job())
    env.update({f"pkg_{name}": version for name, version in package_versions().items()})
    return env


def probe_opengl():
    """The OpenGL device the GL backends use (:func:`renderers.gl.context.device_facts`: renderer,
    version, EGL device index and the devices tried), or ``gl_error`` saying why there is none."""
    from renderers.gl import context

    ok, reason = context.probe()
    if not ok:  # "no OpenGL" is a fact to record, not an error
        return {"gl_renderer": None, "gl_version": None, "gl_vendor": None, "gl_error": reason}
    return context.device_facts()


def probe_opencl():
    """The OpenCL device the CL backends use by default (:func:`renderers.cl.context.environment`:
    device, platform, PoCL and LLVM versions, the devices refused), or ``cl_error`` saying why there is none."""
    from renderers.cl import context

    selector = context.selector_for(None)
    ok, reason = context.probe(selector)
    if not ok:  # as above: recorded, not raised
        return {"cl_platform": None, "cl_device": None, "cl_error": reason}
    return context.environment(selector)


def probe_devices():
    """OpenGL and OpenCL facts (each probed in this process)."""
    return {**probe_opengl(), **probe_opencl()}


DEVICE_PACKAGES = ("renderers.gl", "renderers.cl", "renderers.vtk.gpu")
"""The backends (their registry modules) that render through a device driver."""


def uses_device(backend):
    """Whether ``backend`` renders through a device driver: its render job asks a cluster for a ``gpu``,
    and its images match another run's within a tolerance, not bit for bit (:mod:`pipeline.compare`)."""
    import renderers  # the registry imports no backend

    return renderers.backend_module(backend).startswith(DEVICE_PACKAGES)


def _sources_table(path):
    """``{file: source}`` from the Markdown table of a real-data ``SOURCES.md`` (``{}`` if none)."""
    try:
        lines = Path(path).read_text().splitlines()
    except OSError:
        return {}
    header, sources = None, {}
    for line in lines:
        if not line.startswith("|"):
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if header is None:
            header = [c.lower() for c in cells]
            continue
        if set("".join(cells)) <= set("-: "):
            continue
        row = dict(zip(header, cells))
        source = next((v for k, v in row.items() if k.startswith("source")), "")
        licence = next((v for k, v in row.items() if k.startswith("licen")), "")
        if row.get("file"):
            sources[row["file"].strip("`")] = f"{source}. {licence}".strip(" .").replace("`", "")
    return sources


def real_data_provenance(data_dir=None):
    """Where the real scans come from: the folder, its manifest's entries and their stated sources.

    Returns ``{"folder", "error", "sources_file", "datasets": [{"name", "file", "modality",
    "source"}]}``; ``error`` says why the folder cannot be read (then ``datasets`` is empty).
    """
    from core.errors import InputError
    from datasets import real

    folder = real.resolve_data_dir(data_dir)
    out = {"folder": str(folder), "error": "", "sources_file": "", "datasets": []}
    try:
        manifest = real.read_manifest(folder)
    except InputError as exc:  # DataUnavailableError included
        out["error"] = str(exc).split(". ")[0]
        manifest = {}
    sources_file = folder / "SOURCES.md"
    if sources_file.is_file():
        out["sources_file"] = str(sources_file)
    sources = _sources_table(sources_file)
    for name, entry in manifest.items():
        out["datasets"].append({"name": name, "file": entry["file"], "modality": entry.get("modality", ""),
                                "source": sources.get(entry["file"], f"not stated in {folder / 'SOURCES.md'}")})
    for candidate in (folder / real.BRAINSMALL_FILE, real.DEBIAN_BRAINSMALL):
        if candidate.is_file():
            out["datasets"].append({"name": "brainsmall", "file": str(candidate), "modality": "MRI",
                                    "source": "VolPack's example data (Debian package libvolpack1-dev)"})
            break
    return out
