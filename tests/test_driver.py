"""The Snakemake of ``volbench run`` (pipeline.driver): it sleeps while jobs run, and runs the render service."""

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

# 200 short jobs; then one that takes every core, sleeps and reads the CPU time of the process running
# Snakemake (its ancestor) over its sleep, while 100 more jobs wait for the cores, as render jobs wait
# behind a timed one. Under a job-rate limiter every finished job left a timer that re-armed itself
# while jobs waited, so after 200 jobs the scheduler made passes over the waiting jobs all the time.
SNAKEFILE = textwrap.dedent('''
    rule all:
        input: "idle.txt", expand("waiting/{i}", i=range(100))

    rule quick:
        output: "quick/{i}"
        shell: "touch {output}"

    rule idle:
        input: expand("quick/{i}", i=range(200))
        output: "idle.txt"
        threads: workflow.cores
        priority: 1
        shell: "{python} {measure} {output}"

    rule waiting:
        input: expand("quick/{i}", i=range(200))
        output: "waiting/{i}"
        shell: "touch {output}"
''')

MEASURE = textwrap.dedent('''
    import os, sys, time
    from pipeline import disturbance
    driver = disturbance.orchestrator_pids()[-1]
    def cpu():
        with open(f"/proc/{driver}/stat") as f:
            after = f.read().rsplit(")", 1)[1].split()
        return (int(after[11]) + int(after[12])) / os.sysconf("SC_CLK_TCK")
    time.sleep(1.0)  # Snakemake's own work for the job that just ended
    before, began = cpu(), time.monotonic()
    time.sleep(11.0)  # longer than the 10 s timespan of the limit volbench run used to give
    cores = (cpu() - before) / (time.monotonic() - began)
    open(sys.argv[1], "w").write(f"{cores}")
''')


@pytest.mark.integration
def test_the_orchestrator_uses_no_cpu_while_a_job_runs(tmp_path):
    measure = tmp_path / "measure.py"
    measure.write_text(MEASURE)
    (tmp_path / "Snakefile").write_text(SNAKEFILE.replace("{python}", sys.executable).replace("{measure}", str(measure)))
    done = subprocess.run([sys.executable, "-m", "pipeline.driver", "--snakefile", str(tmp_path / "Snakefile"),
                           "--directory", str(tmp_path), "--cores", "2"],
                          cwd=ROOT, capture_output=True, text=True, timeout=600,
                          env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
    assert done.returncode == 0, done.stderr[-3000:]
    cores = float((tmp_path / "idle.txt").read_text())
    # Snakemake's default limiter (100/1s) measured 0.65 cores here, the 1000000/10s volbench run gave it 0.10.
    assert cores <= 0.05, f"the process running Snakemake used {cores:.3f} cores while a job slept"
    # One progress line, not Snakemake's account of every job.
    assert "302 of 302 steps done" in done.stderr
    assert "rule quick" not in done.stderr + done.stdout
