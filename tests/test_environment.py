from pipeline import environment


def test_host_environment_has_the_required_facts():
    env = environment.host_environment()
    for key in ("cpu_model", "cpu_cores", "python", "git_commit", "pkg_numpy", "pkg_numba", "pkg_snakemake"):
        assert key in env, key
    assert env["cpu_cores"] >= 1
    assert env["pkg_numpy"] is not None


def test_git_commit_outside_a_repository_is_unknown(tmp_path):
    assert environment.git_commit(tmp_path) == "unknown"


def test_device_probes_report_failures_as_values(monkeypatch):
    import builtins

    from renderers.cl import context as cl_context
    from renderers.gl import context as gl_context

    # The context modules remember a failure for the process: keep this one out of later tests.
    monkeypatch.setattr(gl_context, "_SHARED", gl_context._Shared())
    monkeypatch.setattr(cl_context, "_STATE", {"pid": None, "devices": {}, "errors": {}})
    monkeypatch.delenv(cl_context.DEVICE_VARIABLE, raising=False)
    real_import = builtins.__import__

    def no_gl(name, *args, **kwargs):
        if name in ("moderngl", "pyopencl"):
            raise ImportError(f"{name} hidden by the test")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_gl)
    facts = environment.probe_devices()
    assert facts["gl_renderer"] is None and facts["gl_error"] == "moderngl cannot be imported: moderngl hidden by the test"
    assert facts["cl_device"] is None and facts["cl_error"] == "pyopencl cannot be imported: pyopencl hidden by the test"


def test_device_probes_report_the_devices_the_backends_choose(monkeypatch):
    """The probes ask the backends' context modules; they make no choice of their own."""
    from renderers.cl import context as cl_context
    from renderers.gl import context as gl_context

    chosen_cl = {"cl_device": "pthread-skylake-avx512", "cl_pocl_version": "3.1+debian", "cl_llvm_version": "15.0.6",
                 "cl_refused": "1:0 pthread (Portable Computing Language: PoCL 3.0-rc2, LLVM 14.0.6): error: unknown "
                               "target CPU 'generic'"}
    chosen_gl = {"gl_renderer": "NVIDIA H100", "gl_device_index": 1, "gl_devices": "0: llvmpipe; 1: NVIDIA H100"}
    asked = []
    monkeypatch.setattr(cl_context, "probe", lambda selector: asked.append(selector) or (True, ""))
    monkeypatch.setattr(cl_context, "environment", lambda selector: {**chosen_cl, "selector": selector})
    monkeypatch.setattr(gl_context, "probe", lambda: (True, ""))
    monkeypatch.setattr(gl_context, "device_facts", lambda: chosen_gl)
    monkeypatch.setenv(cl_context.DEVICE_VARIABLE, "pocl")
    assert environment.probe_devices() == {**chosen_gl, **chosen_cl, "selector": "pocl"} and asked == ["pocl"]
    monkeypatch.setattr(cl_context, "probe", lambda selector: (False, "no OpenCL device here builds a kernel: ..."))
    monkeypatch.setattr(gl_context, "probe", lambda: (False, "no OpenGL 4.3 context through headless EGL: ..."))
    facts = environment.probe_devices()
    assert facts["cl_error"] == "no OpenCL device here builds a kernel: ..." and facts["cl_device"] is None
    assert facts["gl_error"] == "no OpenGL 4.3 context through headless EGL: ..." and facts["gl_renderer"] is None


def test_a_run_records_the_slurm_job_it_ran_in():
    inside = environment.slurm_job({"SLURM_CLUSTER_NAME": "lab", "SLURM_JOB_ID": "42", "SLURM_JOB_PARTITION": "gpu",
                                    "SLURM_CPUS_PER_TASK": "16", "SLURM_JOB_GPUS": "0", "HOME": "/root"})
    assert inside == {"slurm_cluster": "lab", "slurm_job_id": "42", "slurm_partition": "gpu",
                      "slurm_cpus_per_task": "16", "slurm_gpus": "0"}
    assert environment.slurm_job({"SLURM_JOB_GPUS": "0,1", "SLURM_STEP_GPUS": "1"})["slurm_gpus"] == "1"
    assert set(environment.slurm_job({})) == set(environment.SLURM_FACTS)
    assert all(value is None for value in environment.slurm_job({"SLURM_JOB_ID": ""}).values())
    env = environment.host_environment()
    assert set(environment.SLURM_FACTS) <= set(env)
    assert 1 <= env["usable_cpus"] <= env["cpu_cores"]


def test_node_names_keep_clusters_and_hand_started_runs_apart():
    assert environment.node_name({"hostname": "node001"}) == "node001"
    assert environment.node_name({"hostname": "node001", "slurm_cluster": "lab"}) == "lab/node001"
    assert environment.node_name({"hostname": "node001", "slurm_cluster": None}) == "node001"
    assert environment.node_name({"hostname": "node001", "slurm_cluster": float("nan")}) == "node001"
    assert environment.node_name({}) is None
    assert environment.node_name({"hostname": float("nan")}) is None
