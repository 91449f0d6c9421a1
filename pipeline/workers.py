"""Warm render workers: a pipeline's runs share processes, device contexts and compiled kernels.

A render job used to be a process of its own: an interpreter's start, the imports of NumPy, Numba,
VTK, moderngl and pyopencl, a device context and the compilation of its kernels, all before its
first frame, some 750 times in the default profile. Here a render job stays one Snakemake job per
run (or interleave group), with its own output, retry and time limit, but its rendering happens in a
**worker**: a process that imported the rendering once and renders request after request.

Three parts:

- **The service** (:class:`RenderService`) lives in the process that runs Snakemake
  (:mod:`pipeline.driver`). It listens on a Unix socket named by the environment variable
  :data:`SERVICE_VARIABLE`, which the render jobs inherit. For each request it takes an idle worker
  of the request's backends or starts one, hands it the runs, waits under the profile's
  ``render_time_limit`` and answers. A worker past the limit is killed and its unfinished runs are
  recorded as failed, as :mod:`pipeline.execution` records them; a worker that died is recorded as
  a crash; either way the next request of those backends gets a fresh worker.
- **The client** (:func:`request_render`) is what a render job runs (``python -m pipeline.jobs
  render``): it sends its runs and sleeps until the answer. Where no service answers on this host (a
  cluster node, Snakemake started by hand) the job renders in a process of its own instead, as before.
- **The worker** (``python -m pipeline.worker``, :mod:`pipeline.worker`) renders with :func:`pipeline.rendering.execute_together`.

The untimed steps that start often, the phantoms (``volume``), the comparisons (``evaluate``) and the
tables (``tabulate``), hand their arguments to a worker the same way (:func:`request_step`): each was
a process whose imports cost it more than its work.

A worker renders any backend: a request goes to the idle worker that has already rendered the most of
its backends, so the runs of one backend, within one experiment or across experiments, and the runs
of one interleave group reuse processes whose kernels are compiled and whose device contexts exist
(the old per-job processes mixed backends too, in an interleave group). A timed run goes only to a
worker that has done nothing untimed: untimed work (phantoms, comparisons, tables, ground truths and
pictures) takes the workers that did untimed work before, or new ones. In two default runs the worker
that had generated phantoms and rendered references first timed its later views 7 and 11 % slower than
the other process of the same views (pid 28731 over 85 views, pid 2190 over 157). Whatever the cause
(that worker had generated the volumes and imported every untimed step's libraries), it showed as spread
between processes, not as a disturbance. Nothing here makes a timed view share the machine: Snakemake
gives a timed render job every core, and a worker that waits for a request sleeps on a pipe. A worker
is retired after :data:`MAX_RUNS_PER_WORKER` runs or when it holds more than :data:`MAX_WORKER_MEMORY` of
the machine's memory, and idle workers beyond :data:`MAX_IDLE_WORKERS` are closed, least recently used
first.
"""

import concurrent.futures
import json
import os
import select
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

SERVICE_VARIABLE = "VOLBENCH_WORKERS"
"""``<host>:<socket path>`` of the render service, set by :mod:`pipeline.driver` for its jobs."""

MAX_IDLE_WORKERS = 8
"""Idle workers kept at most; beyond it the least recently used is closed."""

MAX_RUNS_PER_WORKER = 400
"""Runs after which a worker is retired (a fresh one bounds what a long-lived process accumulates)."""

MAX_WORKER_MEMORY = 0.2
"""Share of the machine's memory above which a worker's resident memory retires it after its request."""

CONNECT_TIMEOUT = 10.0
"""Seconds a client waits for the service to accept its connection."""


class ServiceUnavailable(RuntimeError):
    """No render service answers at the address the environment names."""


def service_address(environ=None):
    """The socket of the render service this job may use, or ``None``.

    ``None`` where :data:`SERVICE_VARIABLE` is unset, names another host (a job that a cluster
    executor runs on a node inherits the login node's environment) or the job runs inside a SLURM
    allocation (the service's workers are not in it).
    """
    environ = os.environ if environ is None else environ
    value = environ.get(SERVICE_VARIABLE, "")
    host, _, path = value.partition(":")
    if not path or host != socket.gethostname() or environ.get("SLURM_JOB_ID"):
        return None
    return path


def _send_json(connection, payload):
    connection.sendall(json.dumps(payload).encode() + b"\n")


def _receive_json(connection):
    """One JSON line from a socket (``None`` at end of stream)."""
    chunks = []
    while True:
        chunk = connection.recv(65536)
        if not chunk:
            break
        chunks.append(chunk)
        if chunk.endswith(b"\n"):
            break
    data = b"".join(chunks)
    return json.loads(data) if data.strip() else None


def _ask(address, request):
    """Send ``request`` to the service at ``address`` and wait for its answer, however long it takes (the
    service holds renders to their time limit). Raises :class:`ServiceUnavailable` where nothing answers,
    :class:`RuntimeError` where the service failed."""
    connection = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    connection.settimeout(CONNECT_TIMEOUT)
    try:
        connection.connect(address)
    except OSError as exc:
        connection.close()
        raise ServiceUnavailable(f"no render service at {address} ({exc.strerror or exc})") from None
    with connection:
        connection.settimeout(None)
        _send_json(connection, request)
        reply = _receive_json(connection)
    if reply is None:
        raise ServiceUnavailable(f"the render service at {address} closed the connection without an answer")
    if reply.get("error"):
        raise RuntimeError(reply["error"])
    return reply


def request_render(address, *, runs, profile, device_env, threads, avoid=()):
    """Have the service at ``address`` render ``runs``; return its outcomes ``[{"key", "status", "reason"}]``.

    ``runs`` and ``profile`` are the JSON texts of the render job's command line, ``device_env``
    the path of the workflow's device probe (or ``None``) and ``threads`` the cores Snakemake gave
    the job. ``avoid``: process ids of workers that must not render them (those that timed the same runs
    before: each replicate is a process of its own). Raises :class:`ServiceUnavailable` where nothing
    answers at ``address``.
    """
    return _ask(address, {"runs": runs, "profile": profile, "device_env": device_env, "threads": threads,
                          "watch": [os.getpid(), os.getppid()], "avoid": [pid for pid in avoid if pid]})["outcomes"]


def request_step(address, argv):
    """Have the service at ``address`` run the job step ``argv`` (``pipeline.jobs`` arguments) in a worker.

    Returns ``(exit status, output)``: what the step printed, for the job's log. Raises
    :class:`ServiceUnavailable` where nothing answers at ``address``.
    """
    step = _ask(address, {"step": list(argv)})["step"]
    return step["status"], step["output"]


# ----------------------------------------------------------------------------------------- service
WORKER_COMMAND = (sys.executable, "-m", "pipeline.worker")
"""How the service starts a worker (before ``--reply-fd N`` and the backends)."""


class Worker:
    """A worker process of the service and the pipes to it (see the module notes)."""

    def __init__(self, backends, *, cores, root, log_dir, command=WORKER_COMMAND):
        self.backends = tuple(backends)
        self.loaded = set()  # the backends it has rendered (or been started with): imported, compiled
        self.runs = 0
        self.untimed = False  # it ran untimed work (a step, an untimed render): it times nothing any more
        self.last_used = time.monotonic()
        reply_read, reply_write = os.pipe()
        log_dir.mkdir(parents=True, exist_ok=True)
        self.log_path = log_dir / f"worker-{'+'.join(self.backends)}-{time.time_ns()}.log"
        environment = {**os.environ, "NUMBA_NUM_THREADS": str(cores)}
        environment.pop(SERVICE_VARIABLE, None)
        self.spawned = time.monotonic()
        with open(self.log_path, "wb") as log:
            self.process = subprocess.Popen(
                [*command, "--reply-fd", str(reply_write), *self.backends],
                stdin=subprocess.PIPE, stdout=log, stderr=subprocess.STDOUT, pass_fds=(reply_write,),
                cwd=root, env=environment)
        os.close(reply_write)
        self.replies = os.fdopen(reply_read, "rb")
        self.startup = None  # seconds from spawn to ready, once known

    def send(self, payload):
        self.process.stdin.write(json.dumps(payload).encode() + b"\n")
        self.process.stdin.flush()

    def receive(self, deadline):
        """The worker's next message; ``None`` past ``deadline`` (monotonic); raises :class:`EOFError` if it died."""
        while True:
            remaining = None if deadline is None else deadline - time.monotonic()
            if remaining is not None and remaining <= 0:
                return None
            ready, _, _ = select.select([self.replies], [], [], remaining)
            if ready:
                line = self.replies.readline()
                if not line:
                    raise EOFError
                return json.loads(line)

    def memory_share(self):
        """The worker's resident memory as a share of the machine's (0 where unreadable)."""
        try:
            import psutil

            return psutil.Process(self.process.pid).memory_info().rss / psutil.virtual_memory().total
        except Exception:  # noqa: BLE001 - a worker that cannot be read is not retired for it
            return 0.0

    def close(self):
        """End the worker: end of input first (it exits between requests), killed if it does not."""
        if self.process.poll() is None:
            try:
                self.process.stdin.close()
                self.process.wait(5)
            except (OSError, subprocess.TimeoutExpired):
                self.kill()
        self.replies.close()

    def kill(self):
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait()
        for stream in (self.process.stdin, self.replies):
            try:
                stream.close()
            except OSError:
                pass


class RenderService:
    """The render service of one pipeline run: a socket, the workers, the time limit (see the module notes).

    Parameters
    ----------
    cores : int
        The cores Snakemake may use; each worker's Numba may use this many threads.
    root : path
        The project (every worker's working directory, as every job's).
    log_dir : path
        Where each worker's output goes: a folder per service (its process id), a file per worker.
        Folders of services no longer running are removed when a service starts.
    worker_command : sequence of str
        How a worker is started (:data:`WORKER_COMMAND`; tests give a stand-in).
    """

    def __init__(self, *, cores, root, log_dir, worker_command=WORKER_COMMAND):
        self.cores, self.root = int(cores), Path(root)
        self.log_dir = Path(log_dir) / str(os.getpid())
        self.worker_command = tuple(worker_command)
        self._idle = []
        self._busy = set()
        self._lock = threading.Lock()
        self._folder = Path(tempfile.mkdtemp(prefix="volbench-workers-"))
        self.socket_path = str(self._folder / "socket")
        self._server = None
        self._closed = False
        self.started = 0
        # Workers are started from one thread that lives as long as the service: the kernel ends a
        # worker when the thread that started it ends (PR_SET_PDEATHSIG), and a request's thread
        # ends with its request.
        self._spawner = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="volbench worker start")

    @property
    def address(self):
        """The value of :data:`SERVICE_VARIABLE` for the jobs."""
        return f"{socket.gethostname()}:{self.socket_path}"

    def start(self):
        import shutil

        for old in self.log_dir.parent.glob("*") if self.log_dir.parent.is_dir() else ():
            if old.name.isdigit() and old != self.log_dir and not _alive(int(old.name)):
                shutil.rmtree(old, ignore_errors=True)
        self._server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._server.bind(self.socket_path)
        self._server.listen(64)
        threading.Thread(target=self._accept, name="volbench render service", daemon=True).start()
        return self

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.close()

    def close(self):
        """Stop accepting, end every worker and remove the socket."""
        self._closed = True
        if self._server is not None:
            self._server.close()
        with self._lock:
            workers, self._idle = [*self._idle, *self._busy], []
            self._busy.clear()
        for worker in workers:
            worker.close()
        self._spawner.shutdown()
        Path(self.socket_path).unlink(missing_ok=True)
        try:
            self._folder.rmdir()
        except OSError:
            pass

    def _accept(self):
        while not self._closed:
            try:
                connection, _ = self._server.accept()
            except OSError:  # closed
                return
            threading.Thread(target=self._serve, args=(connection,), name="volbench render request",
                             daemon=True).start()

    def _serve(self, connection):
        with connection:
            try:
                request = _receive_json(connection)
                reply = {"step": self.step(request)} if "step" in request else {"outcomes": self.render(request)}
            except Exception as exc:  # noqa: BLE001 - the job reports it and fails, the service goes on
                reply = {"error": f"the render service failed: {type(exc).__name__}: {exc}"}
            try:
                _send_json(connection, reply)
            except OSError:  # the job was stopped meanwhile
                pass

    def _take(self, backends, avoid=(), *, timed):
        """An idle worker for ``backends`` whose process id is not in ``avoid``, or a new one: ``(worker, new)``.

        ``timed`` work takes only a worker that has done nothing untimed; untimed work takes one that has
        (a new one, marked so, where none is idle). Among those, the idle worker that has loaded the most of
        ``backends`` is taken, the most recently used among equals: one that has them all renders at once,
        another imports what it lacks on its first run of it. So a pipeline on two cores keeps about as many
        untimed workers as it runs untimed jobs side by side and a timed worker per process a timed run takes,
        each with every backend's compiled kernels.
        """
        avoid = set(avoid)
        with self._lock:
            allowed = [w for w in self._idle if w.process.pid not in avoid and w.untimed == (not timed)]
            if allowed:
                worker = max(allowed, key=lambda w: (len(set(backends) & w.loaded), w.last_used))
                self._idle.remove(worker)
                self._busy.add(worker)
                worker.loaded |= set(backends)
                return worker, False
        worker = self._spawner.submit(Worker, backends, cores=self.cores, root=self.root, log_dir=self.log_dir,
                                      command=self.worker_command).result()
        with self._lock:
            self._busy.add(worker)
            self.started += 1
        worker.loaded |= set(backends)
        worker.untimed = not timed
        return worker, True

    def _give_back(self, worker, healthy):
        retire = (not healthy or worker.runs >= MAX_RUNS_PER_WORKER or worker.memory_share() > MAX_WORKER_MEMORY)
        closing = []
        with self._lock:
            self._busy.discard(worker)
            if retire or self._closed:
                closing.append(worker)
            else:
                worker.last_used = time.monotonic()
                self._idle.append(worker)
                while len(self._idle) > MAX_IDLE_WORKERS:
                    oldest = min(self._idle, key=lambda w: w.last_used)
                    self._idle.remove(oldest)
                    closing.append(oldest)
        for old in closing:
            old.close()

    def step(self, request):
        """Run one job step of :func:`request_step` in a worker: ``{"status", "output"}``.

        Any idle worker does (the step imports what it lacks once per worker); no time limit, as for
        the step's own process.
        """
        worker, new = self._take((), timed=False)
        answer = None
        try:
            if not new or worker.receive(None) is not None:
                worker.send(request)
                answer = worker.receive(None)
        except (EOFError, OSError, ValueError):
            pass
        finally:
            if answer is None:
                worker.kill()
            self._give_back(worker, healthy=answer is not None)
        if answer is None:
            return {"status": 1, "output": f"volbench: the worker running {' '.join(request['step'][:1])} died "
                                           f"(exit status {worker.process.returncode}); its log: {worker.log_path}\n"}
        return answer["step"]

    def render(self, request):
        """Render one request of :func:`request_render` in a worker; its outcomes."""
        from pipeline.execution import record_unfinished
        from pipeline.experiments import Profile, Run
        from pipeline.records import run_record_path

        runs = Run.list_from_json(request["runs"])
        profile = Profile.from_json(request["profile"])
        for run in runs:  # an old record must not pass for this attempt's
            run_record_path(profile.results, run.experiment, run.id).unlink(missing_ok=True)
        backends = tuple(sorted({run.backend for run in runs}))
        worker, new = self._take(backends, avoid=request.get("avoid", ()), timed=any(run.timed for run in runs))
        limit = profile.render_time_limit
        started = worker.spawned if new else time.monotonic()
        deadline = None if limit is None else started + limit * len(runs)
        answer, timed_out = None, False
        try:
            ready = worker.receive(deadline) if new else True
            if ready is not None and new:
                worker.startup = time.monotonic() - worker.spawned
            if ready is not None:
                worker.send({**request, "watch": [os.getpid(), *request.get("watch", [])],
                             "worker": {"new": new, "startup": worker.startup, "pid": worker.process.pid,
                                        "runs_before": worker.runs}})
                answer = worker.receive(deadline)
            timed_out = answer is None
        except (EOFError, OSError, ValueError):  # the worker died (a crash in native code, a kill)
            pass
        finally:
            worker.runs += len(runs)
            if answer is None:
                worker.kill()
            self._give_back(worker, healthy=answer is not None)
        if answer is not None:
            return answer["outcomes"]
        records = record_unfinished(runs, profile=profile, device_environment=device_environment(request),
                                    killed=timed_out, exitcode=worker.process.returncode, started=started)
        return [{"key": run.key, "status": record["status"], "reason": record["reason"]}
                for run, record in zip(runs, records)]


def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def device_environment(request):
    """The device facts of the workflow's probe that a record carries (``gl_*``, ``cl_*``)."""
    path = request.get("device_env")
    if not path:
        return {}
    try:
        facts = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return {}
    return {key: value for key, value in facts.items() if key.startswith(("gl_", "cl_"))}
