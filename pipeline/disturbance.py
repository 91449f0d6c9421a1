"""Was the machine quiet while a run was timed? Waits for a CPU, CPU time others used, steal, from ``/proc``.

The first signal is exact: how long this process's threads waited, runnable, for a CPU
(:func:`thread_waits`, the scheduler's run-queue delay), frame by frame.

The kernel counts every CPU's busy time (``/proc/stat``) and this process's own (``/proc/self/stat``,
all its threads: Numba's workers, llvmpipe's, PoCL's) in the same clock ticks. What the machine spent
beyond this process while frames were timed is *foreign* work, in cores: another program, a browser,
a build, a second benchmark. A run whose frames shared the machine with more than
:data:`FOREIGN_LIMIT` of a core on average, or lost more than :data:`STEAL_LIMIT` of its time to the
hypervisor (steal), is **disturbed**; the render job times it again once and keeps the quieter
attempt (:func:`pipeline.rendering.execute`), and the report lists every run still disturbed with
the reason. Where ``/proc`` does not exist (not Linux) nothing is measured and nothing is flagged.
"""

import os
import time
from dataclasses import dataclass
from pathlib import Path

FOREIGN_LIMIT = 0.25
"""Cores of other work, averaged over the timed frames, above which a run is disturbed. Snakemake
and the job's own wrapper stay far below it (they wait); one busy program on another core is 1."""

FOREIGN_NOISE = 0.1
"""Cores of other work under which the machine counts as quiet: Snakemake, the job's wrapper and the
kernel's own threads. Above it, this process's waits for a CPU are others' doing (:func:`verdict`)."""

STEAL_LIMIT = 0.05
"""Share of the timed span a virtual machine's CPUs were taken by the hypervisor."""

OUTLIER_FACTOR = 3.0
"""A frame slower than this many times the run's median frame was interrupted (a frame of one
configuration costs the same work each time)."""

OUTLIER_SHARE = 0.1
"""Share of outlier frames above which a run is disturbed even where ``/proc`` saw no other work."""

MIN_SPAN = 0.5
"""Seconds under which the counters (10 ms ticks) cannot tell: over 1 ms, one tick of other work reads
as ten cores. Shorter spans get no load and are never flagged by it."""

_TICK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


@dataclass(frozen=True)
class Snapshot:
    """CPU counters at one instant (ticks), or ``None`` fields where ``/proc`` is unreadable."""

    wall: float
    busy: int | None
    steal: int | None
    own: int | None
    orchestrator: dict | None = None
    """``{pid: ticks}`` of the watched processes (:func:`watch`) alive at this instant."""


_WATCHED = []
"""The processes of volbench's own orchestration whose CPU time every snapshot reads (:func:`watch`)."""


def watch(pids):
    """Read the CPU time of ``pids`` (the process that runs Snakemake, the waiting job) in every snapshot.

    What they use while a view is timed is the orchestrator's share of the other work
    (``orchestrator_cores`` in :func:`between`): a run's record shows that its own harness was quiet.
    """
    _WATCHED[:] = sorted({int(pid) for pid in pids if pid and int(pid) != os.getpid()})


def _cpu_ticks(stat_path):
    with open(stat_path) as f:
        # The command name may hold spaces: the fields after it start after the last ')'.
        after = f.read().rsplit(")", 1)[1].split()
    return int(after[11]) + int(after[12])  # utime, stime


def snapshot():
    """This instant's machine-wide busy and steal ticks, this process's and the watched processes' CPU ticks."""
    wall = time.monotonic()
    try:
        with open("/proc/stat") as f:
            fields = [int(v) for v in f.readline().split()[1:]]
        # user nice system idle iowait irq softirq steal [guest guest_nice: already in user, nice]
        busy = sum(fields[:8]) - fields[3] - fields[4]
        steal = fields[7] if len(fields) > 7 else 0
        own = _cpu_ticks("/proc/self/stat")
    except (OSError, ValueError, IndexError):
        return Snapshot(wall, None, None, None)
    orchestrator = {}
    for pid in _WATCHED:
        try:
            orchestrator[pid] = _cpu_ticks(f"/proc/{pid}/stat")
        except (OSError, ValueError, IndexError):  # ended meanwhile
            continue
    return Snapshot(wall, busy, steal, own, orchestrator)


DRIVER = "pipeline.driver"
"""The module that runs Snakemake for ``volbench run`` (:mod:`pipeline.driver`)."""


def is_orchestrator(argv):
    """Whether a command line runs the workflow: ``python -m snakemake ...``, Snakemake's ``snakemake``
    script or ``volbench run``'s driver (``python -m pipeline.driver ...``)."""
    return (any(Path(arg).name == "snakemake" for arg in argv[:2])
            or any(argv[i:i + 2] in (["-m", "snakemake"], ["-m", DRIVER]) for i in range(len(argv) - 1)))


def orchestrator_pids(start=None, *, levels=4):
    """This process's ancestors up to the one that runs the workflow (a render job's own, its shell, Snakemake).

    Empty where ``/proc`` cannot be read or no ancestor within ``levels`` runs the workflow.
    """
    pid, found = os.getppid() if start is None else start, []
    for _ in range(levels):
        if pid <= 1:
            break
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                argv = f.read().decode(errors="replace").split("\0")
            with open(f"/proc/{pid}/stat") as f:
                parent = int(f.read().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            return []
        found.append(pid)
        if is_orchestrator(argv):
            return found
        pid = parent
    return []


def thread_waits():
    """Seconds this process's threads have waited, runnable, for a CPU (``None`` where unreadable).

    The scheduler's own account (``/proc/self/task/*/schedstat``, the run-queue delay, in ns): a thread
    that waits here was ready to run while another program held every core it could use. It is exact
    even over a frame of a millisecond, and a thread that sleeps (a worker without work, a wait on a
    device) does not count. Threads that ended since the last reading drop out of the sum, so a
    difference can be slightly low, never high.
    """
    total = 0
    try:
        tasks = os.listdir("/proc/self/task")
    except OSError:
        return None
    for task in tasks:
        try:
            with open(f"/proc/self/task/{task}/schedstat") as f:
                total += int(f.read().split()[1])
        except (OSError, ValueError, IndexError):
            continue
    return total / 1e9


WAIT_LIMIT = 0.05
"""Share of the timed span this process's threads together spent waiting for a CPU above which the
frames were disturbed (a single-threaded frame lost 5 % of its time to other programs)."""

FRAME_WAIT_LIMIT = 0.1
"""Share of one frame's time spent waiting for a CPU above which that frame was interrupted."""


def load_average():
    """The 1-minute load average, or ``None``."""
    try:
        return os.getloadavg()[0]
    except (OSError, AttributeError):
        return None


def between(start, end):
    """``{"foreign_cores", "own_cores", "steal_share", "seconds"}`` from two :func:`snapshot` s.

    Counts are in ticks (10 ms), so over spans much shorter than a second they are coarse: under
    :data:`MIN_SPAN` the loads are ``None``. The timing harness reads them from the first warm-up
    frame to the last timed frame of a view.
    """
    seconds = end.wall - start.wall
    out = {"seconds": seconds, "foreign_cores": None, "own_cores": None, "steal_share": None,
           "orchestrator_cores": None}
    if None in (start.busy, end.busy) or seconds < MIN_SPAN:
        return out
    busy = (end.busy - start.busy) / _TICK
    own = (end.own - start.own) / _TICK
    cpus = os.cpu_count() or 1
    out.update(foreign_cores=max(0.0, busy - own) / seconds, own_cores=own / seconds,
               steal_share=(end.steal - start.steal) / _TICK / seconds / cpus)
    if start.orchestrator and end.orchestrator:
        spent = sum(end.orchestrator[pid] - ticks for pid, ticks in start.orchestrator.items()
                    if pid in end.orchestrator)
        out["orchestrator_cores"] = max(0, spent) / _TICK / seconds
    return out


def outlier_frames(totals):
    """How many frame times exceed :data:`OUTLIER_FACTOR` × their median."""
    if not totals:
        return 0
    ordered = sorted(totals)
    median = ordered[len(ordered) // 2]
    return sum(t > OUTLIER_FACTOR * median for t in totals)


def verdict(load, totals, waits=(), walls=()):
    """Why a view's timed frames were disturbed (a sentence), or ``""`` when they were not.

    ``load`` is :func:`between` over the timed frames, with ``waited_share`` (the threads' wait for a
    CPU over the timed span, :func:`thread_waits`); ``totals`` the frames' total times, ``waits``
    each frame's wait for a CPU and ``walls`` each frame's wall time.
    """
    reasons = []
    foreign, steal, waited = load.get("foreign_cores"), load.get("steal_share"), load.get("waited_share")
    # A process's threads also wait for each other (llvmpipe's rasterizer threads and the thread that
    # feeds them outnumber the cores): waits are another program's doing only where one was working.
    others = foreign is not None and foreign > FOREIGN_NOISE
    if others and waited is not None and waited > WAIT_LIMIT:
        reasons.append(f"its threads waited {100 * waited:.0f} % of the time for a CPU")
    slow = sum(wait > FRAME_WAIT_LIMIT * wall for wait, wall in zip(waits, walls))
    if others and walls and slow / len(walls) > OUTLIER_SHARE:
        reasons.append(f"{slow} of {len(walls)} frames waited over {100 * FRAME_WAIT_LIMIT:.0f} % of their time "
                       "for a CPU")
    if foreign is not None and foreign > FOREIGN_LIMIT:
        reasons.append(f"other work used {foreign:.2f} cores while it was timed")
    if steal is not None and steal > STEAL_LIMIT:
        reasons.append(f"the hypervisor took {100 * steal:.0f} % of the CPU time (steal)")
    outliers = outlier_frames(totals)
    if totals and outliers / len(totals) > OUTLIER_SHARE:
        reasons.append(f"{outliers} of {len(totals)} frames took over {OUTLIER_FACTOR:g}× the median")
    return "; ".join(reasons)


def starvation(load, workers):
    """Why a parallel run had fewer free cores than workers (a sentence), or ``""``.

    ``workers`` is how many threads the technique runs on; the free cores are the machine's less
    the foreign work measured over the timed frames.
    """
    foreign = load.get("foreign_cores")
    if foreign is None or not workers or workers < 2:
        return ""
    free = max(0.0, (os.cpu_count() or 1) - foreign)
    if free < workers - FOREIGN_LIMIT:
        return f"{workers} workers had {free:.1f} free cores (other work used {foreign:.2f})"
    return ""
