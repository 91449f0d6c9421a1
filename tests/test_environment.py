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
