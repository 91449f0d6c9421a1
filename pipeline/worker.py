"""A warm worker of the render service (:mod:`pipeline.workers`): ``python -m pipeline.worker --reply-fd N BACKEND...``.

It imports the rendering once and serves request after request on its standard input, answering on
the pipe ``N``: runs to render (:func:`pipeline.execution.execute_in_process`) or a job step to run
(:mod:`pipeline.jobs`). Apart from the service, which starts it by name and never imports it: the
service and the jobs' client side of it sit below :mod:`pipeline.jobs`, this process above it.
"""

import json
import os
import signal
import sys

from pipeline.workers import device_environment


def _die_with_parent():
    """Have the kernel kill this process when the service's process ends (Linux), however it ends.

    Strictly: when the thread that started it ends, so the service starts workers from one thread
    that lives as long as it does.
    """
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def _serve_requests(reply):
    """The worker's loop: one request a line on standard input, one answer a line on ``reply``."""
    import numba

    from pipeline import disturbance
    from pipeline.execution import execute_in_process
    from pipeline.experiments import Profile, Run

    reply({"ready": True})
    for line in sys.stdin.buffer:
        request = json.loads(line)
        if "step" in request:
            reply({"step": _run_step(request["step"])})
            continue
        runs = Run.list_from_json(request["runs"])
        profile = Profile.from_json(request["profile"])
        numba.set_num_threads(max(1, min(int(request.get("threads") or 1), numba.config.NUMBA_NUM_THREADS)))
        disturbance.watch(request.get("watch", []))
        records = execute_in_process(runs, profile=profile, device_environment=device_environment(request),
                                     harness={"process": "worker", **request.get("worker", {})})
        reply({"outcomes": [{"key": run.key, "status": record["status"], "reason": record["reason"]}
                            for run, record in zip(runs, records)]})


def _run_step(argv):
    """Run ``pipeline.jobs`` step ``argv`` here: ``{"status", "output"}`` (its printed output, a traceback
    where it failed), as its own process would have exited and printed."""
    import contextlib
    import io
    import traceback

    from pipeline import jobs

    output = io.StringIO()
    status = 0
    with contextlib.redirect_stdout(output), contextlib.redirect_stderr(output):
        try:
            jobs.main(argv)
        except SystemExit as exc:  # argparse's refusal of its arguments
            status = exc.code if isinstance(exc.code, int) else 1
        except Exception:  # noqa: BLE001 - the job fails with it, the worker goes on
            traceback.print_exc()
            status = 1
    return {"status": status, "output": output.getvalue()}


def main(argv=None):
    """``python -m pipeline.worker --reply-fd N BACKEND...``: a worker of :class:`RenderService`."""
    import argparse

    parser = argparse.ArgumentParser(prog="python -m pipeline.worker", description=__doc__.splitlines()[0])
    parser.add_argument("--reply-fd", type=int, required=True)
    parser.add_argument("backends", nargs="*", help="backends to import before the first request")
    args = parser.parse_args(argv)
    _die_with_parent()
    replies = os.fdopen(args.reply_fd, "wb")

    def reply(payload):
        replies.write(json.dumps(payload).encode() + b"\n")
        replies.flush()

    import renderers

    for backend in args.backends:
        try:
            renderers.backend_class(backend)
        except Exception:  # noqa: BLE001 - an unavailable backend's runs record why when they run
            pass
    try:
        _serve_requests(reply)
    except KeyboardInterrupt:  # Ctrl-C reached the whole process group: the pipeline is stopping
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
