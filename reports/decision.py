"""The index's decision panel: which technique to use, how fast, how accurate, and where it breaks.

Built from the runs that compare every backend's settings with the reference (the experiments with
``overview = True``, :func:`technique_rows`), per kind of scene (opaque surfaces,
semi-transparent material, maximum intensity projection, iso-surfaces): each technique's Pareto
front over its settings (the settings no other setting of the same technique beats in both time
and PSNR), its fastest setting that reaches the accuracy bar, and where the stability atlas found
it breaking. The reference is the ground truth, not a contender, and is left out. A technique that
made no frame for a kind says why in its row rather than vanishing.

The banner says where the timings were taken: GL frames on the OpenGL renderer the runs recorded
(llvmpipe is Mesa's CPU rasterizer, so "GPU" techniques then run on the CPU cores), OpenCL frames on
the recorded device, CPU backends on the recorded CPU.
"""

import numpy as np
import pandas as pd

from reports import takeaways
from reports.plots import pareto_mask

__all__ = ["KIND_WORDS", "pareto_front", "panel", "technique_label", "technique_rows", "timing_banner"]

KIND_WORDS = {
    "opaque": "opaque surfaces",
    "semi-transparent": "semi-transparent material",
    "mip": "maximum intensity projection",
    "iso": "iso-surface",
}
"""A scene kind (the ``kind`` tag of the overview runs) in words."""

REFERENCE = "reference"


def technique_label(backend, setting):
    """``"gl-raycast (step 0.5 voxel)"``: a backend with its setting in words (``"default"``: the name alone)."""
    return f"{backend} ({takeaways.setting_words(setting)})" if setting and setting != "default" else str(backend)


def technique_rows(frame):
    """One row per run compared with a reference: technique, data set, time (s), PSNR, SSIM, FLIP.

    ``frame`` is tidy results (one row per run and view); views are reduced to the median time
    and metrics, the fastest frame's minimum and the slowest frame's maximum. ``timed_with`` names the
    job that timed the run (its interleave group, or the run alone): two runs' times compare like with
    like only within one; ``disturbed`` says whether any of its views was timed on a disturbed machine.
    """
    needed = {"status", "reference", "time_total", "psnr"}
    if frame.empty or not needed <= set(frame.columns):
        return pd.DataFrame(columns=["technique", "backend", "setting", "dataset", "time_total", "time_min",
                                     "time_max", "psnr", "ssim", "flip", "record", "exr", "run", "experiment", "kind",
                                     "timed_with", "disturbed"])
    rows = frame[(frame.status == "ok") & frame.reference.notna()].copy()
    rows["setting"] = rows["setting"].fillna("") if "setting" in rows else ""
    rows["dataset"] = rows["scene"] if "scene" in rows else rows.get("dataset", "")
    for column in ("time_total_min", "time_total_max", "ssim", "flip", "record", "exr", "kind", "interleave",
                   "info_disturbed"):
        if column not in rows:
            rows[column] = np.nan
    out = []
    for (experiment, run), group in rows.groupby(["experiment", "run"], sort=False):
        first = group.iloc[0]
        out.append({
            "technique": technique_label(first.backend, first.setting), "backend": first.backend,
            "setting": first.setting, "dataset": first.dataset,
            "time_total": float(group.time_total.median()), "time_min": float(group.time_total_min.min()),
            "time_max": float(group.time_total_max.max()), "psnr": float(group.psnr.median()),
            "ssim": float(group.ssim.median()), "flip": float(group.flip.median()),
            "record": first.record, "exr": first.exr, "run": run, "experiment": experiment,
            "kind": first.kind if pd.notna(first.kind) else first.dataset,
            "timed_with": f"{experiment}/{first.interleave}" if isinstance(first.interleave, str) and first.interleave
            else f"{experiment}/{run}",
            "disturbed": bool(group.info_disturbed.map(lambda text: isinstance(text, str) and bool(text.strip())).any()),
        })
    return pd.DataFrame(out)


def pareto_front(rows, *, time_col="time_total", accuracy_col="psnr"):
    """The rows of ``rows`` that no other row beats: none is both at least as fast and at least as
    accurate while strictly better in one of the two. Sorted from fastest to slowest.

    Parameters
    ----------
    rows : pandas.DataFrame
        With ``time_col`` (lower is better) and ``accuracy_col`` (higher is better).

    Returns
    -------
    pandas.DataFrame
    """
    front = rows[pareto_mask(rows[time_col], rows[accuracy_col])]
    return front.sort_values(time_col, kind="stable")


def device_family(backend):
    """``"gl"``, ``"cl"`` or ``"cpu"``: the device that times ``backend``'s frames (VTK's CPU ray caster
    draws through OpenGL, but its rays are cast on the CPU)."""
    if backend.startswith("gl-") or backend == "vtk-gpu":
        return "gl"
    if backend.startswith("cl-"):
        return "cl"
    return "cpu"


def timing_banner(runs_df):
    """Where the timings of ``runs_df`` were taken, one entry per kind of device.

    Returns
    -------
    list of dict
        ``{"what", "where", "software"}``: the backends (words), the device they ran on (from the
        runs' own records) and whether that device is a CPU standing in for a GPU (Mesa llvmpipe,
        PoCL on a CPU), whose frame times say nothing about GPUs.
    """
    if runs_df is None or runs_df.empty or "backend" not in runs_df:
        return []
    ok = runs_df[runs_df.status == "ok"] if "status" in runs_df else runs_df
    timed = ok[ok.backend != REFERENCE]
    out = []
    for family in ("gl", "cl", "cpu"):
        rows = timed[[device_family(b) == family for b in timed.backend]]
        if rows.empty:
            continue
        backends = ", ".join(sorted(set(rows.backend)))
        cpus = _values(rows, "cpu_model")
        cores = _values(rows, "usable_cpus") or _values(rows, "cpu_cores")
        cpu_words = f"{', '.join(cpus) or 'an unrecorded CPU'}" + (
            f" ({', '.join(str(int(float(c))) for c in cores)} cores)" if cores else "")
        if family == "gl":
            device = rows.get("gl_renderer", pd.Series(np.nan, index=rows.index))
            if "vtk_gl_renderer" in rows:
                device = device.where(~rows.backend.eq("vtk-gpu"), rows.vtk_gl_renderer)
            devices = sorted({str(d) for d in device.dropna()})
            software = any("llvmpipe" in d.lower() or "softpipe" in d.lower() for d in devices) or \
                bool(_values(rows, "gl_software_rasterizer") == ["True"])
            where = ", ".join(devices) or "an unrecorded OpenGL device"
            if software:
                where += f": Mesa's software rasterizer, running on {cpu_words}, not a GPU"
            out.append({"what": f"OpenGL ({backends})", "where": where, "software": software})
        elif family == "cl":
            devices = _values(rows, "cl_device")
            types = _values(rows, "cl_device_type")
            software = any("CPU" in t for t in types)
            where = ", ".join(devices) or "an unrecorded OpenCL device"
            if software:
                where += f" (PoCL on {cpu_words}, not a GPU)"
            out.append({"what": f"OpenCL ({backends})", "where": where, "software": software})
        else:
            out.append({"what": f"CPU ({backends})", "where": cpu_words, "software": False})
    return out


def _values(rows, column):
    if column not in rows:
        return []
    return sorted({str(v) for v in rows[column].dropna() if str(v) not in ("", "nan", "None")})


def panel(overview, runs, *, psnr_min=takeaways.PSNR_GOOD, failures=None, stated_above=()):
    """The decision panel's content, per scene of the overview runs.

    Parameters
    ----------
    overview : pandas.DataFrame
        :func:`technique_rows` of the overview experiments (times in seconds), with a
        ``kind`` column (the scene's kind; the scene's name where the runs did not tag one).
    runs : pandas.DataFrame
        :func:`reports.outcomes.per_run` of the same experiments: the runs that made no frame,
        with their status and reason.
    psnr_min : float
        The accuracy bar (dB).
    failures : dict, optional
        ``{backend: phrase}`` completing "fails when …" (the stability atlas); a backend without
        an entry gets "not in the atlas".
    stated_above : collection of str
        Backends whose failure the page states at its top: their rows refer to it instead of repeating
        the message.

    Returns
    -------
    list of dict
        One per scene: ``scene``, ``kind`` (words), ``points`` (every technique's settings with a
        ``front`` flag) and ``table`` (one row per technique: ``backend``, ``setting``, ``ms``,
        ``range``, ``psnr``, ``accurate``, ``fails_when``, ``status``, ``run``, ``record``, ``timed_with``,
        ``disturbed``).
    """
    failures = dict(failures or {})
    out = []
    if overview.empty:
        return out
    contenders = overview[overview.backend != REFERENCE].copy()
    for scene, rows in contenders.groupby("dataset", sort=False):
        kind = str(rows.kind.iloc[0]) if "kind" in rows and pd.notna(rows.kind.iloc[0]) else str(scene)
        rows = rows.copy()
        rows["front"] = False
        table = []
        for backend, settings in rows.groupby("backend", sort=False):
            front = pareto_front(settings)
            rows.loc[front.index, "front"] = True
            accurate = settings[settings.psnr >= psnr_min]
            chosen = accurate.loc[accurate.time_total.idxmin()] if not accurate.empty else \
                settings.loc[settings.psnr.idxmax()]
            table.append({
                "backend": backend, "setting": takeaways.setting_words(chosen.setting or "default"),
                "ms": takeaways.number(chosen.time_total * 1e3),
                "range": f"{takeaways.number(chosen.time_min * 1e3)}–{takeaways.number(chosen.time_max * 1e3)}",
                "psnr": takeaways.number(chosen.psnr), "accurate": not accurate.empty,
                "time": float(chosen.time_total), "fails_when": failures.get(backend, "not in the atlas"),
                "status": "" if not accurate.empty else f"no setting reaches {takeaways.number(psnr_min)} dB",
                "run": chosen.run, "record": chosen.record, "timed_with": chosen.get("timed_with"),
                "disturbed": bool(chosen.get("disturbed", False)),
            })
        table.sort(key=lambda r: (not r["accurate"], r["time"]))
        table.extend(_absent(runs, scene, set(rows.backend), failures, stated_above))
        out.append({"scene": scene, "kind": KIND_WORDS.get(kind, kind), "points": rows, "table": table})
    return out


def _absent(runs, scene, present, failures, stated_above):
    """Rows for the backends whose runs of ``scene`` made no frame, with the reason."""
    if runs is None or runs.empty or "scene" not in runs:
        return []
    rows = []
    missing = runs[(runs.scene == scene) & (runs.backend != REFERENCE) & ~runs.backend.isin(present)]
    for backend, group in missing.groupby("backend", sort=False):
        reason = next((r for r in group.reason if r), "no reason recorded")
        planned = bool((group.status == "skipped").all())
        if backend in stated_above:
            reason = "stated at the top of this page"
        rows.append({"backend": backend, "setting": "", "ms": "", "range": "", "psnr": "", "accurate": False,
                     "time": np.inf, "fails_when": failures.get(backend, "not in the atlas"),
                     "status": ("lacks this kind of scene: " if planned else "made no frame here: ") + reason,
                     "run": group.run.iloc[0], "record": group.record.iloc[0] if "record" in group else None})
    return rows

