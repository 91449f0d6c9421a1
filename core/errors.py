"""Exceptions shared by every part of volbench.

Each error names the offending input and says how to fix it (CONVENTIONS, Errors). They are
raised before any rendering work starts.
"""


class VolbenchError(Exception):
    """Base class of all volbench errors."""


class InputError(VolbenchError, ValueError):
    """An input (array, file, parameter, scene field) is malformed or out of range."""


class UnsupportedFeatureError(VolbenchError):
    """A backend was asked to render a scene that uses a feature it lacks.

    Parameters
    ----------
    backend : str
        Registry name of the backend.
    feature : str
        Name of the missing capability (a ``Capabilities`` field, e.g. ``"projections"``).
    reason : str
        Why the backend lacks it.
    """

    def __init__(self, backend, feature, reason):
        self.backend = backend
        self.feature = feature
        self.reason = reason
        super().__init__(f"backend {backend!r} does not support {feature}: {reason}")


class BackendUnavailableError(VolbenchError):
    """A backend cannot run on this machine (no GL context, no OpenCL device, missing library)."""
