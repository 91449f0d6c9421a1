"""Real scans, read in place from a data folder that is never copied into the repository.

The folder is a configuration value: the ``data_dir`` argument, else the environment variable
``VOLBENCH_REAL_DATA``, else ``<repo>/../shared/data/real``. It holds ``volumes.json``, a
manifest of headerless raw files::

    {"cthead": {"file": "cthead_256x256x99_uint8.raw", "dims": [256, 256, 99], "dtype": "uint8",
                "spacing": [1, 1, 2], "range": [0, 255], "modality": "CT head"}, ...}

(``range`` optional; keys starting with ``_`` are comments). VolPack's example brain,
``brainsmall.den``, is looked for in the folder first and then where Debian's
``libvolpack1-dev`` installs it.

A data set whose folder, manifest entry or file is missing raises :class:`DataUnavailableError`,
whose message says what is missing and how to point volbench at the data, so the pipeline can
record the run as skipped with that reason.
"""

import json
import os
from pathlib import Path

from datasets.loaders import load_den, load_raw
from core.errors import InputError

ENV_VAR = "VOLBENCH_REAL_DATA"
REPO_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_DATA_DIR = REPO_ROOT.parent / "shared" / "data" / "real"
MANIFEST = "volumes.json"
BRAINSMALL_FILE = "brainsmall.den"
DEBIAN_BRAINSMALL = Path("/usr/share/doc/libvolpack1-dev/examples") / BRAINSMALL_FILE


class DataUnavailableError(InputError):
    """A real data set cannot be loaded on this machine because its files are missing."""


_HOW_TO = (f"Point volbench at the folder holding {MANIFEST} with the environment variable {ENV_VAR}, "
           "the pipeline profile's real_data, or the data_dir argument of datasets.load.")


def resolve_data_dir(path=None):
    """The real-data folder: ``path``, else ``$VOLBENCH_REAL_DATA``, else the default."""
    if path is not None:
        return Path(path)
    env = os.environ.get(ENV_VAR)
    return Path(env) if env else DEFAULT_DATA_DIR


def read_manifest(path=None):
    """The manifest of the real-data folder as ``{name: entry}`` (comment keys dropped).

    Raises
    ------
    DataUnavailableError
        The folder or its ``volumes.json`` does not exist.
    InputError
        The manifest is not valid JSON or an entry lacks ``file``, ``dims`` or ``dtype``.
    """
    folder = resolve_data_dir(path)
    manifest = folder / MANIFEST
    if not folder.is_dir():
        raise DataUnavailableError(f"real-data folder {folder} does not exist. {_HOW_TO}")
    if not manifest.is_file():
        raise DataUnavailableError(f"real-data folder {folder} has no {MANIFEST}. {_HOW_TO}")
    try:
        entries = json.loads(manifest.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"{manifest}: cannot read the manifest: {exc}") from None
    if not isinstance(entries, dict):
        raise InputError(f"{manifest}: expected a JSON object of data sets")
    entries = {k: v for k, v in entries.items() if not k.startswith("_")}
    for name, entry in entries.items():
        missing = [key for key in ("file", "dims", "dtype") if not isinstance(entry, dict) or key not in entry]
        if missing:
            raise InputError(f"{manifest}: entry {name!r} lacks {', '.join(missing)}")
    return entries


def _brainsmall(folder):
    candidates = [folder / BRAINSMALL_FILE, DEBIAN_BRAINSMALL]
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    raise DataUnavailableError(
        f"real data set 'brainsmall' is unavailable: {BRAINSMALL_FILE} is in none of "
        f"{', '.join(str(c) for c in candidates)}. Install the Debian package libvolpack1-dev "
        f"(make setup does) or put the file in the real-data folder ({ENV_VAR}).")


def load_real(source, *, data_dir=None, name=None):
    """Read a real scan from the data folder.

    Parameters
    ----------
    source : str
        A manifest entry, or ``"brainsmall"`` for VolPack's example.
    data_dir : str or Path, optional
        The real-data folder (see the module notes for the default).
    name : str, optional
        The data set's registered name (defaults to ``source``), used in messages and ``meta``.

    Returns
    -------
    Volume
        With ``meta`` holding the path, the modality and ``kind = "real"``.

    Raises
    ------
    DataUnavailableError
        The folder, the manifest entry or the file is missing.
    InputError
        The file exists but does not match its manifest entry (size, dtype).
    """
    name = name or source
    folder = resolve_data_dir(data_dir)
    if source == "brainsmall":
        volume = load_den(_brainsmall(folder), name=name)
        volume.meta.update(dataset=name, kind="real", modality="MRI")
        return volume
    try:
        entries = read_manifest(folder)
    except DataUnavailableError as exc:
        raise DataUnavailableError(f"real data set {name!r} is unavailable: {exc}") from None
    if source not in entries:
        raise DataUnavailableError(f"real data set {name!r} is unavailable: {folder / MANIFEST} has no entry "
                                   f"for it (entries: {', '.join(sorted(entries))}). {_HOW_TO}")
    entry = entries[source]
    path = folder / entry["file"]
    if not path.is_file():
        raise DataUnavailableError(f"real data set {name!r} is unavailable: {path} (listed in {MANIFEST}) "
                                   f"does not exist. {_HOW_TO}")
    volume = load_raw(path, dims=entry["dims"], dtype=entry["dtype"], spacing=entry.get("spacing", (1, 1, 1)),
                      value_range=entry.get("range"), name=name)
    volume.meta.update(dataset=name, kind="real", modality=entry.get("modality", ""))
    return volume
