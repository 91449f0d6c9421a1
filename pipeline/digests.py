"""What makes Snakemake rerun a job: the code that shapes its output, and failed or damaged runs.

Every job of the Snakefile carries, as the param ``code``, a digest of the code that shapes its
output (:func:`job_code_digest`), derived from the imports rather than kept by hand (see
:func:`job_sources`): an edit to any of that code reruns the job (Snakemake's ``params`` trigger)
and the jobs downstream, and an edit to anything else reruns nothing. A render job also takes a
retry marker as an input (:func:`mark_retry`), which reruns a run whose last record failed or names
an image that is missing or damaged.
"""

import ast
import functools
import hashlib
import json
import os
import time
import typing
from pathlib import Path

import renderers
from core.errors import InputError
from pipeline.records import image_damage, run_record_path

ROOT = Path(__file__).resolve().parent.parent

JOBS = "pipeline.jobs"
"""The module whose functions are the jobs' entry points (``python -m pipeline.jobs <rule> ...``)."""

NAMED_IMPORTS = {
    "pipeline.experiments": "pipeline.experiments",
    "renderers": "renderers",
}
"""The modules that import others by a name computed at run time (``importlib.import_module``),
which :mod:`ast` cannot follow, and the package whose every module a job that runs that code
imports through them. The experiment registry's lookups (``plan``, ``selected``...) import every
paper's package, while its classes (``Run``, ``Profile``), which a render job takes, import none.
The backend registry's lookups import any backend: planning reads backend classes (their options,
quality sweeps) and the report probes every backend, but a render job's lookups import only its
own backend, the one :func:`job_code_digest` is given. A module that imports by a computed name in
code a job runs and is not named here stops the digest with an error, so that no job's code
escapes it."""

LEFT_OUT_SUFFIXES = (".pyc", ".nbi", ".nbc", ".md")
"""Files in the packages that shape no output: caches written beside the sources (CPython's and
Numba's) and documentation (Markdown)."""


def job_sources(rule, *, backend=None, root=ROOT):
    """The files whose content shapes the output of the Snakemake rule ``rule``, and its entry code.

    What a job runs is read from the sources with :mod:`ast`, never imported. It starts at the
    job's entry function in :mod:`pipeline.jobs` and the helpers there it calls. Of every module
    that code imports, what runs is the code that runs on import (statements other than
    definitions, imports and assignments) and what the importer takes from it (``from a import
    f``: ``f``; ``import a`` or ``from p import a``: what the importer uses of it, ``a.f``, or all
    of it where it uses the module otherwise); and of those, the functions, classes, constants and
    module-level imports they refer to, with the imports inside those functions, and so on through
    every module reached. The packages above a module run on import too: their ``__init__.py``
    counts, and what it imports where that is used. The data files of a
    package (templates, ``.cl`` kernels: the non-Python files of its folder and of its subfolders
    that are not packages) count where code that runs locates files beside it (``__file__``,
    :mod:`importlib.resources`, :mod:`pkgutil`). Where a module imports by a computed name (a
    registry), :data:`NAMED_IMPORTS` says what it imports.

    Parameters
    ----------
    rule : str
        A rule of the Snakefile: the name of its entry function in :mod:`pipeline.jobs`.
    backend : str, optional
        A render job's backend: the backend registry's lookups import every module of its package
        under ``renderers/`` (and no other backend).
    root : path
        The project folder whose files are read.

    Returns
    -------
    files : list of Path
        Sorted: the files of the modules reached (:mod:`pipeline.jobs` aside) and the data files
        that count.
    code : list of str
        The source of the entry function and of the helpers of :mod:`pipeline.jobs` it uses, the
        entry first: of that module, only these shape this job.

    Raises
    ------
    InputError
        :mod:`pipeline.jobs` has no function ``rule``.
    RuntimeError
        Code the job runs imports by a computed name from a module :data:`NAMED_IMPORTS` lacks.
    """
    root = Path(root)
    project = _Project(root)
    jobs = project.module(JOBS)
    if rule not in jobs.units:
        raise InputError(f"rule {rule!r}: {JOBS} has no function of that name; it has {', '.join(sorted(jobs.units))}")
    entry = jobs.used({rule}, project.files.__contains__)
    code = [ast.get_source_segment(jobs.text, node) for name in (rule, *sorted(entry.units - {rule}))
            for node in jobs.units[name]]
    pending = [*entry.imports, (JOBS.rpartition(".")[0], set())]
    named = dict(NAMED_IMPORTS)
    if backend is not None:
        # Its package under renderers/ (first two parts of the registry's module: renderers.vtk for vtk.gpu).
        named["renderers"] = ".".join(renderers.backend_module(backend).split(".")[:2])
    modules, readers = _closure(pending, project, named)
    files = {project.files[module] for module in modules}
    for module in readers:
        files.update(_data_files(project.files[module].parent))
    return sorted(files), code


def source_digest(files, *, root=ROOT, extra=()):
    """Hex digest of the content and relative names of ``files`` (under ``root``), plus ``extra`` strings.

    Content, not modification times: a checkout or a copy that changes no byte reruns nothing.
    """
    root = Path(root)
    digest = hashlib.sha256()
    for path in sorted(files):
        digest.update(Path(path).relative_to(root).as_posix().encode() + b"\0")
        digest.update(hashlib.sha256(Path(path).read_bytes()).digest())
    for text in extra:
        digest.update(text.encode() + b"\0")
    return digest.hexdigest()[:16]


def job_code_digest(rule, *, backend=None, root=ROOT):
    """The digest a Snakemake job carries as a param: of :func:`job_sources` (files and entry code)."""
    files, code = job_sources(rule, backend=backend, root=root)
    return source_digest(files, root=root, extra=code)


def _closure(imports, project, named):
    """``(modules, readers)``: the project modules that ``imports`` reach, and those of them whose
    code that runs locates files beside it; see :func:`job_sources`.

    ``imports`` are ``(module, names)`` pairs: the names taken from ``module``, or ``None`` for the
    module as a whole. ``named`` is :data:`NAMED_IMPORTS` for this job.
    """
    taken, readers, registries, pending = {}, set(), set(), list(imports)
    while pending:
        module, names = pending.pop()
        if module not in project.files:
            continue  # the standard library or an installed package
        parts = module.split(".")
        # The packages above a module run on import too: with their code that runs on import.
        requests = [(".".join(parts[:i]), set()) for i in range(1, len(parts))] + [(module, names)]
        # A name taken from a package may be one of its modules (``datasets.phantoms``).
        pending += [(f"{module}.{name}", None) for name in names or () if f"{module}.{name}" in project.files]
        for target, target_names in requests:
            if target in taken:
                done = taken[target]
                if done is None or (target_names is not None and target_names <= done):
                    continue
                target_names = None if target_names is None else target_names - done
            taken[target] = None if target_names is None else taken.get(target, set()) | target_names
            use = project.module(target).used(target_names, project.files.__contains__)
            if use.locates_files:
                readers.add(target)
            if use.imports_by_name and target not in registries:
                if target not in named:
                    raise RuntimeError(
                        f"{target} imports modules by a name computed at run time, which the rerun digests "
                        "cannot follow: name it in pipeline.digests.NAMED_IMPORTS with the package it imports from")
                registries.add(target)
                pending += [(name, None) for name in project.package_modules(named[target])]
            pending += use.imports
    return set(taken), readers


def _data_files(folder):
    """The non-Python files of a package folder and of its subfolders that are not packages (data, templates)."""
    files = []
    for path in folder.iterdir():
        if path.is_file() and path.suffix not in (".py", *LEFT_OUT_SUFFIXES):
            files.append(path)
        elif path.is_dir() and path.name != "__pycache__" and not (path / "__init__.py").exists():
            files += _data_files(path)
    return files


class _Project:
    """The modules of the project's packages under ``root`` (its folders with an ``__init__.py``)."""

    def __init__(self, root):
        self.files = {}
        """``{module name: file}``: ``a/b.py`` and ``a/b/__init__.py`` are both module ``a.b``."""
        for package in (path for path in root.iterdir() if (path / "__init__.py").is_file()):
            for file in package.rglob("*.py"):
                if "__pycache__" not in file.parts:
                    parts = file.relative_to(root).with_suffix("").parts
                    self.files[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = file

    def package_modules(self, package):
        """Every module of ``package`` (itself and all modules under it)."""
        return sorted(name for name in self.files if name == package or name.startswith(f"{package}."))

    def module(self, name):
        """The :class:`_Module` of ``name``."""
        file = self.files[name]
        return _parse(file.read_bytes(), name if file.name == "__init__.py" else name.rpartition(".")[0])


@functools.lru_cache(maxsize=None)
def _parse(source, package):
    """The :class:`_Module` of a module's source; cached by content, so an edited file is read afresh."""
    return _Module(source.decode(), package)


class _Import(typing.NamedTuple):
    """One name an import statement binds: ``import module`` (``name`` ``None``) or ``from module import name``."""

    module: str
    name: str | None
    bound: str


def _imports(node, package):
    """The :class:`_Import` of each name an import statement binds (none for any other node)."""
    if isinstance(node, ast.Import):
        # ``import a.b`` binds a, through which a.b is used; ``import a.b as c`` binds c.
        return [_Import(alias.name, None, alias.asname or alias.name.split(".")[0]) for alias in node.names]
    if isinstance(node, ast.ImportFrom):
        module = _absolute(node, package)
        return [_Import(module, alias.name, alias.asname or alias.name) for alias in node.names]
    return []


class _Code:
    """What some code refers to: names (:attr:`attributes`: of those it uses only as
    ``name.attribute``, the attributes), its import statements, whether it imports by a computed
    name, and whether it locates files beside its module (``__file__``)."""

    def __init__(self, nodes, package):
        items = [item for node in nodes for item in ast.walk(node)]
        bases = {id(item.value): item.attr for item in items
                 if isinstance(item, ast.Attribute) and isinstance(item.value, ast.Name)}
        names = [item for item in items if isinstance(item, ast.Name)]
        self.names = {item.id for item in names}
        bare = {item.id for item in names if id(item) not in bases}
        self.attributes = {}
        for item in names:
            if item.id not in bare:
                self.attributes.setdefault(item.id, set()).add(bases[id(item)])
        self.imports = [entry for item in items for entry in _imports(item, package)]
        self.imports_by_name = any(isinstance(item, ast.Call) and _call_name(item.func) in ("import_module", "__import__")
                                   for item in items)
        self.locates_files = "__file__" in self.names or any(map(_reads_package_files, self.imports))


class _Use(typing.NamedTuple):
    """What the code of a module that runs uses: the imports it takes (``(module, names)`` pairs,
    ``names`` ``None`` for a whole module), the functions, classes and constants of the module it
    runs (``units``), and whether it imports by a computed name or locates files beside it."""

    imports: list
    units: set
    imports_by_name: bool
    locates_files: bool


class _Module:
    """One module's source: its named parts (functions, classes, constants), its module-level
    imports, and the rest of its module-level code, which runs whenever it is imported."""

    def __init__(self, text, package):
        self.text = text
        self.units = {}     # name -> the definitions and assignments binding it at module level
        self.bindings = {}  # name -> the module-level imports binding it
        on_import = []
        self._split(ast.parse(text).body, on_import, package)
        self.on_import = _Code(on_import, package)
        self.unit_code = {name: _Code(nodes, package) for name, nodes in self.units.items()}

    def _split(self, statements, on_import, package):
        for node in statements:
            names = _assigned_names(node)
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                self.units.setdefault(node.name, []).append(node)
            elif names:
                for name in names:
                    self.units.setdefault(name, []).append(node)
            elif isinstance(node, (ast.Import, ast.ImportFrom)):
                for item in _imports(node, package):
                    self.bindings.setdefault(item.bound, []).append(item)
            elif _is_main_guard(node):
                continue  # runs only when the module is the program; the digests start from the entry function
            elif any(isinstance(value, list) and value and isinstance(value[0], (ast.stmt, ast.excepthandler))
                     for _, value in ast.iter_fields(node)):
                # A compound statement (if, try, with): its imports and definitions are the module's too.
                for _, value in ast.iter_fields(node):
                    for item in value if isinstance(value, list) else [value]:
                        if isinstance(item, ast.stmt):
                            self._split([item], on_import, package)
                        elif isinstance(item, ast.excepthandler):
                            on_import += [item.type] if item.type else []
                            self._split(item.body, on_import, package)
                        elif isinstance(item, ast.AST):
                            on_import.append(item)
            else:
                on_import.append(node)

    def used(self, names, is_module):
        """The :class:`_Use` of the code that runs on import and of ``names`` (``None``: of everything).

        ``is_module(name)`` tells a project module from a name inside one.
        """
        pending = [*self.units, *self.bindings] if names is None else [*names]
        pending += self.on_import.names
        parts, seen = [self.on_import], set()
        while pending:
            name = pending.pop()
            if name not in seen:
                seen.add(name)
                if name in self.units:
                    parts.append(self.unit_code[name])
                    pending += self.unit_code[name].names
        bare = {name for part in parts for name in part.names - set(part.attributes)}
        attributes = {}
        for part in parts:
            for name, used in part.attributes.items():
                if name not in bare:
                    attributes[name] = attributes.get(name, set()) | used
        bound = [item for name in sorted(seen & set(self.bindings)) for item in self.bindings[name]]
        imports = [pair for item in bound for pair in _taken(item, attributes, is_module)]
        imports += [pair for part in parts for item in part.imports for pair in _taken(item, part.attributes, is_module)]
        return _Use(imports, seen & set(self.units), any(part.imports_by_name for part in parts),
                    any(part.locates_files for part in parts) or any(map(_reads_package_files, bound)))


def _taken(item, attributes, is_module):
    """The ``(module, names)`` pairs an :class:`_Import` takes, given ``attributes``: for each name
    the code uses only as ``name.attribute``, those attributes.

    ``import m``, ``import m as c`` and ``from p import m`` (a module) take ``m`` whole, or only the
    attributes the code uses of the name bound; ``import a.b`` also takes of ``a`` what the code
    uses of it; ``from p import f`` takes the name ``f`` of ``p``.
    """
    if item.name == "*":
        return [(item.module, None)]
    if item.name is None:
        if item.bound == item.module or item.bound != item.module.split(".")[0]:
            return [(item.module, attributes.get(item.bound))]
        return [(item.module, None), (item.bound, attributes.get(item.bound))]
    submodule = f"{item.module}.{item.name}"
    if is_module(submodule):
        return [(submodule, attributes.get(item.bound))]
    return [(item.module, {item.name})]


def _assigned_names(node):
    """The names a module-level assignment binds (``X = ...``, ``X: T = ...``, ``X, Y = ...``), else ``[]``.

    Such an assignment is a named part of its module: its value is computed on import, but shapes a
    job only where the job's code uses the name.
    """
    if isinstance(node, ast.Assign):
        targets = node.targets
    elif isinstance(node, ast.AnnAssign) and node.value is not None:
        targets = [node.target]
    else:
        return []
    names = []
    for target in targets:
        items = target.elts if isinstance(target, ast.Tuple) else [target]
        if not all(isinstance(item, ast.Name) for item in items):
            return []  # ``x.attr = ...``, ``table[key] = ...``: code that runs, not a name
        names += [item.id for item in items]
    return names


def _reads_package_files(item):
    """Whether an :class:`_Import` brings the standard library's readers of a package's own files."""
    return item.module in ("importlib.resources", "pkgutil") or (item.module, item.name) == ("importlib", "resources")


def _is_main_guard(node):
    """``if __name__ == "__main__":``"""
    test = node.test if isinstance(node, ast.If) else None
    return (isinstance(test, ast.Compare) and isinstance(test.left, ast.Name) and test.left.id == "__name__"
            and any(isinstance(c, ast.Constant) and c.value == "__main__" for c in test.comparators))


def _absolute(node, package):
    """The absolute module name of a ``from ... import`` in a module of ``package``."""
    if node.level == 0:
        return node.module
    parts = package.split(".")
    base = parts[:len(parts) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def _call_name(func):
    return func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)


# ---------------------------------------------------------------------------------------------
# Failed and damaged runs.

def retry_marker_path(results_dir, experiment, run_id):
    """``results/.retry/<experiment>/<run>``: an input of the run's render job (see :func:`mark_retry`)."""
    return Path(results_dir) / ".retry" / experiment / run_id


def mark_retry(results_dir, experiment, run_id):
    """Make the run's retry marker say whether its render job must run again; return its path.

    A failed run's record is a finished output to Snakemake, which would keep it forever. So
    every render job takes this marker as an input, and the workflow calls this for every run
    when it starts: for a run whose record is ``failed`` (or unreadable), or ``ok`` but naming an
    image that is missing or damaged (:func:`pipeline.records.image_damage`), the marker is
    rewritten now, newer than the record and with text naming that record (Snakemake skips a newer
    input whose checksum it has recorded before), so Snakemake reruns the job ("updated input
    files"), a dry run included; for any other run the marker is empty and dated 1970, older than
    any record, so it never triggers. The record stays until the retry replaces it, and skipped runs
    (which cannot happen here) are not retried.
    """
    marker = retry_marker_path(results_dir, experiment, run_id)
    record_path = run_record_path(results_dir, experiment, run_id)
    why = ""
    if record_path.is_file():
        try:
            record = json.loads(record_path.read_text())
            status = record.get("status")
        except (OSError, ValueError, AttributeError):
            why = "is unreadable"
        else:
            if status not in ("ok", "skipped"):
                why = f"is {status}"
            elif status == "ok":
                damage = image_damage(record)
                why = f"names a damaged image ({damage})" if damage else ""
    marker.parent.mkdir(parents=True, exist_ok=True)
    if why:
        # Snakemake ignores a newer input whose checksum it has seen before, so the marker's text
        # names this very record (its modification time and digest): each failure is new to it.
        stamp = f"{record_path.stat().st_mtime_ns} {hashlib.sha256(record_path.read_bytes()).hexdigest()[:16]}"
        marker.write_text(f"retry {experiment}/{run_id}: its last record ({stamp}) {why}\n")
        now = time.time()
        os.utime(marker, (now, max(now, record_path.stat().st_mtime + 1)))
    else:
        marker.write_text("")
        os.utime(marker, (0, 0))
    return marker
