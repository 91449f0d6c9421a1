"""The experiment model: profiles, runs to execute, claims as checks, experiments and papers.

An :class:`Experiment` is named ``<first author><year>-<what>`` (``volbench-...`` for our own).
Given a :class:`Profile` it lists its :class:`Run` s; the pipeline executes each run as one
Snakemake job (image + JSON record), compares it with its reference run, and collects everything
into tidy CSV (one row per run and view). The experiment then checks its claims on that table and
lays out its part of the report.
"""

import hashlib
import json
import re
from dataclasses import dataclass, field

from core.errors import InputError
from core.papers import PAPERS
from core.validation import check_positive_int, check_scalar
from core.yaml_io import load_yaml_file
from datasets import MIN_SIZE

RUN_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]*$")


def canonical_json(value):
    """JSON with sorted keys and no whitespace: the basis of stable hashes."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), default=str)


SCALES = ("smoke", "default", "full")
"""The sizes an experiment knows its own settings for (:attr:`Experiment.scales`): a few minutes for CI,
every experiment at reduced size, paper scale."""

SIZES = {"smoke": {"volume_size": 32, "image_size": 48}, "default": {"volume_size": 128, "image_size": 256},
         "full": {"volume_size": 256, "image_size": 512}}
"""The phantom size (voxels along its longest axis) and the image size (pixels) most experiments take at each scale
(:func:`scaled`'s default base)."""


def scaled(*, base=SIZES, smoke=None, default=None, full=None):
    """An experiment's own settings for each scale (:attr:`Experiment.scales`): ``base``'s, with those given for a
    scale added to them or replacing them.

    Parameters
    ----------
    base : dict
        ``{scale: {key: value}}``: the settings the experiment shares with others (default :data:`SIZES`).
    smoke, default, full : dict, optional
        The experiment's own settings at that scale of :data:`SCALES`, over ``base``'s.

    Returns
    -------
    dict
        ``{scale: {key: value}}``, a new mapping: ``base`` is not changed.

    Examples
    --------
    >>> scaled(smoke={"orbit": 0}, full={"image_size": 1024})["full"]
    {'volume_size': 256, 'image_size': 1024}
    """
    own = {"smoke": smoke, "default": default, "full": full}
    return {scale: {**base.get(scale, {}), **(own[scale] or {})} for scale in SCALES if scale in base or own[scale]}


PROFILE_REQUIRED = ("name", "scale", "volume_size", "image_size", "warmup", "repeat", "results", "render_time_limit")
"""The keys every profile file sets. A default for any of them would silently change what is measured
(sizes, frames, the time limit, where ``null`` says "no limit" explicitly) or put two profiles'
records in one results folder."""


@dataclass(frozen=True)
class Profile:
    """A pipeline profile (``config/<name>.yaml``).

    Every value is checked when the profile is made, so a wrong one is an error naming the key
    before any work starts. A profile file (:meth:`from_mapping`, :meth:`load`) must set the keys
    of :data:`PROFILE_REQUIRED`; the others have defaults that change no measurement:
    ``experiments`` ("all": it chooses which experiments run, not what one measures, and a dry run
    lists them), ``settings`` (none: each experiment's own defaults), ``real_data`` (``None``:
    ``$VOLBENCH_REAL_DATA``, else ``../shared/data/real``; the report names the folder read) and
    ``cache`` (phantoms are cached under a key of their generator's parameters, so profiles share
    it without mixing). Made in code (tests), every field but ``name`` has a default.

    Parameters
    ----------
    name : str
    scale : {"smoke", "default", "full"}
        Whose settings each experiment takes (:attr:`Experiment.scales`): its few-minutes CI runs,
        its reduced-size runs or the paper's sizes. ``settings`` overrides single keys.
    volume_size : int
        Phantom size (voxels along the longest axis) where an experiment gives none.
    image_size : int
        Image width and height where an experiment gives none.
    warmup, repeat : int
        Frames for the timing harness: ``warmup`` >= 0 untimed, then ``repeat`` >= 1 timed.
    min_time : float
        Seconds of timed frames per view of a timed run, at least: short frames are repeated until
        they fill it (:mod:`pipeline.timing`). 0: ``repeat`` frames only.
    experiments : list of str or "all"
    settings : dict
        Per-experiment overrides of the experiments' own settings for ``scale``, keyed by
        experiment name.
    real_data : str, optional
        Folder of the real scans (``None``: the datasets default).
    results : str
        Output folder of the pipeline.
    cache : str
        Folder of generated phantoms (kept across profiles and ``make clean``).
    render_time_limit : float, optional
        Seconds one render job (every view and frame of one run) may take; past it the job is
        killed and the run recorded as failed, so one bad job cannot stall the pipeline.
        ``None`` (``null`` in a profile file, where it must be set): no limit.
    replicates : int
        Processes that time each timed run (or interleave group), one after another, each with its own
        warm-up and frames: the process is the unit of replication, and a claim's interval is drawn over
        processes, then frames (:mod:`~pipeline.experiments.kit.intervals`). 1 (the default): one
        process, an interval that cannot show the spread between two runs, and says so.
    """

    name: str
    scale: str = "default"
    volume_size: int = 64
    image_size: int = 128
    warmup: int = 1
    repeat: int = 3
    experiments: object = "all"
    settings: dict = field(default_factory=dict)
    real_data: str | None = None
    results: str = "results"
    cache: str = ".cache/volumes"
    render_time_limit: float | None = None
    min_time: float = 0.0
    replicates: int = 1

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise InputError(f"profile name: expected a non-empty string, got {self.name!r}")
        where = f"profile {self.name!r}"
        if self.scale not in SCALES:
            raise InputError(f"{where} scale: expected one of {', '.join(SCALES)} (whose settings the experiments "
                             f"take), got {self.scale!r}")
        check_positive_int(self.volume_size, name=f"{where} volume_size (voxels along a phantom's longest axis)",
                           minimum=MIN_SIZE)
        check_positive_int(self.image_size, name=f"{where} image_size (pixels)")
        check_positive_int(self.warmup, name=f"{where} warmup (untimed frames)", minimum=0)
        check_positive_int(self.repeat, name=f"{where} repeat (timed frames)")
        check_positive_int(self.replicates, name=f"{where} replicates (processes per timed run)")
        if isinstance(self.min_time, (bool, str)):
            raise InputError(f"{where} min_time: expected seconds (a number >= 0), got {self.min_time!r}")
        check_scalar(self.min_time, name=f"{where} min_time (seconds of timed frames per view)", low=0)
        names = self.experiments
        if names != "all" and (not isinstance(names, (list, tuple)) or not all(isinstance(n, str) and n for n in names)):
            raise InputError(f"{where} experiments: expected 'all' or a list of names, got {names!r}")
        if not isinstance(self.settings, dict):
            raise InputError(f"{where} settings: expected a mapping of experiment names, "
                             f"got {type(self.settings).__name__}")
        for key in ("results", "cache", "real_data"):
            value = getattr(self, key)
            if not (isinstance(value, str) and value) and not (key == "real_data" and value is None):
                raise InputError(f"{where} {key}: expected a folder name, got {value!r}"
                                 + ("; null reads the default folder" if key == "real_data" else ""))
        limit = self.render_time_limit
        if limit is not None:
            if isinstance(limit, (bool, str)):  # YAML's yes/no or a quoted number: a typo, not seconds
                raise InputError(f"{where} render_time_limit: expected seconds (a number > 0) or null for no "
                                 f"limit, got {limit!r}")
            object.__setattr__(self, "render_time_limit", check_scalar(
                limit, name=f"{where} render_time_limit (seconds; null for no limit)", low=0, low_open=True))

    @classmethod
    def from_mapping(cls, mapping):
        """The profile a mapping (a profile file, Snakemake's config) describes; see :data:`PROFILE_REQUIRED`."""
        if not isinstance(mapping, dict):
            raise InputError(f"profile: expected a mapping of keys ({', '.join(PROFILE_REQUIRED)}, ...), "
                             f"got {type(mapping).__name__}")
        known = set(cls.__dataclass_fields__)
        unknown = set(mapping) - known
        if unknown:
            raise InputError(f"profile: unknown keys {sorted(unknown)}; allowed: {sorted(known)}")
        missing = [key for key in PROFILE_REQUIRED if key not in mapping]
        if missing:
            where = f"profile {mapping['name']!r}" if "name" in mapping else "profile"
            raise InputError(f"{where}: {', '.join(missing)} not set; every profile sets "
                             f"{', '.join(PROFILE_REQUIRED)} (as config/default.yaml does; "
                             "render_time_limit: null means no limit)")
        return cls(**mapping)

    @classmethod
    def load(cls, path):
        """The profile of a YAML file, read strictly (:func:`core.yaml_io.load_yaml_file`) and checked."""
        return cls.from_mapping(load_yaml_file(path, what="profile"))

    @classmethod
    def from_json(cls, text):
        """The profile of a job's ``--profile`` argument (JSON of its fields, as the Snakefile writes it)."""
        return cls.from_mapping(json.loads(text))

    def setting(self, experiment, key, default):
        """What ``experiment`` takes for ``key`` in this profile.

        The profile's ``settings[experiment][key]`` where it sets one, else the experiment's own
        setting for this profile's :attr:`scale` (:attr:`Experiment.scales`), else ``default``.
        ``experiment`` is an :class:`Experiment` (or, for a profile's own overrides alone, its name).
        """
        name = experiment if isinstance(experiment, str) else experiment.name
        overrides = self.settings.get(name, {})
        if key in overrides:
            return overrides[key]
        own = {} if isinstance(experiment, str) else experiment.scales.get(self.scale, {})
        return own.get(key, default)


@dataclass(frozen=True)
class Run:
    """One backend rendering one scene over a list of views: one Snakemake job.

    Parameters
    ----------
    experiment : str
    id : str
        Unique within the experiment; safe as a file name.
    backend : str
        Registry name.
    scene : dict
        Scene mapping (see :mod:`pipeline.scene_io`).
    views : tuple of dict
        Camera overrides, each with a ``"view"`` name (e.g. ``{"view": "az30", "azimuth": 30}``).
    options : dict
        Backend options.
    reference : str, optional
        Id of the run in the same experiment whose images are the ground truth for this one.
    warmup, repeat : int
    tags : dict
        Extra CSV columns describing the run (data set, preset, swept parameter, ...).
    statistics : dict, optional
        A volume entry (the scene format) whose data-set statistics the record should carry,
        e.g. the rendered phantom at its paper size.
    min_time : float
        Seconds of timed frames at least, per view (:mod:`pipeline.timing`); more frames until then.
    interleave : str, optional
        Runs of one experiment with the same ``interleave`` name are timed together in one job, their
        frames alternating view by view (:func:`pipeline.timing.measure_together`): a claim comparing
        them takes its ratio round by round, with an interval. The runs of a group share their frames:
        all timed, or all one untimed frame (then the job renders them in turn, one job start for many
        pictures). A group whose backends render through different OpenGL stacks is timed in a process
        per stack, one after the other (:func:`pipeline.experiments.stack_parts`): its runs of different
        stacks are compared by process, not round by round.
    replicates : int
        Processes that time the run one after another (the profile's ``replicates`` for a timed run, 1
        for an untimed one): its job renders it, or its interleave group, once in each, the group's
        order reversed every other process, and its record keeps each process's frames.
    """

    experiment: str
    id: str
    backend: str
    scene: dict
    views: tuple
    options: dict = field(default_factory=dict)
    reference: str | None = None
    warmup: int = 1
    repeat: int = 3
    tags: dict = field(default_factory=dict)
    statistics: dict | None = None
    min_time: float = 0.0
    interleave: str | None = None
    replicates: int = 1

    def __post_init__(self):
        if not RUN_ID.match(self.id):
            raise InputError(f"run id {self.id!r}: use letters, digits and . _ + - only")
        if self.interleave is not None and not RUN_ID.match(str(self.interleave)):
            raise InputError(f"run {self.id!r} interleave {self.interleave!r}: use letters, digits and . _ + - only")
        check_scalar(self.min_time, name=f"run {self.id!r} min_time (seconds of timed frames)", low=0)
        check_positive_int(self.replicates, name=f"run {self.id!r} replicates (processes that time it)")
        if self.replicates > 1 and not self.timed:
            raise InputError(f"run {self.id!r}: replicates={self.replicates} for an untimed run (one untimed frame); "
                             "only timed runs are rendered in several processes")
        names = [v.get("view") for v in self.views]
        if not names or None in names or len(set(names)) != len(names):
            raise InputError(f"run {self.id!r}: every view needs a unique 'view' name, got {names}")

    @property
    def key(self):
        return f"{self.experiment}/{self.id}"

    @property
    def timed(self):
        """Whether the run's frames are timed (else one untimed frame: :func:`pipeline.timing.measure_together`).

        An untimed run's job may share the machine with other untimed work; a timed one's never does.
        """
        return not (self.warmup == 0 and self.repeat == 1 and self.min_time == 0)

    @property
    def volume_entries(self):
        """The volume entries (scene format) the run reads: its scene's, and its statistics entry."""
        return [*self.scene["volumes"], *([self.statistics] if self.statistics else [])]

    def as_dict(self):
        return {name: getattr(self, name) for name in self.__dataclass_fields__}

    @classmethod
    def list_from_json(cls, text):
        """The runs of a render job's ``--run`` argument: one run's :meth:`as_dict` as JSON, or a group's list."""
        fields = json.loads(text)
        return [cls(**{**one, "views": tuple(one["views"])}) for one in (fields if isinstance(fields, list) else [fields])]

    def spec_hash(self):
        """Hash of everything that determines the output; Snakemake reruns a job when it changes."""
        return hashlib.sha256(canonical_json(self.as_dict()).encode()).hexdigest()[:16]


@dataclass(frozen=True)
class ClaimResult:
    """The outcome of checking one claim on measured data.

    ``holds`` is ``None`` when the claim could not be judged: "not measured", or, with
    ``inconclusive``, a timing claim whose confidence ``interval`` straddles its bound
    (:mod:`~pipeline.experiments.kit.intervals`). ``interval`` is the 95 % interval of the measured
    value (``(low, high)``, in the value's own unit) where it rests on timed frames, and ``margin`` the
    value's relative distance from its bound, positive on the holding side; ``frames`` how many timed
    frames the interval rests on in its thinnest arm; ``value`` and ``bound`` the deciding value and the bound
    it was judged against, where a :class:`~pipeline.experiments.kit.intervals.Decision` made it.
    """

    measured: str
    holds: bool | None
    detail: str = ""
    interval: tuple | None = None
    margin: float | None = None
    inconclusive: bool = False
    frames: int | None = None
    value: float | None = None
    bound: float | None = None

    @classmethod
    def decided(cls, measured, decision, detail=""):
        """The result of a :class:`~pipeline.experiments.kit.intervals.Decision` (holds, fails or inconclusive);
        why an undecidable one is inconclusive ends the detail."""
        if decision.why:
            detail = f"{detail}; inconclusive: {decision.why}" if detail else f"inconclusive: {decision.why}"
        return cls(measured, decision.holds, detail, decision.interval, decision.margin, decision.inconclusive,
                   decision.frames, decision.value, decision.bound)


CLAIM_KINDS = ("timing", "count", "accuracy", "cost model")
"""What a claim measures: ``timing`` a time, a frame rate or their ratio (machine-dependent, judged with an
interval over timed frames); ``count`` a number the code counts (fragments, samples, passes, bytes, a statistic
of a phantom), which does not depend on the machine but where a parallel run's scheduling shares out its work;
``accuracy`` an image against its reference (PSNR, SSIM, an error); ``cost model`` a model's prediction of the
times from counts, against the measured times."""


@dataclass(frozen=True)
class Claim:
    """A statement from a paper (or our own expectation) checked against the results.

    ``check(df)`` receives the experiment's tidy results (successful rows only) and returns a
    :class:`ClaimResult`; ``holds`` is ``None`` when the data needed is missing, which the report
    shows as "not measured" rather than as a pass.

    ``kind`` is what the claim measures (:data:`CLAIM_KINDS`): a check of the kit
    (:mod:`~pipeline.experiments.kit.checks`) knows it from its measurement; a check written by hand
    declares it. ``paper_value`` is the paper's own number the claim judges, in words (``"×3.0"``,
    ``"0.2–4 %"``). ``ours`` marks a target of our own beside the paper's, saying why it differs (``"a
    software rasterizer's early-z is per 4×2 block"``); the paper's number is then a claim of its own, so
    it is always judged.
    """

    id: str
    statement: str
    expected: str
    check: object
    paper_value: str = ""
    ours: str = ""
    kind: str = ""

    def __post_init__(self):
        kind = self.kind or getattr(self.check, "kind", "")
        if kind not in CLAIM_KINDS:
            raise ValueError(f"claim {self.id!r}: kind {kind!r} is not one of {', '.join(CLAIM_KINDS)}; a check "
                             f"written by hand declares what it measures with Claim(..., kind=...)")
        object.__setattr__(self, "kind", kind)

    @property
    def target(self):
        """``"ours"`` for our own target, ``"paper"`` for the paper's statement."""
        return "ours" if self.ours else "paper"

    def with_ours(self, statement, expected, check, *, why):
        """This claim of the paper's number, ``<id>-paper``, and right after it our target ``<id>`` beside it.

        Our target never stands alone where it departs from the paper: the paper's number is judged too, the twin
        right before ours in ``claims.csv`` and on the page, both stating this claim's :attr:`paper_value` and
        :attr:`kind`.

        Parameters
        ----------
        statement, expected : str
        check : callable
            Our claim's, as :class:`Claim` takes them.
        why : str
            Why our target differs from the paper's number (:attr:`ours`).

        Returns
        -------
        tuple of Claim
            ``(self, ours)``: splice them into an experiment's claims with ``*``.
        """
        if not self.id.endswith("-paper") or self.ours:
            raise ValueError(f"claim {self.id!r}: only a claim of the paper's number, '<id>-paper', takes ours "
                             "beside it")
        return self, Claim(self.id.removesuffix("-paper"), statement, expected, check, paper_value=self.paper_value,
                           ours=why, kind=self.kind)

    def evaluate(self, df):
        if df.empty:
            return ClaimResult("no data", None, "no successful runs")
        try:
            return self.check(df)
        except KeyError as exc:  # a column no run reported (common.numeric names it)
            return ClaimResult("not measurable", None, str(exc.args[0]) if exc.args else "a column is missing")
        except (ValueError, ZeroDivisionError) as exc:
            return ClaimResult("not measurable", None, str(exc))


class Experiment:
    """Base class of experiments. Subclasses set the class attributes and implement ``runs``.

    Attributes
    ----------
    name : str
        ``<first author><year>-<what>``.
    paper : str
        Key of :data:`PAPERS`.
    title, description : str
    claims : tuple of Claim
    settings : frozenset of str
        The keys a profile may set for this experiment under ``settings: {<name>: {...}}``;
        any other key is a typo and an error (:func:`pipeline.experiments.check_settings`).
    scales : dict
        ``{scale: {key: value}}``: the experiment's own settings for each profile scale
        (:data:`SCALES`), kept beside the experiment as scikit-image's benchmarks keep their
        reduced and full parameters; a profile's ``settings`` override single keys.
    page : str or None
        The report page (``<page>.html``) that shows this experiment; ``None``: its paper's page.
        A study that spans every paper's backends (the stability atlas) has a page of its own.
    """

    name = ""
    paper = "volbench"
    page = None
    title = ""
    description = ""
    claims = ()
    settings = frozenset()
    scales = {}

    def runs(self, profile):
        """The runs for ``profile`` (list of :class:`Run`)."""
        raise NotImplementedError

    def paper_table(self):
        """The paper's own numbers as a DataFrame (``None`` when the paper has none)."""
        return None

    def report(self, results, ctx):
        """Report blocks for this experiment (see :mod:`reports.html`)."""
        return []


@dataclass(frozen=True)
class Paper:
    """A paper volbench reproduces: what its package (``pipeline/experiments/<id>/``) declares.

    Parameters
    ----------
    id : str
        Key of :data:`core.papers.PAPERS` (its title lives there, with every data set's paper ids).
    technique : str or None
        The backend whose frames are the paper's technique; a paper whose technique made no frame
        on a machine is not reproduced there, however many of its baselines ran. ``None``: the
        project's own studies.
    baselines : tuple of str
        The other backends its experiments need (the methods it compares with).
    needs : str
        What the backends are, in words (the report's list of papers not reproduced yet).
    experiments : tuple of type
        Its :class:`Experiment` classes, in report order.
    """

    id: str
    technique: str | None
    baselines: tuple = ()
    needs: str = ""
    experiments: tuple = ()

    def __post_init__(self):
        if self.id not in PAPERS:
            raise InputError(f"paper {self.id!r}: not in core.papers.PAPERS ({', '.join(PAPERS)}); add its title there")

    @property
    def title(self):
        return PAPERS[self.id]

    @property
    def backends(self):
        """Every backend the paper needs: its technique first, then its baselines."""
        return tuple(b for b in (self.technique, *self.baselines) if b)
