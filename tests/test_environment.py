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

    real_import = builtins.__import__

    def no_gl(name, *args, **kwargs):
        if name in ("moderngl", "pyopencl"):
            raise ImportError(f"{name} hidden by the test")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_gl)
    facts = environment.probe_devices()
    assert facts["gl_renderer"] is None and "hidden by the test" in facts["gl_error"]
    assert facts["cl_device"] is None and "hidden by the test" in facts["cl_error"]


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
